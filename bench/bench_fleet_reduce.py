"""Stage 1 of fleet discovery (``discover --fleet ROOT --reduce 60s``): what reducing a dense machine-day
costs, from Parquet and from CSV, and what it saves stage 2, against stage 2 on the raw days (the
anchor), in the same run and process.

The fleet: ``--machines`` folders of ``--days`` one-day files at 1 Hz (86400 rows each), made by the
scenario generator; each day written once as CSV and once as Parquet. Measured (process CPU seconds):
* stage 1 per machine-day: ``reduce_file`` on the Parquet day and on the CSV day;
* stage 2 per machine: ``discover_machine`` over its raw days (the anchor) and over its reduced days;
  the ratio, and whether both name the same physics.

Usage: .venv/bin/python bench/bench_fleet_reduce.py [--machines 3] [--days 2]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from nckemu.thermal.fleet.discover import MachineFolder, discover_machine
from nckemu.thermal.fleet.reduce import plan, reduce_file
from nckemu.thermal.model.terms import render_model
from nckemu.thermal.recordings.recording import write_recording
from nckemu.thermal.synthetic.scenarios import SCENARIOS, make_scenario

DAY_S = 86400.0


def write_days(root: Path, machines: int, days: int) -> list[tuple[MachineFolder, MachineFolder]]:
    """Each machine twice: its days as CSV and as Parquet (same values)."""
    made_machines = []
    for index in range(machines):
        made = make_scenario(SCENARIOS[index % len(SCENARIOS)], seed=300 + index, duration_h=24.0 * days, dt_s=1.0)
        folders = []
        for suffix in ("csv", "parquet"):
            folder = root / suffix / f"m{index + 1:02d}"
            folder.mkdir(parents=True)
            runs = []
            for day in range(days):
                inside = (made.recording.t_s >= day * DAY_S) & (made.recording.t_s < (day + 1) * DAY_S)
                path = folder / f"day{day + 1:03d}.{suffix}"
                write_recording(path, made.recording.slice(inside))
                runs.append(str(path))
            model = folder / "model.toml"
            model.write_text(render_model(made.baseline), encoding="utf-8")
            folders.append(MachineFolder(folder.name, tuple(runs), str(model)))
        made_machines.append((folders[0], folders[1]))
    return made_machines


def cpu_s() -> float:
    return time.process_time()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--machines", type=int, default=3)
    parser.add_argument("--days", type=int, default=2)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as directory:
        root = Path(directory)
        machines = write_days(root, args.machines, args.days)
        stage1 = {}
        reduced_machines = []
        for kind, pick in (("csv", 0), ("parquet", 1)):
            folders = [pair[pick] for pair in machines]
            tasks = plan(folders, root / kind, 60.0)
            start = cpu_s()
            for task in tasks:
                result = reduce_file(task, 60.0)
                assert "error" not in result, result
            stage1[kind] = (cpu_s() - start) / len(tasks)
            if kind == "parquet":
                reduced_machines = [MachineFolder(f.name, tuple(t.target for t in tasks if t.machine == f.name), f.model)
                                    for f in folders]
        raw_cpu = reduced_cpu = 0.0
        same = True
        for (_, raw_folder), reduced_folder in zip(machines, reduced_machines, strict=True):
            start = cpu_s()
            raw = discover_machine(raw_folder)
            raw_cpu += cpu_s() - start
            start = cpu_s()
            reduced = discover_machine(reduced_folder)
            reduced_cpu += cpu_s() - start
            names = [[e["effect"] for e in d["findings"]["missing_physics"]] for d in (raw, reduced)]
            same = same and names[0] == names[1]
    days = args.machines * args.days
    result = {"machine_days": days, "stage1_cpu_s_per_day_parquet": stage1["parquet"],
              "stage1_cpu_s_per_day_csv": stage1["csv"], "stage2_cpu_s_per_day_raw": raw_cpu / days,
              "stage2_cpu_s_per_day_reduced": reduced_cpu / days, "same_findings": same}
    if args.json:
        print(json.dumps(result))
        return 0
    print(f"{days} dense machine-days (1 Hz, 86400 rows each), {args.machines} machines")
    print(f"stage 1, reduce to 60 s means: {stage1['parquet']:.2f} s CPU per machine-day from Parquet, "
          f"{stage1['csv']:.2f} s from CSV (Parquet/CSV {stage1['parquet'] / stage1['csv']:.2f})")
    print(f"stage 2, discover: anchor on the raw days {raw_cpu / days:.2f} s CPU per machine-day, on the reduced "
          f"days {reduced_cpu / days:.2f} s (ratio {reduced_cpu / raw_cpu:.3f}); same physics named: {same}")
    print(f"both stages from Parquet: {stage1['parquet'] + reduced_cpu / days:.2f} s per machine-day against "
          f"{raw_cpu / days:.2f} s for discovery on the raw days")
    return 0


if __name__ == "__main__":
    sys.exit(main())
