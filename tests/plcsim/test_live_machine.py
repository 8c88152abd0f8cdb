"""A living machine over the wire: python-snap7 polls PIW 420, SD43900[AX4] and actToolBasePos of
`nckemu serve --inputs REC.csv --plc tc_z.awl --speed 600x` and every value is what the offline
`plc run --inputs ... --out SIM.csv` computed for the same simulated time (the NCK's sysTimeUdword,
read before and after in the same job, says which time that is)."""

from __future__ import annotations

import bisect
import math
import time
from pathlib import Path

import numpy as np
import pytest
import snap7

from nckemu.emulator.machine.machine_file import load_machine
from nckemu.plcsim.replay import run_on_recording, with_simulation, write_atomically
from nckemu.thermal.recordings.recording import load_recording
from tests.support.live_tools import MACHINE, PROGRAM, poll, serve, write_recording

SPEED = 600.0
POLL_WALL_S = 12.0
# A written value has reached the applied TC within a few IPO cycles (the MD32760 rate limit).
RAMP_S = 0.1


def _values_between(times: list[float], values: list[float], start_s: float, end_s: float,
                    initial: float) -> set[float]:
    """What a piecewise-constant signal (value i from times[i] on) may read during [start_s, end_s]."""
    first = bisect.bisect_left(times, start_s) - 1  # a write at start_s may be yet to land
    last = bisect.bisect_right(times, end_s) - 1
    return {initial if i < 0 else values[i] for i in range(first, last + 1)}


def test_snap7_polls_follow_the_recording_and_the_program_as_offline(tmp_path: Path) -> None:
    recording_path = write_recording(tmp_path / "rec.csv", hours=3.0)
    recording = load_recording(recording_path)
    machine = load_machine(MACHINE)
    offline = run_on_recording(PROGRAM, machine, recording, "Z", cycle_s=1.0, progress=False)
    write_atomically(tmp_path / "SIM.csv", with_simulation(recording, "Z", offline.sim_um))
    sim_um = load_recording(tmp_path / "SIM.csv").simulated_um["Z"]
    assert np.allclose(sim_um, offline.sim_um, rtol=1e-5, atol=1e-3)  # SIM.csv is the same column, 6 digits
    t0 = offline.clock_offset_s
    put_times = [job.time_s for job in offline.log.puts]
    put_values = [job.values["SD1"] for job in offline.log.puts]
    row_times = [float(t) - t0 for t in recording.t_s]   # on the emulator's clock
    ipo_s = machine.ipo_cycle_s
    bed = recording.temperatures_C["temp_bed_C"]
    z = recording.positions_mm["Z"]
    sensor = next(s for s in machine.sensors if s.name == "bed")

    polls = []
    with serve("--machine", str(MACHINE), "--inputs", str(recording_path), "--plc", str(PROGRAM),
               "--speed", f"{SPEED:g}x") as served:
        client = snap7.Client()
        client.connect("127.0.0.1", 0, 4, served.port)
        try:
            deadline = time.monotonic() + POLL_WALL_S
            while time.monotonic() < deadline:
                polls.append(poll(client, ref=len(polls) % 60000 + 1))
                time.sleep(0.003)
        finally:
            client.disconnect()
    assert polls[-1].after_s > 1800.0, "600x for 12 s is two simulated hours (half an hour even on a loaded machine)"

    checked = {"piw": 0, "sd": 0, "tc": 0, "pos": 0}
    for p in polls:
        assert p.before_s <= p.after_s
        # At a cycle's start exactly the clock may stand held while that cycle has yet to run.
        cycles = range(math.ceil(p.before_s - 1e-9) - 1, math.floor(p.after_s + 1e-9) + 1)
        # PIW 420: the bed of a cycle inside the job's window, through the sensor's scaling
        words = {sensor.raw_value(float(np.interp(t0 + k, recording.t_s, bed))) for k in cycles}
        assert p.piw420 in words, (p, words)
        checked["piw"] += 1
        # SD43900: what the offline program had written by then
        written = _values_between(put_times, put_values, p.before_s, p.after_s, 0.0)
        assert p.sd43900_mm in written, (p, written)
        checked["sd"] += 1
        # actToolBasePos of Z: the recorded position plus the compensation (compensation_sign -1)
        places = {float(np.interp(t0 + k, recording.t_s, z)) for k in cycles}
        assert any(abs(p.act_z_mm - (place - p.tc_z_mm)) < 1e-9 for place in places), (p, places)
        checked["pos"] += 1
        # The applied TC against SIM.csv: the row before, if no PUT came between it and the poll;
        # the row after, if the last PUT before the poll came after the row before and none follows.
        r = bisect.bisect_right(row_times, p.before_s - ipo_s) - 1
        if r < 0 or r + 1 >= len(row_times):
            continue
        puts_between = [t for t in put_times if row_times[r] - 1e-9 <= t <= p.after_s]
        if not puts_between:
            assert p.tc_z_mm * 1000.0 == pytest.approx(offline.sim_um[r], abs=1e-6), (p, r)
            checked["tc"] += 1
        elif puts_between[-1] < p.before_s - RAMP_S and not [t for t in put_times
                                                              if p.before_s - RAMP_S <= t <= row_times[r + 1]]:
            assert p.tc_z_mm * 1000.0 == pytest.approx(offline.sim_um[r + 1], abs=1e-6), (p, r)
            checked["tc"] += 1
    assert checked["tc"] > 100 and checked["sd"] > 100, checked
    assert len({p.piw420 for p in polls}) > 20, "PIW 420 follows the warming bed"
    assert len({p.sd43900_mm for p in polls}) > 10, "SD43900 follows the program's writes"
    assert max(p.sd43900_mm for p in polls) > 0.05


def test_verbose_prints_one_line_per_simulated_minute_never_floods(tmp_path: Path) -> None:
    """-v at 60x: a line a simulated minute (one a wall second); stderr does not get the PLC client's frames."""
    recording = write_recording(tmp_path / "rec.csv", hours=1.0)
    with serve("--machine", str(MACHINE), "--inputs", str(recording), "--plc", str(PROGRAM), "--speed", "60x",
               "-v") as served:
        time.sleep(5.0)
    out, err = served.process.communicate(timeout=20)
    lines = [line for line in out.splitlines() if line.startswith('{"live"')]
    assert 3 <= len(lines) <= 7, out
    assert '"live: t 00:01:00, rec -00:01:00, bed 25.00' in lines[0]
    assert "PLC RUN" in lines[-1]
    assert len(err.splitlines()) < 40 and "DEBUG snap7" not in err, err[-2000:]
