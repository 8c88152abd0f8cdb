"""Runs that follow another relation in more than one term (issue 51, the held-back month's shape):
on ``reversed_month`` the spindle rear's three terms change sign on six runs. The group is found from
the residual's relation even though one coefficient a group still leaves a quiet run worse (named, as
a term of one coefficient is), and the later terms are fitted apart on the same groups; the headline
gives the group once, with the final model's figures."""

from __future__ import annotations

import numpy as np
import pytest

from nckemu.thermal.discovery.discover import Discovery, discover_runs
from nckemu.thermal.discovery.wording import headline_lines
from nckemu.thermal.synthetic.scenarios import AXIS, MONTH_REVERSED_RUNS, RunFamily, make_month_family

# Seed 7: before the group was carried, no split harming a run was named, and nothing was: median over
# runs 5.020 um, worst run 13.808 um.
SEED = 7


@pytest.fixture(scope="module")
def month() -> tuple[RunFamily, Discovery]:
    family = make_month_family("reversed_month", SEED)
    return family, discover_runs(family.runs, AXIS, family.model)


def test_the_reversed_runs_are_one_group_with_every_term_fitted_apart(month: tuple[RunFamily, Discovery]) -> None:
    family, result = month
    reversed_runs = {family.runs[i].name for i in MONTH_REVERSED_RUNS}
    apart = [m for m in result.missing_physics if m.evidence.regime is not None and m.evidence.regime.apart]
    assert len(apart) >= 2, [m.effect for m in result.missing_physics]
    groups = {frozenset(m.evidence.regime.runs) for m in apart}
    assert len(groups) == 1  # the later terms are fitted apart on the group named first
    group = next(iter(groups))
    assert reversed_runs <= group and len(group - reversed_runs) <= 1  # at most a quiet light run beside them
    first, carried = apart[0], apart[1]
    assert "was named on" in carried.evidence.why and "was named on" not in first.evidence.why
    labels = {f"{m.effect}({m.parameters.get('sensor', m.parameters.get('sensors'))})" for m in result.missing_physics}
    assert len(labels) <= 4
    assert result.heldout_rms_after_um < 0.6 * result.heldout_rms_before_um
    assert result.run_figures["worst_after_um"] <= 6.5


def test_the_headline_gives_the_group_once_with_the_final_figures(month: tuple[RunFamily, Discovery]) -> None:
    _family, result = month
    lines = headline_lines(result)
    assert len(lines) <= 4
    apart = next(m for m in result.missing_physics if m.evidence.regime is not None and m.evidence.regime.apart)
    figure = lines[-1]
    assert figure.count(f"on {apart.evidence.regime.runs_words}: median") == 1
    rows = [row for row in result.runs if row["name"] in set(apart.evidence.regime.runs)]
    final_median = float(np.median([row["heldout_rms_after_um"] for row in rows]))
    assert f"-> {final_median:.3f} um (one coefficient for all runs" in figure
