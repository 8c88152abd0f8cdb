"""One sensor at two time constants (issue 42): a fast skin and a slow core, found by the round that
names the one, as a move of two with each one's share; the null and a single time constant stay as
they were."""

from __future__ import annotations

import pytest

from nckemu.thermal.discovery.discover import discover_runs
from nckemu.thermal.discovery.settings import Settings
from nckemu.thermal.discovery.wording import finding_lines
from nckemu.thermal.synthetic.scenarios import (
    AXIS,
    TWO_TAU_FAST_S,
    TWO_TAU_SLOW_S,
    make_two_tau_family,
)


def test_a_skin_and_a_core_are_both_named_with_their_shares() -> None:
    family = make_two_tau_family("two_tau_days", 1, runs=12)
    result = discover_runs(family.runs, AXIS, family.model)
    transients = sorted((m for m in result.missing_physics if m.effect == "transient_gradient"),
                        key=lambda m: m.parameters["tau_s"])
    assert [m.parameters["sensor"] for m in transients] == ["front", "front"]
    assert abs(transients[0].parameters["tau_s"] - TWO_TAU_FAST_S) <= 0.25 * TWO_TAU_FAST_S
    assert abs(transients[1].parameters["tau_s"] - TWO_TAU_SLOW_S) <= 0.25 * TWO_TAU_SLOW_S
    moves = [m.evidence.move for m in transients]
    assert all(move is not None for move in moves)
    assert abs(sum(move.share for move in moves if move) - 1.0) < 0.01
    assert any(alt.effects == "transient_gradient(front) alone" for move in moves if move for alt in move.equivalent)
    assert "two time constants of one sensor" in transients[0].evidence.preferred
    line = next(line for line in finding_lines(result) if line.startswith("two time constants of front"))
    assert line.count("tau ") == 2 and line.count("um/K") == 2 and "of the two" in line


@pytest.mark.slow  # the two-time-constant search turned off and on: 30-70 s on two cores (make slow)
def test_turned_off_the_one_time_constant_stands() -> None:
    family = make_two_tau_family("two_tau_days", 1, runs=12)
    result = discover_runs(family.runs, AXIS, family.model, Settings(second_time_constant_ratio=0.0))
    assert sum(m.effect == "transient_gradient" for m in result.missing_physics) == 1


def test_the_null_names_nothing() -> None:
    family = make_two_tau_family("null_two_tau_days", 1, runs=12)
    assert not discover_runs(family.runs, AXIS, family.model).missing_physics
