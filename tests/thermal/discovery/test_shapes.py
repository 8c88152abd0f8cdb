"""Parsimony by shape (issue 51): a temperature with its own lag is named as the transient and static
part it spans, a term's bar is weighed by its parameters, and a second time constant that a later
temperature made redundant is withdrawn."""

from __future__ import annotations

import numpy as np
import pytest

from nckemu.thermal.discovery import shapes
from nckemu.thermal.discovery.discover import discover_runs
from nckemu.thermal.discovery.fits import cancelling
from nckemu.thermal.discovery.settings import Settings
from nckemu.thermal.model.lags import first_order_lag
from nckemu.thermal.model.terms import Term
from nckemu.thermal.synthetic.scenarios import AXIS, SHAPE_SENSOR, SHAPE_TAU_S, make_shape_family


def test_a_temperature_and_its_lag_span_the_transient_and_a_static_part() -> None:
    t = np.arange(0.0, 8 * 3600.0, 60.0)
    sensor = 20.0 + 5.0 * (t > 3600.0)
    lag = first_order_lag(t, sensor, 1800.0)
    a, b = 12.0, -8.5  # the pair: temperature +12 um/K, its lag -8.5 um/K
    pair = a * (sensor - 20.0) + b * (lag - 20.0)
    shape = (a + b) * (sensor - 20.0) - b * (sensor - lag)
    assert np.allclose(pair, shape)
    terms = [Term("temperature", {"sensor": "rear", "t_ref_C": 20.0, "coeff_um_per_K": a}),
             Term("thermal_lag", {"sensor": "rear", "t_ref_C": 20.0, "tau_s": 1800.0, "coeff_um_per_K": b})]
    assert shapes.temperature_with_lag(terms) == [(0, 1)]
    assert shapes.as_transient(terms[1]).effect == "transient_gradient"
    words = shapes.shape_words("rear", 1800.0, b, a)
    assert "a transient of rear at 0.5 h (+8.5 um/K" in words and "static part (+3.5 um/K)" in words


def test_each_parameter_buys_its_share() -> None:
    assert shapes.parameter_bar(0.05, 1) == pytest.approx(0.05)
    assert shapes.parameter_bar(0.05, 2) == pytest.approx(0.0975)
    assert shapes.parameters_of(Term("heating_cooling_hysteresis", {"sensor": "a", "tau_heat_s": 600.0,
                                                                    "tau_cool_s": 900.0})) == 3


def test_a_transient_with_a_static_part_is_named_as_that_shape() -> None:
    """Seed 1 named the rear at two time constants in the first round (the slow one standing in for the
    static part), then the static part: three terms. The slow one is now withdrawn."""
    family = make_shape_family("transient_as_pair", 1)
    result = discover_runs(family.runs, AXIS, family.model)
    rear = [m for m in result.missing_physics if m.parameters.get("sensor") == SHAPE_SENSOR]
    transients = [m for m in rear if m.effect == "transient_gradient"]
    assert len(transients) == 1 and abs(transients[0].parameters["tau_s"] - SHAPE_TAU_S) <= 0.25 * SHAPE_TAU_S
    assert not any(m.effect == "thermal_lag" for m in rear)
    assert any(w.effect == "transient_gradient" and "explain what it did" in w.why for w in result.withdrawn)


def test_two_large_terms_that_cancel_are_what_a_machine_cannot_have() -> None:
    """Lags of two neighbouring sensors at +20 and -15 um/K (fl_thermal ch5, the bar weighed in the
    rounds): each moves the structure by more than the whole error, together by a fraction of it.
    Two correlated sensors at 3 and -1.5 um/K (pair_days' truth), each within the error, pass."""
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 10 * 3600.0, 60.0)
    rising = np.sin(2 * np.pi * t / 36000.0)
    near, neighbour = rising, rising + 0.15 * rng.normal(size=t.size)
    full = np.column_stack([near, neighbour])
    named = (Term("thermal_lag", {"sensor": "t3", "tau_s": 2500.0, "coeff_um_per_K": 20.0}),)
    new = (Term("thermal_lag", {"sensor": "t1", "tau_s": 4150.0, "coeff_um_per_K": -15.0}),)
    y = 5.0 * rising
    words = cancelling(full, np.array([20.0, -15.0]), y, named, new, Settings())
    assert "cancel each other" in words and "thermal_lag(t3)" in words and "+20" in words and "-15" in words
    assert cancelling(full, np.array([3.0, -1.5]), y, named, new, Settings()) == ""  # within the error
    assert cancelling(full, np.array([20.0, -15.0]), y, named, new, Settings(cancelling_share=0.0)) == ""
    assert cancelling(full, np.array([20.0, -15.0]), y, (), new, Settings()) == ""  # nothing named yet
