"""Issue 50: a warm-up on a fitted machine, served at 600x with the user's compensation program
(fixtures/plc/tc_z.awl: 0.3 mm per 10 K of the bed above 30 degC, FB3 PUT once a minute): the bed heats
through its [[sensor.response]], the PLC reads it on PIW 420 and writes SD43900 from it."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import snap7

from nckemu.clients.sync import NckClient
from nckemu.emulator.machine.machine_file import machine_text
from tests.support.live_tools import poll, serve

ROOT = Path(__file__).resolve().parents[3]
# The bed of the built-in machine with a fitted response of a spindle bearing's size (for the test: it
# must pass tc_z's 30 degC within minutes): 25 degC plus 1.5 K per krpm^1.2 through 20 min.
BED = """
[[sensor]]
name = "bed"
temperature_C = 25.0
plc_input = "PIW420"
[[sensor.response]]
name = "spindle"
input = "spindle_rpm"
K = 1.5
power = 1.2
tau_s = 1200.0
"""


def _machine(path: Path) -> Path:
    text, _source = machine_text(None)
    start = text.index("[[sensor]]")
    end = text.index("\n[", text.index("raw_per_C", start))
    path.write_text(text[:start] + BED.strip() + "\n" + text[end:])
    return path


def _hand_mm(bed_C: float) -> float:
    return 0.3 * (bed_C - 30.0) / 10.0 if bed_C > 30.0 else 0.0


@pytest.mark.timeout(180)
def test_a_warm_up_on_the_fitted_machine_writes_the_compensation_of_the_twins_bed(tmp_path: Path) -> None:
    machine = _machine(tmp_path / "fitted.toml")
    program = tmp_path / "WARM.MPF"
    program.write_text("N10 S8000 M3\nN20 G4 F7200\nN30 M5\nN40 M30\n")
    with serve("--machine", str(machine), "--program", str(program), "--plc", str(ROOT / "fixtures/plc/tc_z.awl"),
               "--speed", "600x") as served:
        with NckClient("127.0.0.1", served.port, slot=2) as plc:
            plc.db_write(21, 7, b"\x00")
            plc.db_write(21, 7, b"\x02")                 # NC start (DB21.DBX7.1 rising edge)
        client = snap7.Client()
        client.connect("127.0.0.1", 0, 4, served.port)
        try:
            deadline = time.monotonic() + 60.0
            checked = 0
            while time.monotonic() < deadline and checked < 20:
                p = poll(client)
                bed_C = p.piw420 / 276.48
                if bed_C > 33.0:   # warm: tc_z writes from the minute's PIW 420 (the bed moves < 0.7 K a minute)
                    assert p.sd43900_mm == pytest.approx(_hand_mm(bed_C), abs=0.025), (p, bed_C)
                    checked += 1
                time.sleep(0.05)
        finally:
            client.disconnect()
    assert checked == 20, "the bed passed 33 degC within a minute of wall time at 600x"
