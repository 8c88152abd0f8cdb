"""A living 828D lathe (issue 32): `nckemu serve --inputs` moves r0035 of the spindle drive with the
recording's motor temperature column and r0032 with the spindle's load (its speed), as a collector polls
them over S7; the machine status (the live page) shows the drive temperatures beside the sensors."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest

from nckemu.clients.sync import NckClient
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.status import machine_status
from tests.support.live_tools import serve

LATHE = Path(__file__).resolve().parents[4] / "fixtures" / "machines" / "lathe_828d.toml"


def write_recording(path: Path, hours: float = 2.0, step_s: float = 60.0) -> Path:
    """The spindle motor warms 30 -> 60 degC; the spindle rests and turns at 4500 rpm by turns."""
    lines = ["t_s,temp_spindle_motor_C,temp_bed_C,spindle_rpm"]
    for i in range(int(hours * 3600 / step_s) + 1):
        t = i * step_s
        rpm = 0.0 if (t // 900) % 2 == 0 else 4500.0
        lines.append(f"{t:g},{30.0 + 30.0 * t / (hours * 3600):.4f},{21.0 + math.sin(t / 900.0):.4f},{rpm:g}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def spindle_power_kW(rpm: float) -> float:
    """r0032 of the lathe's drive 1 (11 kW, 6000 rpm, 15 % of load at rated speed, 90 % efficiency)."""
    load = 0.15 * rpm / 6000.0
    return 11.0 * load * min(rpm / 6000.0, 1.0) / 0.9 + 11.0 * 0.1 * load * load


@pytest.mark.timeout(120)
def test_r0035_follows_the_recording_and_r0032_the_spindle(tmp_path: Path) -> None:
    recording = write_recording(tmp_path / "lathe.csv")
    polls = []
    with serve("--machine", str(LATHE), "--inputs", str(recording), "--speed", "600x") as served, \
            NckClient("127.0.0.1", served.port) as nck:
        deadline = time.monotonic() + 8.0
        while time.monotonic() < deadline:
            # one job: the motor sensor, r0035, the spindle's speed and r0032 of drive 1
            polls.append(nck.get("NCKEMU_SENSOR_TEMP[l1]", "/DriveVsa/Drive/r0035[u1]", "actSpeed",
                                 "/DriveVsa/Drive/r0032[u1]"))
            time.sleep(0.01)
    assert len(polls) > 50
    for sensor_C, r0035, rpm, r0032 in polls:
        assert r0035 == pytest.approx(sensor_C, abs=1e-4)          # REAL4 on the wire
        assert 30.0 - 1e-3 <= r0035 <= 60.0 + 1e-3
        assert r0032 == pytest.approx(spindle_power_kW(rpm), rel=1e-5, abs=1e-6)
    assert len({round(p[1], 3) for p in polls}) > 10, "r0035 warms with the recording"
    assert {p[2] > 0 for p in polls} == {True, False}, "the spindle rests and turns"
    assert max(p[3] for p in polls) > 0.1 and min(p[3] for p in polls) == 0.0


def test_machine_status_lists_the_drives_beside_the_sensors() -> None:
    emulator = Emulator(LATHE, clock=SimulatedClock())
    emulator.nck.set_sensor_temperature("spindle_motor", 44.0)
    status = machine_status(emulator)
    first = status["drives"][0]
    assert (first["number"], first["axis"], first["motor_C"]) == (1, 3, 44.0)
    assert first["power_unit_C"] == pytest.approx(24.0 + 30.0 * 9.0 / 26.0)
    assert [d["number"] for d in status["drives"]] == [1, 2, 3] and "sensors" in status
    page = (Path(__file__).resolve().parents[4] / "nckemu/emulator/faces/web/page.html").read_text()
    assert '<table id="drives">' in page and "r0035" in page
