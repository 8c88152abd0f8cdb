"""Runs that follow another relation (issue 51): a stretch of dates with the rear's effect reversed is
found from the residual's relation (or given by the run names), fitted apart with each run held out,
and named with its runs and both models' figures; a null names nothing; a bad --group-by is an error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from nckemu.errors import NckConfigError
from nckemu.thermal.discovery.discover import Discovery, discover_runs
from nckemu.thermal.discovery.regimes import consecutive, groups_by_column, groups_by_names, natural_break
from nckemu.thermal.discovery.wording import headline_lines
from nckemu.thermal.synthetic.scenarios import (
    AXIS,
    DUTY_MIX_LIGHT_RUNS,
    REGIME_RUNS,
    REGIME_UM_PER_K,
    SHAPE_SENSOR,
    RunFamily,
    make_duty_mix_family,
    make_shape_family,
    make_transient_family,
)


@pytest.fixture(scope="module")
def regime() -> tuple[RunFamily, Discovery]:
    family = make_shape_family("regime_days", 1)
    return family, discover_runs(family.runs, AXIS, family.model)


def test_the_reversed_stretch_is_found_and_fitted_apart(regime: tuple[RunFamily, Discovery]) -> None:
    family, result = regime
    groups = [m for m in result.missing_physics if m.evidence.regime is not None]
    assert len(groups) == 2 and all(m.parameters["sensor"] == SHAPE_SENSOR for m in groups)
    apart = next(m for m in groups if m.evidence.regime.apart)
    usual = next(m for m in groups if not m.evidence.regime.apart)
    assert set(apart.evidence.regime.runs) == {family.runs[i].name for i in REGIME_RUNS}
    assert abs(apart.parameters["coeff_um_per_K"] + REGIME_UM_PER_K) <= 0.25 * REGIME_UM_PER_K
    assert abs(usual.parameters["coeff_um_per_K"] - REGIME_UM_PER_K) <= 0.25 * REGIME_UM_PER_K
    # both models' figures: one coefficient for all runs leaves the reversed runs far worse
    assert apart.evidence.regime.median_after_um < apart.evidence.regime.median_one_coefficient_um / 2
    assert "10 consecutive runs" in apart.evidence.why and "fitted apart" in apart.evidence.why
    # the improved model holds one relation: the larger group's
    kept = [t.coefficient for t in result.improved_model.terms if t.parameters.get("sensor") == SHAPE_SENSOR]
    assert kept == pytest.approx([usual.parameters["coeff_um_per_K"]], abs=1e-6)
    lines = headline_lines(result)
    assert len(lines) <= 4 and "but" in lines[0] and "one coefficient for all runs" in lines[-1]
    assert result.to_json()["missing_physics"][0]["evidence"]["regime"]["runs"]


def test_groups_from_the_run_names() -> None:
    names = ["2017-01-05_TM1", "2017-02-25_TM7", "2017-03-02_TM10", "2017-01-20_TM3"]
    assert list(groups_by_names(names, r"2017-0([23])")) == [0, 1, 1, 0]  # "" twice, "2" and "3" apart
    assert groups_by_names(names, r"TM") is None
    with pytest.raises(NckConfigError, match="not a regular expression"):
        groups_by_names(names, "(")
    assert consecutive(["a", "b", "c", "d", "e"], np.array([0, 1, 1, 0, 0]))
    assert not consecutive(["a", "b", "c", "d", "e"], np.array([1, 0, 1, 0, 0]))


def test_given_groups_name_the_same_stretch() -> None:
    family = make_shape_family("regime_days", 2)
    result = discover_runs(family.runs, AXIS, family.model, group_by=r"2026-03-(1[1-9]|20)")
    apart = [m for m in result.missing_physics if m.evidence.regime is not None and m.evidence.regime.apart]
    assert apart and "the runs' names" in apart[0].evidence.why


def test_groups_from_a_column_of_the_recordings() -> None:
    # a code: the most common value against the rest; values that all differ: cut where groups are tightest
    assert list(natural_break(np.array([1.0, 2.0, 1.0, 1.0, 2.0, 2.0, 1.0]))) == [0, 1, 0, 0, 1, 1, 0]
    assert list(natural_break(np.array([0.1, 0.2, 0.15, 5.0, 5.5, 6.0, 4.8, 5.2]))) == [1, 1, 1, 0, 0, 0, 0, 0]
    assert natural_break(np.array([1.0, 1.0, 2.0, 1.0])) is None  # one run apart: too few
    family = make_duty_mix_family("duty_mix_days", 1)
    light = groups_by_column(family.runs, "spindle_rpm")
    assert light is not None and all(light[:DUTY_MIX_LIGHT_RUNS] == 1)  # the light days by their mean speed
    with pytest.raises(NckConfigError, match="no column 'coolant_flow'"):
        groups_by_column(family.runs, "coolant_flow")


def test_a_column_names_the_same_stretch() -> None:
    """A fixture's position (recorded, one value a run) marks the reversed days: offered as the grouping,
    it names them; a column no run has is refused before the search."""
    family = make_shape_family("regime_days", 2)
    for index, run in enumerate(family.runs):
        run.positions_mm["W"] = np.full(len(run.t_s), 100.0 if index in REGIME_RUNS else 0.0)
    result = discover_runs(family.runs, AXIS, family.model, group_by="column:W")
    apart = [m for m in result.missing_physics if m.evidence.regime is not None and m.evidence.regime.apart]
    assert apart and set(apart[0].evidence.regime.runs) == {family.runs[i].name for i in REGIME_RUNS}
    assert "the runs' W column" in apart[0].evidence.why
    with pytest.raises(NckConfigError, match="no column"):
        discover_runs(family.runs, AXIS, family.model, group_by="column:V")


def test_the_null_names_no_group() -> None:
    family = make_shape_family("null_shape_days", 1)
    assert not discover_runs(family.runs, AXIS, family.model).missing_physics


def test_the_report_leads_with_the_headline(regime: tuple[RunFamily, Discovery], tmp_path: Path) -> None:
    from nckemu.thermal.discovery.report import write_report

    _family, result = regime
    write_report(tmp_path / "r.html", result, "regime")
    page = (tmp_path / "r.html").read_text(encoding="utf-8")
    assert page.index("one coefficient for all runs") < page.index("Missing physics")


@pytest.mark.slow  # 30 runs searched: 5-20 s on two cores
def test_a_term_that_harms_the_light_days_is_fitted_apart_on_them() -> None:
    """Seed 14 of the duty mix: temperature(rear) helps the heavy days and leaves light days worse
    (0.6 -> 1.4 um: the coolant pump cycles the rear sensor). Fitted apart over the stretch of light days
    it harms none, and each group has its own size: the heavy days the 1.5 um/K the family left out, the
    light days next to nothing. (Before: the light days split off later on a front-rear gradient, and the
    rear's own size halved.)"""
    family = make_duty_mix_family("duty_mix_days", 14)
    result = discover_runs(family.runs, AXIS, family.model)
    groups = {m.evidence.regime.apart: m for m in result.missing_physics if m.evidence.regime is not None}
    assert set(groups) == {False, True} and all(m.parameters["sensor"] == "rear" for m in groups.values())
    assert set(groups[True].evidence.regime.runs) == {run.name for run in family.runs[:DUTY_MIX_LIGHT_RUNS]}
    assert abs(groups[False].parameters["coeff_um_per_K"] - 1.5) <= 0.3 * 1.5
    assert abs(groups[True].parameters["coeff_um_per_K"]) < 0.3
    assert "leaves runs worse than before" in groups[True].evidence.why
    assert not [row for row in result.runs
                if row["heldout_rms_after_um"] > 1.1 * row["heldout_rms_before_um"] + 0.3]


def test_a_term_fitted_apart_is_withdrawn_when_the_later_terms_explain_it() -> None:
    # pair_days seed 16: the rear's lag fitted apart on runs 20-26 first, then both temperatures; the
    # lag's two groups' columns together buy nothing over them, and are withdrawn as one.
    family = make_transient_family("pair_days", 16)
    result = discover_runs(family.runs, AXIS, family.model)
    assert {(m.effect, m.parameters.get("sensor")) for m in result.missing_physics} == \
        {("temperature", "rear"), ("temperature", "front")}
    assert all(m.evidence.regime is None for m in result.missing_physics)
    withdrawn = [w for w in result.withdrawn if w.label.endswith("fitted apart over groups of runs")]
    assert len(withdrawn) == 1 and withdrawn[0].effect == "thermal_lag"
    assert "for each of its 3 parameters" in withdrawn[0].why
