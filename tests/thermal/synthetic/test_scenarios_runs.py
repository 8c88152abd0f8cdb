"""Families of runs: deterministic, field-like, and the concealed physics shows only across runs."""

from __future__ import annotations

import numpy as np
import pytest

from nckemu.thermal.model.lags import first_order_lag
from nckemu.thermal.synthetic.scenarios import (
    AXIS,
    FAMILY_GRADIENT_UM_PER_K,
    FAMILY_SENSORS,
    FAMILY_TAU_COOL_S,
    FAMILY_TAU_HEAT_S,
    RUN_FAMILIES,
    make_run_family,
)


@pytest.mark.parametrize("name", RUN_FAMILIES)
def test_a_family_is_deterministic_per_seed_and_field_like(name: str) -> None:
    family = make_run_family(name, seed=4, runs=8)
    again = make_run_family(name, seed=4, runs=8)
    other = make_run_family(name, seed=5, runs=8)
    assert [r.name for r in family.runs] == [f"{name}_s4_run{i:02d}" for i in range(1, 9)]
    for a, b in zip(family.runs, again.runs, strict=True):
        assert np.array_equal(a.errors_um[AXIS], b.errors_um[AXIS], equal_nan=True)
    assert not np.array_equal(family.runs[0].t_s, other.runs[0].t_s)
    for run in family.runs:
        steps = np.diff(run.t_s)
        assert steps.min() > 0 and steps.max() / steps.min() > 2  # irregular sampling
        assert {"temp_spindle_C", "temp_bed_C"} <= set(run.temperatures_C) <= {f"temp_{s}_C" for s in FAMILY_SENSORS}
        assert abs(run.errors_um[AXIS][0]) < 1.5  # re-referenced: the gauge reads about 0 at the start
    assert len(family.truth.offsets_um) == 8 and len(set(family.truth.offsets_um)) == 8
    if name.startswith("null"):
        assert family.truth.effect is None


def test_families_hold_gaps_runs_without_speed_and_runs_without_a_sensor() -> None:
    runs = [run for seed in range(1, 6) for run in make_run_family("job_mix_gradient", seed).runs]
    assert any(np.diff(run.t_s).max() > 600 for run in runs)
    assert any(run.spindle_rpm is None for run in runs)
    assert any(len(run.temperatures_C) < len(FAMILY_SENSORS) for run in runs)
    assert any(np.isnan(run.errors_um[AXIS]).any() for run in runs)


def test_a_null_shares_the_inputs_and_the_difference_is_the_concealed_term() -> None:
    family = make_run_family("job_mix_gradient", seed=2)
    null = make_run_family("null_job_mix", seed=2)
    assert family.truth.effect == "thermal_gradient"
    for run, plain in zip(family.runs, null.runs, strict=True):
        assert np.array_equal(run.t_s, plain.t_s)
        if "temp_rear_C" not in run.temperatures_C or "temp_front_C" not in run.temperatures_C:
            continue
        term = FAMILY_GRADIENT_UM_PER_K * (run.sensor("front") - run.sensor("rear"))
        difference = run.errors_um[AXIS] - plain.errors_um[AXIS]
        good = ~np.isnan(difference)
        assert np.sqrt(np.mean((difference - term)[good] ** 2)) < 0.5  # the readings' noise, 6 x 0.03 K x sqrt 2


def _best_lag_s(run, grid_s: np.ndarray) -> float:
    """The one time constant that best explains a run's reading, with the run's own offset and scale."""
    error = run.errors_um[AXIS] - 2.0 * (run.sensor("bed") - 20.0)
    good = ~np.isnan(error)
    costs = []
    for tau_s in grid_s:
        design = np.column_stack([np.ones(good.sum()), first_order_lag(run.t_s, run.sensor("spindle"), tau_s)[good]])
        _, residual, *_ = np.linalg.lstsq(design, error[good], rcond=None)
        costs.append(float(residual[0]))
    return float(grid_s[int(np.argmin(costs))])


def test_within_a_day_one_lag_fits_and_it_differs_between_heating_and_cooling_days() -> None:
    family = make_run_family("heating_cooling_days", seed=3)
    grid_s = np.geomspace(600.0, 4 * 3600.0, 25)
    best = {"heating": [], "cooling": []}
    for run, kind in zip(family.runs, family.truth.kinds, strict=True):
        best[kind].append(_best_lag_s(run, grid_s))
    assert len(best["heating"]) >= 2 and len(best["cooling"]) >= 2
    assert np.median(best["heating"]) == pytest.approx(FAMILY_TAU_HEAT_S, rel=0.35)
    assert np.median(best["cooling"]) == pytest.approx(FAMILY_TAU_COOL_S, rel=0.35)
    assert max(best["heating"]) < min(best["cooling"])


def test_the_bench_size_is_reachable() -> None:
    family = make_run_family("job_mix_gradient", seed=1, runs=2, hours_per_run=24.0, dt_s=1.0)
    rows = [len(run.t_s) for run in family.runs]
    assert all(80_000 < n < 87_000 for n in rows)  # 1 Hz on average over 24 h, less the gaps


def test_unknown_family_and_too_few_runs() -> None:
    with pytest.raises(ValueError, match="unknown run family"):
        make_run_family("magic")
    with pytest.raises(ValueError, match="at least 2 runs"):
        make_run_family("job_mix_gradient", runs=1)
