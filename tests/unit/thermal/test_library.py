"""The candidate library: which terms a round tries, with their features; what some runs lack."""

from __future__ import annotations

import numpy as np

from nckemu.thermal.library import Library, bounded, extends, label, present_key, time_constants
from nckemu.thermal.problem import Problem
from nckemu.thermal.readings import prepare
from nckemu.thermal.scenarios import make_scenario
from nckemu.thermal.settings import Settings
from nckemu.thermal.terms import Term


def _library(runs: int = 1) -> Library:
    recording = make_scenario("thermal_lag", 1).recording
    settings = Settings()
    if runs == 1:
        problem = Problem([("r", prepare(recording, settings))], "Z", make_scenario("thermal_lag", 1).baseline)
    else:
        edges = np.linspace(0, recording.t_s[-1] + 1, runs + 1)
        parts = [recording.slice((recording.t_s >= a) & (recording.t_s < b)) for a, b in zip(edges, edges[1:], strict=False)]
        del parts[1].temperatures_C["temp_rear_C"]
        parts[2].spindle_rpm = None
        problem = Problem([(f"run{i}", prepare(p, settings)) for i, p in enumerate(parts)], "Z",
                          make_scenario("thermal_lag", 1).baseline, per_run_offset=True)
    return Library(problem, settings)


def test_a_round_offers_every_family_once() -> None:
    library = _library()
    design = np.column_stack([library.problem.feature(t) for t in library.problem.base_terms])
    candidates = library.candidates(design, set())
    families = {c.term.effect for c in candidates}
    assert {"time_drift", "centrifugal_growth", "quadratic_temperature", "thermal_gradient",
            "thermal_lag", "heating_cooling_hysteresis", "position_dependent_expansion"} <= families
    lag = next(c for c in candidates if c.label == "thermal_lag(spindle)")
    assert lag.grid_points > 10 and lag.feature.shape == library.problem.y.shape
    assert 2000 < lag.term.parameters["tau_s"] < 3000  # the truth is 2400 s
    # a second call with the same design is served from the cache (same arrays)
    again = library.candidates(design, {"time_drift"})
    assert "time_drift" not in {c.term.effect for c in again}
    assert next(c for c in again if c.label == "thermal_lag(spindle)").feature is lag.feature


def test_columns_some_runs_lack_are_named_and_not_tried() -> None:
    library = _library(runs=3)
    assert library.unavailable == {"spindle_rpm": ["run2"], "temp_rear_C": ["run1"]}
    assert "rear" not in library.sensors() and not library.has_spindle()
    design = np.column_stack([library.problem.feature(t) for t in library.problem.base_terms])
    labels = {c.label for c in library.candidates(design, set())}
    assert not any("rear" in name for name in labels) and "centrifugal_growth" not in labels
    assert "offset" not in labels  # each run's own offset is in the baseline


def test_term_helpers() -> None:
    lag = Term("thermal_lag", {"sensor": "a", "tau_s": 600.0, "coeff_um_per_K": 1.0})
    plain = Term("temperature", {"sensor": "a", "coeff_um_per_K": 1.0})
    assert extends(lag, plain) and not extends(plain, lag)
    assert time_constants(lag) == 1 and bounded(lag) and not bounded(Term("thermal_lag", {"tau_s": 10.0}))
    assert label(Term("thermal_gradient", {"sensors": ["a", "b"]})) == "thermal_gradient(a - b)"
    assert present_key(lag) == "thermal_lag:a" and present_key(Term("offset", {})) == "offset"
