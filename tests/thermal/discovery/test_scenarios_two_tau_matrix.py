"""One sensor at two time constants (issue 42) against discover_runs over 20 seeds: the front
column's transient at 0.5 h and at 3 h, both named with time constants within 25 % and each with its
share of the move; nothing on the null. Slow: 40 discoveries of 30 runs."""

from __future__ import annotations

import pytest

from nckemu.thermal.discovery.discover import discover_runs
from nckemu.thermal.synthetic.scenarios import (
    AXIS,
    TWO_TAU_FAST_S,
    TWO_TAU_SENSOR,
    TWO_TAU_SLOW_S,
    make_two_tau_family,
)
from tests.thermal.discovery.seed_matrix import seed_outcomes

pytestmark = [pytest.mark.slow, pytest.mark.timeout(3600)]


def _close(value: float, truth: float) -> bool:
    return abs(value - truth) <= 0.25 * truth


def _outcome(name: str, seed: int) -> tuple[bool, list[str]]:
    family = make_two_tau_family(name, seed)
    found = discover_runs(family.runs, AXIS, family.model).missing_physics
    named = [f"{m.effect}({m.parameters.get('sensor', m.parameters.get('sensors'))}, "
             f"{m.parameters.get('tau_s', 0) / 3600:.2f} h)" for m in found]
    if name == "null_two_tau_days":
        return not found, named
    taus = sorted(m.parameters["tau_s"] for m in found
                  if m.effect == "transient_gradient" and m.parameters["sensor"] == TWO_TAU_SENSOR)
    shares = [m.evidence.move.share for m in found if m.effect == "transient_gradient" and m.evidence.move]
    ok = len(taus) == 2 and _close(taus[0], TWO_TAU_FAST_S) and _close(taus[1], TWO_TAU_SLOW_S) \
        and len(shares) == 2 and abs(sum(shares) - 1.0) < 0.01
    return ok, named


@pytest.mark.parametrize("name", ["two_tau_days", "null_two_tau_days"])
def test_twenty_seeds(name: str) -> None:
    outcomes, hits = seed_outcomes(name, _outcome)
    if name == "two_tau_days":
        assert len(hits) >= 18, outcomes
    else:
        assert len(hits) == 20, outcomes
