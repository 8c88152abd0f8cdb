"""Fleet discovery on Dask: 200 synthetic machine-days with 1 and 2 local workers, and the scaling ratio.

The fleet: ``--machines`` folders (default 50) of ``--days`` one-day runs each (default 4: 200
machine-days), made by the scenario generator (``thermal/synthetic/scenarios.py``, the scenarios in turn, one
seed per machine) at its 60 s sampling, with each machine's baseline model. Written as CSV, read by
the workers.

Measured in the same run:
* the anchor: every machine's ``discover_machine`` called in this process, one after another (what a
  task costs without Dask);
* ``discover --fleet`` on a local cluster of 1 and of 2 worker processes (started before the clock
  runs; the scheduler address is handed over as ``--scheduler`` would be): wall time, machine-days/s;
  the scaling ratio (1-worker time / 2-worker time; 2.0 is perfect) and each against the anchor;
* the workers' resident memory after the run;
* one dense machine-day (1 Hz, 86400 samples) read from CSV and discovered in this process: the cost
  per machine-day the plan in docs/fleet.md extrapolates from.

Usage: .venv/bin/python bench/bench_fleet_discover.py [--machines 50] [--days 4] [--workers 1 2]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from nckemu.thermal.fleet.discover import discover_fleet, discover_machine, scan_root
from nckemu.thermal.model.terms import render_model
from nckemu.thermal.recordings.recording import load_recording, write_recording
from nckemu.thermal.synthetic.scenarios import SCENARIOS, make_scenario

DAY_S = 86400.0


def write_fleet(root: Path, machines: int, days: int, dt_s: float = 60.0) -> None:
    for index in range(machines):
        made = make_scenario(SCENARIOS[index % len(SCENARIOS)], seed=100 + index, duration_h=24.0 * days, dt_s=dt_s)
        folder = root / f"m{index + 1:04d}"
        folder.mkdir(parents=True)
        t_s = made.recording.t_s
        for day in range(days):
            inside = (t_s >= day * DAY_S) & (t_s < (day + 1) * DAY_S)
            write_recording(folder / f"day{day + 1:03d}.csv", made.recording.slice(inside))
        (folder / "model.toml").write_text(render_model(made.baseline), encoding="utf-8")


def on_cluster(root: Path, workers: int) -> dict[str, float]:
    import psutil
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      host="127.0.0.1") as cluster:
        def cpu_s() -> float:
            times = psutil.Process().cpu_times()
            return float(times.user + times.system)

        with Client(cluster) as client:
            client.wait_for_workers(workers)
            cpu_before = sum(client.run(cpu_s).values())
        started = time.perf_counter()
        document = discover_fleet(scan_root(root), scheduler=cluster.scheduler_address)
        seconds = time.perf_counter() - started
        with Client(cluster) as client:
            rss = client.run(lambda: psutil.Process().memory_info().rss / 2**20)
            cpu_used_s = sum(client.run(cpu_s).values()) - cpu_before
    if document["failed"]:
        raise RuntimeError(f"machines failed: {document['failed']}")
    # cores the workers had on average: below their count, the host (not Dask) limited the scaling
    return {"seconds": seconds, "worker_rss_mb": max(rss.values()), "machines": len(document["machines"]),
            "worker_cores_used": cpu_used_s / seconds, "worker_cpu_s": cpu_used_s}


def dense_day(root: Path) -> dict[str, float]:
    folder = root / "dense"
    write_fleet(folder, 1, 1, dt_s=1.0)
    machine = scan_root(folder)[0]
    started = time.perf_counter()
    result = discover_machine(machine)
    seconds = time.perf_counter() - started
    started = time.perf_counter()
    load_recording(machine.runs[0])
    read_s = time.perf_counter() - started
    size_mb = sum(Path(run).stat().st_size for run in machine.runs) / 2**20
    return {"seconds": seconds, "read_s": read_s, "csv_mb": size_mb, "samples": result["findings"]["samples"]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--machines", type=int, default=50)
    parser.add_argument("--days", type=int, default=4)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    import os

    busy = os.getloadavg()[0]
    machine_days = args.machines * args.days
    with tempfile.TemporaryDirectory(prefix="nckemu-fleet-") as temporary:
        root = Path(temporary) / "fleet"
        write_fleet(root, args.machines, args.days)
        machines = scan_root(root)
        discover_machine(machines[0])  # imports and first-call costs, which each worker pays once too
        started = time.perf_counter()
        for machine in machines:
            discover_machine(machine)
        anchor_s = time.perf_counter() - started
        runs = {workers: on_cluster(root, workers) for workers in args.workers}
        dense = dense_day(Path(temporary))
    base = runs[args.workers[0]]["seconds"]
    result = {
        "machine_days": machine_days, "machines": args.machines, "anchor_in_process_s": anchor_s,
        "anchor_s_per_machine_day": anchor_s / machine_days,
        "clusters": {str(w): {**r, "machine_days_per_s": machine_days / r["seconds"],
                              "cpu_s_per_machine_day": r["worker_cpu_s"] / machine_days,
                              "speedup_over_first": base / r["seconds"], "over_anchor": anchor_s / r["seconds"]}
                     for w, r in runs.items()},
        "dense_machine_day": dense, "cores": os.cpu_count(), "load_average_at_start": busy,
    }
    if args.json:
        print(json.dumps(result))
        return 0
    print(f"{machine_days} machine-days ({args.machines} machines x {args.days} days, 60 s sampling); "
          f"{os.cpu_count()} cores, load average {busy:.1f} at start")
    print(f"anchor, in this process one after another: {anchor_s:.1f} s ({1000 * anchor_s / machine_days:.0f} ms "
          f"per machine-day)")
    for workers, figures in result["clusters"].items():
        print(f"local cluster, {workers} worker(s): {figures['seconds']:.1f} s, {figures['machine_days_per_s']:.2f} "
              f"machine-days/s, x{figures['speedup_over_first']:.2f} over {args.workers[0]} worker(s), "
              f"x{figures['over_anchor']:.2f} over the anchor; workers used {figures['worker_cores_used']:.2f} cores, "
              f"{1000 * figures['cpu_s_per_machine_day']:.0f} ms CPU per machine-day; "
              f"worker RSS {figures['worker_rss_mb']:.0f} MB")
    print(f"one dense machine-day (1 Hz, {dense['samples']} samples, {dense['csv_mb']:.1f} MB CSV): read and "
          f"discovered in {dense['seconds']:.1f} s, of which reading the CSV {dense['read_s']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
