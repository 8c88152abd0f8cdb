"""Heat identification's run time (issue 50: under 60 s here for each case), with the same family search
on the time-constant grid alone (no continuous polish of time constants and powers) as the anchor,
measured in the same run:

1. 16 sensors on 46 h at 15 s: ../shared/data/fl_thermal/recording.csv (read and put on the fit's 60 s
   grid, as `nckemu machine fit` does), or, without ../shared, a generated recording of that size;
2. 30 runs x 24 h at 1 Hz of one generated machine (6 sensors: the room, a cabinet, a bearing at
   speed^1.6, a housing at two time constants, a table the coolant cools, a frame its neighbour heats),
   each put on the 60 s grid (the time to do so is printed), each run held out once.

Usage: .venv/bin/python bench/bench_heat.py [--runs 30] [--hours 24] [--no-anchor]
(NCKEMU_SHARED=DIR: where ../shared is, from a git worktree)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from nckemu.heat_response import SENSOR, SPINDLE, HeatTerm, simulate  # noqa: E402
from nckemu.thermal.heat.fit import Settings, fit_heat  # noqa: E402
from nckemu.thermal.heat.table import load_heat_runs, to_grid  # noqa: E402

SHARED = Path(os.environ.get("NCKEMU_SHARED") or Path(__file__).resolve().parent.parent.parent / "shared")
FL = SHARED / "data" / "fl_thermal" / "recording.csv"
MACHINE = {
    "bearing": (HeatTerm(SPINDLE, 0.2, 1800.0, 1.6),),
    "housing": (HeatTerm(SPINDLE, 0.3, 900.0, 1.0), HeatTerm(SPINDLE, 0.4, 10800.0, 1.0)),
    "table": (HeatTerm(SPINDLE, 0.3, 1500.0, 1.0), HeatTerm("coolant", -2.0, 1200.0)),
    "frame": (HeatTerm(SENSOR, 0.4, 5400.0, sensor="bearing", from_C=20.0),),
}


def blocks(rng: np.random.Generator, count: int, length: tuple[int, int], values: list[float]) -> np.ndarray:
    out, k = np.empty(count), 0
    while k < count:
        n = int(rng.integers(*length))
        out[k:k + n] = values[int(rng.integers(len(values)))]
        k += n
    return out


def generated_run(index: int, hours: float, dt_s: float) -> tuple[np.ndarray, dict, dict]:
    """One day of the machine at ``dt_s``: raw rows as a logger writes them."""
    rng = np.random.default_rng(index)
    t_s = np.arange(0.0, hours * 3600.0, dt_s)
    count = len(t_s)
    per_minute = int(round(60.0 / dt_s))
    rpm = np.repeat(blocks(rng, count // per_minute + 1, (40, 120), [0.0, 0.0, 3000.0, 6000.0, 9000.0, 12000.0]),
                    per_minute)[:count]
    coolant = np.repeat(blocks(rng, count // per_minute + 1, (30, 90), [0.0, 1.0]), per_minute)[:count]
    room = 20.0 + 2.0 * np.sin(2 * np.pi * (t_s / 86400.0 + rng.uniform()))
    inputs = {SPINDLE: rpm, "coolant": coolant}
    base = {"bearing": 20.0, "housing": 20.0, "table": 20.0, "frame": 20.0, "cabinet": 22.0}
    coarse = slice(None, None, per_minute)   # the physics on a minute's grid, the rows at dt_s
    truth = simulate(t_s[coarse], {k: v[coarse] for k, v in inputs.items()}, base, MACHINE, {"room": room[coarse]})
    sensors = {name: np.interp(t_s, t_s[coarse], values) + rng.normal(0.0, 0.03, count)
               for name, values in truth.items()}
    return t_s, sensors, inputs


def timed(label: str, work) -> object:
    started = time.perf_counter()
    result = work()
    print(f"{label}: {time.perf_counter() - started:.1f} s", flush=True)
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--no-anchor", action="store_true")
    args = parser.parse_args()
    anchor = Settings(polish=False)

    if FL.exists():
        runs = timed("FL_THERMAL: read and put on the 60 s grid", lambda: load_heat_runs([str(FL)], [SPINDLE]))
    else:
        t_s, sensors, inputs = generated_run(0, 46.0, 15.0)
        sensors.update({f"extra{k}": sensors["bearing"] * (0.1 * k) + 20.0 for k in range(10)})
        runs = [timed("generated 46 h at 15 s: put on the 60 s grid", lambda: to_grid("day", t_s, sensors, inputs, 60.0))]
    fit = timed(f"16 sensors x 46 h ({sum(len(r.t_s) for r in runs)} grid rows): fit", lambda: fit_heat(runs))
    print(f"  median held-out {np.median([s.heldout_after_K for s in fit.sensors if s.terms]):.3f} K")
    if not args.no_anchor:
        timed("  anchor, the time-constant grid alone", lambda: fit_heat(runs, anchor))

    raw = timed(f"{args.runs} runs x {args.hours:g} h at 1 Hz: generated",
                lambda: [generated_run(k, args.hours, 1.0) for k in range(args.runs)])
    print(f"  {sum(len(t) for t, _s, _i in raw) / 1e6:.2f} million rows x {len(raw[0][1])} sensors")
    runs = timed("  put on the 60 s grid", lambda: [to_grid(f"day{k:02d}", t, s, i, 60.0)
                                                   for k, (t, s, i) in enumerate(raw)])
    fit = timed("  fit, each run held out once", lambda: fit_heat(runs))
    for result in fit.sensors:
        print(f"  {result.sensor}: " + "; ".join(n.term.words() for n in result.terms))
    if not args.no_anchor:
        timed("  anchor, the time-constant grid alone", lambda: fit_heat(runs, anchor))
    return 0


if __name__ == "__main__":
    sys.exit(main())
