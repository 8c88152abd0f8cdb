"""``nckemu plc run --inputs``: a 24 h recording at 1 Hz (86,400 rows, one 1 s PLC cycle each) through
seed 000's program on the emulator. Target: under 60 s on the 2-core development machine.

Usage: .venv/bin/python bench/bench_plc_replay.py [--hours 24] [--program fixtures/plc/tc_z.awl]
Anchor: the same program for the same simulated time without a recording (`plc run --duration`),
which drives the sensors from the machine file's profile.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from nckemu.plcsim.replay import run_on_recording  # noqa: E402
from nckemu.plcsim.run import run_program  # noqa: E402
from nckemu.thermal.recordings.recording import Recording  # noqa: E402


def day_at_1hz(hours: float) -> Recording:
    t = np.arange(0.0, hours * 3600.0, 1.0)
    bed = 35.0 + 10.0 * np.sin(2 * np.pi * t / 86400.0)
    error = np.where(bed > 30.0, (bed - 30.0) / 10.0 * 300.0, 0.0)
    return Recording("<24 h at 1 Hz>", t, {"temp_bed_C": bed}, None, {"Z": np.full_like(t, -1000.0)}, {"Z": error})


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--program", default=str(ROOT / "fixtures" / "plc" / "tc_z.awl"))
    args = parser.parse_args()
    machine = ROOT / "fixtures" / "machines" / "bed_ramp.toml"
    recording = day_at_1hz(args.hours)
    started, cpu_started = time.perf_counter(), time.process_time()
    run = run_on_recording(args.program, machine, recording, "Z", cycle_s=1.0)
    replay_s, replay_cpu_s = time.perf_counter() - started, time.process_time() - cpu_started
    residual = recording.errors_um["Z"] - run.sim_um
    started = time.perf_counter()
    run_program(args.program, machine=machine, duration_s=args.hours * 3600.0, cycle_s=1.0)
    anchor_s = time.perf_counter() - started
    print(f"plc run --inputs: {len(recording.t_s):,} rows, {run.cycles:,} PLC cycles, {len(run.log.puts)} FB3 PUT "
          f"jobs in {replay_s:.1f} s wall, {replay_cpu_s:.1f} s CPU ({run.cycles / replay_s:,.0f} cycles/s; "
          f"target 24 h in < 60 s); "
          f"residual RMS {float(np.sqrt(np.mean(residual ** 2))):.2f} um")
    load = os.getloadavg()[0]
    print(f"load average {load:.1f} on {os.cpu_count()} cores (other work shares the machine)")
    print(f"anchor, plc run --duration {args.hours:g}h (profile-driven sensors): {anchor_s:.1f} s "
          f"({replay_s / anchor_s:.2f}x)")
    return 0 if replay_s < 60.0 * args.hours / 24.0 else 1


if __name__ == "__main__":
    sys.exit(main())
