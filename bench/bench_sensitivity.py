"""Detection limit of discovery: for each concealed effect of the scenario generator, the smallest
size (the effect's RMS over the gauge readings, in units of the gauge noise RMS) at which it is named
first, with its parameter within 30 % (time constants 35 %), in at least 90 % of seeds.

Each effect is scaled down a ladder (1, 0.7, 0.5, ... of its size in the scenario) with the noise
unchanged (``scaled_scenario``); the walk stops at the first rung below 90 %.

Usage: .venv/bin/python bench/bench_sensitivity.py [--seeds 10] [--workers 2]
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from nckemu.thermal.discovery.discover import discover  # noqa: E402
from nckemu.thermal.synthetic.scenarios import AXIS, SCENARIOS, make_scenario, scaled_scenario  # noqa: E402

LADDER = (1.0, 0.7, 0.5, 0.35, 0.25, 0.18, 0.125, 0.09, 0.06, 0.04, 0.03)
LAG_PARAMETERS = {"tau_s", "tau_heat_s", "tau_cool_s"}
# The generator's gauge noise: white 0.3 um plus AR(1) 0.3 um.
NOISE_RMS_UM = float(np.hypot(0.3, 0.3))


def effect_rms_um(name: str, seed: int) -> float:
    """RMS of the effect's contribution at full size (about zero, so an offset counts), over the gauge readings."""
    full = make_scenario(name, seed).recording.errors_um[AXIS]
    reference = scaled_scenario(name, seed, 0.0).recording.errors_um[AXIS]
    contribution = (full - reference)[~np.isnan(full)]
    return float(np.sqrt(np.mean(np.square(contribution))))


def hit(job: tuple[str, float, int]) -> bool:
    name, scale, seed = job
    scenario = scaled_scenario(name, seed, scale)
    found = discover(scenario.recording, model=scenario.baseline).missing_physics
    if not found or found[0].effect != scenario.truth_effect:
        return False
    top = found[0].parameters
    return all(abs(top[key] - truth) <= (0.35 if key in LAG_PARAMETERS else 0.30) * abs(truth)
               for key, truth in scenario.truth_parameters.items())


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    seeds = range(1, args.seeds + 1)
    effects = [s for s in SCENARIOS if not s.startswith("null")]
    started = time.perf_counter()
    print(f"| effect | size in the scenario (x noise RMS) | smallest size found in >= 90 % of {args.seeds} seeds "
          "(x noise RMS) | rate there | rate one rung below |")
    print("|---|---|---|---|---|")
    with ProcessPoolExecutor(args.workers) as pool:
        for name in effects:
            size = float(np.mean([effect_rms_um(name, seed) for seed in seeds])) / NOISE_RMS_UM
            passed: tuple[float, float] | None = None
            below = "-"
            for scale in LADDER:
                rate = sum(pool.map(hit, [(name, scale, seed) for seed in seeds])) / len(seeds)
                if rate < 0.9:
                    below = f"{rate:.0%} at {scale * size:.2g}"
                    break
                passed = (scale, rate)
            limit = f"{passed[0] * size:.2g}" if passed else f"> {size:.2g}"
            there = f"{passed[1]:.0%}" if passed else "-"
            print(f"| {name} | {size:.2g} | {limit} | {there} | {below} |", flush=True)
    print(f"\n{time.perf_counter() - started:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
