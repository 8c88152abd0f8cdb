"""The candidate library: which terms a round tries, with their features; what some runs lack."""

from __future__ import annotations

import numpy as np

from nckemu.thermal.discovery.library import Library, bounded, extends, label, present_key, time_constants
from nckemu.thermal.discovery.problem import Problem
from nckemu.thermal.discovery.readings import prepare
from nckemu.thermal.discovery.settings import Settings
from nckemu.thermal.model.lags import first_order_lag
from nckemu.thermal.model.terms import Term, parse_model, render_model
from nckemu.thermal.synthetic.scenarios import make_scenario


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


def test_columns_some_runs_lack_are_named_and_judged_where_they_are() -> None:
    library = _library(runs=3)
    assert library.unavailable == {"spindle_rpm": ["run2"], "temp_rear_C": ["run1"]}
    assert "rear" in library.sensors() and library.has_spindle()  # two of three runs have them
    assert "judged on the runs that have it" in library.handling("temp_rear_C")
    design = np.column_stack([library.problem.feature(t) for t in library.problem.base_terms])
    candidates = {c.label: c for c in library.candidates(design, set())}
    assert "offset" not in candidates  # each run's own offset is in the baseline
    rear = candidates["temperature(rear)"]
    assert list(rear.runs_with) == [True, False, True]
    assert not rear.feature[library.problem.groups == 1].any()  # no contribution where it is missing
    assert list(candidates["centrifugal_growth"].runs_with) == [True, True, False]
    assert candidates["temperature(front)"].runs_with is None


def test_term_helpers() -> None:
    lag = Term("thermal_lag", {"sensor": "a", "tau_s": 600.0, "coeff_um_per_K": 1.0})
    plain = Term("temperature", {"sensor": "a", "coeff_um_per_K": 1.0})
    assert extends(lag, plain) and not extends(plain, lag)
    assert time_constants(lag) == 1 and bounded(lag) and not bounded(Term("thermal_lag", {"tau_s": 10.0}))
    assert label(Term("thermal_gradient", {"sensors": ["a", "b"]})) == "thermal_gradient(a - b)"
    assert present_key(lag) == "thermal_lag:a" and present_key(Term("offset", {})) == "offset"


def test_the_transient_family_reads_as_an_engineer_reads_it() -> None:
    """transient_gradient(sensor, tau): the sensor less its own first-order lag, in um/K, no reference
    temperature (the difference has none); it extends the plain temperature of the same sensor."""
    transient = Term("transient_gradient", {"sensor": "a", "tau_s": 5400.0, "coeff_um_per_K": 4.0})
    plain = Term("temperature", {"sensor": "a", "coeff_um_per_K": 1.0})
    assert label(transient) == "transient_gradient(a)" and present_key(transient) == "transient_gradient:a"
    assert extends(transient, plain) and time_constants(transient) == 1 and bounded(transient)
    assert not bounded(Term("transient_gradient", {"sensor": "a", "tau_s": 30.0}))
    model = parse_model('axis = "Z"\n[[term]]\neffect = "transient_gradient"\nsensor = "front"\ntau_s = 5400\n'
                        'coeff_um_per_K = 4.0\n')
    assert render_model(model).count("t_ref_C") == 0
    recording = make_scenario("thermal_lag", 1).recording
    feature = model.terms[0].feature(recording, "Z")
    front = recording.sensor("front")
    assert np.allclose(feature, front - first_order_lag(recording.t_s, front, 5400.0))
    assert feature[0] == 0.0  # settled at the start


def test_a_round_offers_a_transient_per_sensor_with_its_time_constant_fitted() -> None:
    library = _library()
    design = np.column_stack([library.problem.feature(t) for t in library.problem.base_terms])
    transients = [c for c in library.candidates(design, set()) if c.term.effect == "transient_gradient"]
    assert {c.term.parameters["sensor"] for c in transients} == set(library.sensors())
    assert all(c.grid_points > 10 and 60 <= c.term.parameters["tau_s"] <= library.duration_s() / 3 * 1.25
               for c in transients)
    column = library.transient_column("front", 3600.0)
    assert column.shape == library.problem.y.shape
    assert "transient_gradient:front" not in {present_key(c.term) for c in
                                              library.candidates(design, {"transient_gradient:front"})
                                              if c.term.effect == "transient_gradient"}
