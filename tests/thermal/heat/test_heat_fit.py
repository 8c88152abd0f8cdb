"""Issue 50: heat identification finds concealed heat physics again, with its figures, and names
nothing where there is none (generated machines: nckemu/thermal/heat/scenarios.py)."""

from __future__ import annotations

import numpy as np
import pytest

from nckemu.heat_response import SENSOR, SPINDLE, simulate
from nckemu.thermal.heat.fit import fit_heat
from nckemu.thermal.heat.scenarios import FAMILIES, generate, judged
from nckemu.thermal.heat.table import HeatRun
from nckemu.thermal.model.lags import first_order_lag


def _found(fit):
    return {s.sensor: [n.term for n in s.terms] for s in fit.sensors}


@pytest.mark.parametrize("family", FAMILIES)
def test_each_family_is_named_with_its_figures_on_one_seed(family):
    scenario = generate(family, 0)
    fit = fit_heat([scenario.run])
    named, false = judged(scenario, _found(fit))
    assert named, (scenario.truth[scenario.subject], _found(fit)[scenario.subject])
    assert false == []
    assert fit.reference == ["ambient"]
    subject = next(s for s in fit.sensors if s.sensor == scenario.subject)
    assert subject.heldout_after_K < 0.2 * subject.heldout_before_K


@pytest.mark.slow
@pytest.mark.parametrize("family", FAMILIES)
def test_twenty_seeds_each_named_and_nulls_silent(family):
    named_count, false_all = 0, []
    for seed in range(20):
        scenario = generate(family, seed)
        named, false = judged(scenario, _found(fit_heat([scenario.run])))
        named_count += named
        false_all += [f"seed {seed}: {line}" for line in false]
    assert named_count >= 18, f"{family}: named in {named_count} of 20"
    assert false_all == []


def test_a_series_stepped_as_the_twin_steps_it_equals_the_fit_columns():
    """heat_response.simulate (the twin's stepping) and first_order_lag (the fit's columns) agree."""
    t_s = np.arange(0.0, 6 * 3600.0, 60.0)
    rpm = np.where((t_s // 1800) % 2 == 1, 8000.0, 0.0)
    from nckemu.heat_response import HeatTerm
    terms = {"bearing": (HeatTerm(SPINDLE, 0.3, 1500.0, 1.4),),
             "frame": (HeatTerm(SENSOR, 0.5, 3600.0, sensor="bearing", from_C=20.0),)}
    out = simulate(t_s, {SPINDLE: rpm}, {"bearing": 20.0, "frame": 20.0}, terms)
    bearing = 20.0 + 0.3 * first_order_lag(t_s, (rpm / 1000.0) ** 1.4, 1500.0)
    np.testing.assert_allclose(out["bearing"], bearing, atol=1e-9)
    np.testing.assert_allclose(out["frame"], 20.0 + 0.5 * first_order_lag(t_s, bearing - 20.0, 3600.0), atol=1e-9)


def test_several_runs_are_judged_each_held_out():
    """One machine's 48 h cut into four runs of 12 h: each run held out once, each with its own offset."""
    whole = generate("speed_power", 0, hours=48.0)
    run, cut = whole.run, len(whole.run.t_s) // 4
    runs = [HeatRun(f"run{k}", run.t_s[k * cut:(k + 1) * cut],
                    {name: values[k * cut:(k + 1) * cut] + 0.5 * k for name, values in run.sensors_C.items()},
                    {name: values[k * cut:(k + 1) * cut] for name, values in run.inputs.items()})
            for k in range(4)]
    fit = fit_heat(runs)
    assert "each held out once" in fit.judged_on
    bearing = next(s for s in fit.sensors if s.sensor == "bearing")
    named, false = judged(whole, {s.sensor: [n.term for n in s.terms] for s in fit.sensors})
    assert named and false == []
    assert bearing.heldout_after_K < 0.2 * bearing.heldout_before_K
