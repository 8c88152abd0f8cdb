"""A living machine under load: the largest ``--speed`` at which the PLC cycle (1 s simulated) and the
recording keep up while 8 python-snap7 clients poll, and the server's CPU per simulated hour.

Usage: .venv/bin/python bench/bench_live.py [--speeds 600,1200,2400,4800,9600,19200] [--seconds 6] [--clients 8]
       [--poll-hz 20]

Each speed starts `nckemu serve --inputs ... --plc ... --speed S --loop --http 0` (loop_mill, its 36 h
recording, bed_only_z.awl), lets the clients poll PIW 420, SD43900[AX4] and actToolBasePos in one job
each (``--poll-hz`` per client), and reads the server's simulated time, lag and slips from the live
page's /status.json. A speed keeps up when simulated time advanced at least 98 % of speed x wall time
with no slip and at most a quarter of a wall second behind at the end. CPU: the server process's user + system time from /proc.

Anchor (same run): the offline `plc run --inputs` of the same program on the same recording, which
runs simulated time as fast as the computer allows (cycles/s, CPU per simulated hour); the live
figures are given as a ratio to it.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from nckemu.plcsim.replay import run_on_recording  # noqa: E402
from nckemu.thermal.recordings.recording import load_recording  # noqa: E402
from tests.support.live_tools import poll, serve  # noqa: E402

MACHINE = ROOT / "fixtures/machines/loop_mill.toml"
RECORDING = ROOT / "fixtures/thermal/loop_bed_program_spindle_lag.csv"
PROGRAM = ROOT / "fixtures/plc/bed_only_z.awl"
# Keeping up also means not drifting behind: at the end, at most this much wall time of lag.
MAX_LAG_WALL_S = 0.25


def _poller(port: int, period_s: float, stop: multiprocessing.synchronize.Event, counter: multiprocessing.Value) -> None:  # type: ignore[name-defined]
    import snap7

    client = snap7.Client()
    client.connect("127.0.0.1", 0, 4, port)
    n = 0
    next_s = time.monotonic()
    while not stop.is_set():
        poll(client, ref=n % 60000 + 1)
        n += 1
        next_s += period_s
        time.sleep(max(0.0, next_s - time.monotonic()))
    with counter.get_lock():
        counter.value += n
    client.disconnect()


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _status(port: int) -> dict:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/status.json", timeout=10) as answer:
        return json.loads(answer.read())


def measure(speed: float, seconds: float, clients: int, poll_hz: float) -> dict:
    with serve("--machine", str(MACHINE), "--inputs", str(RECORDING), "--plc", str(PROGRAM), "--loop",
               "--speed", f"{speed:g}x", "--http", "0") as served:
        http = int(served.ready["http"])
        stop = multiprocessing.Event()
        counter = multiprocessing.Value("l", 0)
        workers = [multiprocessing.Process(target=_poller, args=(served.port, 1.0 / poll_hz, stop, counter))
                   for _ in range(clients)]
        for worker in workers:
            worker.start()
        time.sleep(1.0)  # connected, warm
        first, cpu0, wall0 = _status(http), _cpu_s(served.process.pid), time.monotonic()
        time.sleep(seconds)
        last, cpu1, wall1 = _status(http), _cpu_s(served.process.pid), time.monotonic()
        stop.set()
        for worker in workers:
            worker.join(timeout=20)
    wall = wall1 - wall0
    simulated = last["live"]["t_s"] - first["live"]["t_s"]
    achieved = simulated / wall
    slips = last["live"]["slips"] - first["live"]["slips"]
    return {"speed": speed, "achieved": achieved, "slips": slips, "lag_s": last["live"]["lag_s"],
            "cycles": last["live"]["cycles"] - first["live"]["cycles"], "polls_per_s": counter.value / (wall + 1.0),
            "cpu_s_per_sim_h": (cpu1 - cpu0) / (simulated / 3600.0) if simulated > 0 else float("nan"),
            "keeps_up": achieved >= 0.98 * speed and slips == 0 and last["live"]["lag_s"] / speed <= MAX_LAG_WALL_S,
            "step_wall_ms": last["live"]["step_wall_ms"], "puts": last["live"]["jobs"]["PUT"]}


def anchor(hours: float) -> tuple[float, float]:
    """Offline plc run --inputs over ``hours`` of the recording: cycles/s and CPU s per simulated hour."""
    recording = load_recording(RECORDING)
    recording = recording.slice(recording.t_s <= hours * 3600.0)
    started, cpu = time.perf_counter(), time.process_time()
    run = run_on_recording(PROGRAM, MACHINE, recording, "Z", cycle_s=1.0, progress=False)
    wall, cpu = time.perf_counter() - started, time.process_time() - cpu
    return run.cycles / wall, cpu / (run.cycles / 3600.0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speeds", default="600,1200,2400,4800,9600,19200")
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--clients", type=int, default=8)
    parser.add_argument("--poll-hz", type=float, default=20.0)
    parser.add_argument("--anchor-hours", type=float, default=2.0)
    args = parser.parse_args()
    cycles_per_s, anchor_cpu = anchor(args.anchor_hours)
    print(f"anchor: offline plc run --inputs, {args.anchor_hours:g} h of {RECORDING.name}: {cycles_per_s:,.0f} "
          f"one-second cycles/s (= {cycles_per_s:,.0f}x as fast as possible), {anchor_cpu:.2f} s CPU per simulated hour")
    print(f"{args.clients} python-snap7 clients at {args.poll_hz:g} polls/s each (PIW 420, SD43900[AX4], "
          f"actToolBasePos, 2 x sysTimeUdword in one job); {args.seconds:g} s per speed")
    print("| --speed | achieved | keeps up | slips | lag (wall s) | polls/s | wall ms/cycle | CPU s per sim h | x anchor CPU |")
    print("|---|---|---|---|---|---|---|---|---|")
    best = 0.0
    for speed in (float(s.strip().removesuffix("x")) for s in args.speeds.split(",")):
        r = measure(speed, args.seconds, args.clients, args.poll_hz)
        print(f"| {speed:g}x | {r['achieved']:,.0f}x | {'yes' if r['keeps_up'] else 'no'} | {r['slips']} | "
              f"{r['lag_s'] / speed:.3f} | {r['polls_per_s']:.0f} | {r['step_wall_ms']:.3f} | {r['cpu_s_per_sim_h']:.2f} | "
              f"{r['cpu_s_per_sim_h'] / anchor_cpu:.2f} |", flush=True)
        if r["keeps_up"]:
            best = max(best, speed)
    load = os.getloadavg()[0]
    print(f"largest speed that keeps up: {best:g}x ({best / cycles_per_s:.2f} of the offline anchor's wall pace, "
          f"{best * anchor_cpu / 3600.0:.2f} of its CPU pace); "
          f"load average {load:.1f} on {os.cpu_count()} cores (other work shares the machine)")
    return 0 if best >= 600 else 1


if __name__ == "__main__":
    sys.exit(main())
