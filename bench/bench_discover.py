"""Discovery run time on a 24 h, 1 Hz, 10-sensor recording, and how it grows with record length.

Usage: .venv/bin/python bench/bench_discover.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from nckemu.thermal.discovery.discover import discover  # noqa: E402
from nckemu.thermal.model.lags import first_order_lag  # noqa: E402
from nckemu.thermal.model.terms import Term, ThermalModel  # noqa: E402
from nckemu.thermal.recordings.recording import Recording  # noqa: E402


def recording(hours: float, sensors: int = 10, seed: int = 1) -> Recording:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, hours * 3600.0, 1.0)
    rpm = np.where((t // 7200) % 2 == 1, 6000.0, 0.0)
    ambient = 20 + np.sin(2 * np.pi * t / 86400)
    temperatures = {}
    for index in range(sensors):
        tau = 600.0 * (index + 1)
        temperatures[f"temp_s{index}_C"] = first_order_lag(t, ambient + (index % 4 + 1) * rpm / 3000, tau) \
            + rng.normal(0, 0.03, len(t))
    truth = 3 * (temperatures["temp_s0_C"] - 20) + 1.5 * (first_order_lag(t, temperatures["temp_s3_C"], 2400) - 20)
    error = truth + rng.normal(0, 0.4, len(t))
    error[np.arange(len(t)) % 120 != 0] = np.nan  # a gauge read every 2 minutes
    return Recording("<bench>", t, temperatures, rpm, {}, {"Z": error})


def main() -> int:
    model = ThermalModel("Z", [Term("offset", {"value_um": 0.0}),
                               Term("temperature", {"sensor": "s0", "t_ref_C": 20.0, "coeff_um_per_K": 3.0})])
    print("hours  samples  gauge_readings  seconds  found")
    for hours in (6, 12, 24, 48):
        rec = recording(hours)
        started = time.perf_counter()
        result = discover(rec, model=model)
        elapsed = time.perf_counter() - started
        found = ", ".join(m.effect for m in result.missing_physics) or "-"
        print(f"{hours:5}  {len(rec.t_s):7}  {result.samples:14}  {elapsed:7.2f}  {found}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
