"""What stopped the search (issue 51: "the cap decides the model, not the data"). A search that reaches
Settings.max_effects judges the next round in full with the limit lifted, on a copy of its path: when
nothing would be admitted, the data stopped it (no "limit" guard on the closest candidates, words that
say so); when something would, the limit stopped it, and the words name what and its figure."""

from __future__ import annotations

import pytest

from nckemu.thermal.discovery.discover import Discovery, discover_runs
from nckemu.thermal.discovery.settings import Settings
from nckemu.thermal.discovery.wording import finding_lines
from nckemu.thermal.synthetic.scenarios import AXIS, make_transient_family

from .measured_runs import measured_runs

DATA_STOPPED = "nothing more earns its place; the data, not the limit, stopped the search"


def _terms(result: Discovery) -> list[tuple[str, str]]:
    return [(m.effect, str(m.parameters.get("sensor", m.parameters.get("sensors")))) for m in result.missing_physics]


def test_a_limit_reached_where_the_data_stop_says_the_data_stopped_it() -> None:
    # pair_days: the truth is two temperatures (rear +3, front -1.5 um/K); with room for two terms the
    # search names both and the next round, judged, admits nothing
    family = make_transient_family("pair_days", seed=1)
    result = discover_runs(family.runs, AXIS, family.model, Settings(max_effects=2))
    assert sorted(_terms(result)) == [("temperature", "front"), ("temperature", "rear")]
    assert result.stopped_by == "data" and not result.stopped_at_limit and not result.beyond_limit
    assert result.stopped.startswith("2 terms named, the most Settings.max_effects allows") \
        and DATA_STOPPED in result.stopped
    assert f"stopped: {result.stopped}" in finding_lines(result)
    document = result.to_json()
    assert document["stopped_by"] == "data" and document["stopped_at_limit"] == "" and document["beyond_limit"] == {}
    # the closest candidates were judged, and failed on their own guards
    assert result.closest and all("limit" not in item.held_back_by and item.held_back_by for item in result.closest)
    assert all(g.guard != "limit" for item in result.closest for g in item.guards)
    # the trial round left nothing behind: a search without the limit near ends where this one did
    free = discover_runs(family.runs, AXIS, family.model, Settings(max_effects=6))
    assert _terms(free) == _terms(result) and free.heldout_rms_after_um == result.heldout_rms_after_um
    assert [m.parameters for m in free.missing_physics] == [m.parameters for m in result.missing_physics]
    assert free.stopped_by == "data" and not free.stopped
    assert [(c.label, c.held_back_by) for c in free.closest] == [(c.label, c.held_back_by) for c in result.closest]
    assert free.smallest_detectable_um == result.smallest_detectable_um


def test_a_limit_that_cuts_the_search_short_names_what_the_next_round_would() -> None:
    family = make_transient_family("pair_days", seed=1)
    result = discover_runs(family.runs, AXIS, family.model, Settings(max_effects=1))
    assert _terms(result) == [("temperature", "rear")]
    assert result.stopped_by == "limit"
    assert result.beyond_limit["terms"] == ["temperature(front)"]
    before_um, after_um = result.beyond_limit["before_um"], result.beyond_limit["after_um"]
    assert after_um < 0.8 * before_um
    assert result.stopped == result.stopped_at_limit
    assert result.stopped_at_limit.startswith(
        f"1 term named, the most Settings.max_effects allows: the next round would name temperature(front) "
        f"(the median over runs of held-out RMS {before_um:.3g} -> {after_um:.3g} um): the limit, not the data, "
        f"stopped the search; raise Settings.max_effects to let it")
    assert result.to_json()["beyond_limit"]["terms"] == ["temperature(front)"]
    assert result.closest and all("limit" in item.held_back_by for item in result.closest)


@pytest.mark.slow  # two discoveries of 14 measured runs: ~15 s on two cores
def test_fl_thermal_ch5_is_stopped_by_its_data_not_by_the_limit() -> None:
    runs = measured_runs("fl_thermal/recording.csv", 3.5)
    result = discover_runs(runs, "ch5", None)
    assert len(result.missing_physics) == Settings().max_effects
    assert result.stopped_by == "data" and not result.stopped_at_limit and DATA_STOPPED in result.stopped
    assert all("limit" not in item.held_back_by for item in result.closest)
    # a search allowed more names the same terms: the data stopped it
    more = discover_runs(runs, "ch5", None, Settings(max_effects=10))
    assert _terms(more) == _terms(result) and more.stopped_by == "data"
