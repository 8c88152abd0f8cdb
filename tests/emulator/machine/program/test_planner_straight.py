"""The planner's straight-move fast path (Planner.straight, what the channel calls for every G0/G1)
equals its general path (Planner.move) on random moves, limits, overrides, feed groups and look-ahead
states: the same time, speed, length and time law (where the path is at every instant)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.emulator.machine.program.motions import Move
from nckemu.emulator.machine.program.planner import (
    EPSILON_MM,
    AxisLimits,
    MotionLimits,
    Overrides,
    Planner,
    time_law,
)

AXES = ("X", "Y", "Z", "A")
positions = st.floats(-2000.0, 2000.0, allow_nan=False) | st.sampled_from([0.0, 1.0e-10, 5.0])
# MD32000 and MD32300 are positive (the machine file refuses others)
limits = st.builds(AxisLimits, st.floats(1.0, 60000.0), st.floats(0.01, 20.0) | st.just(math.inf))


@settings(max_examples=400, deadline=None)
@given(start=st.fixed_dictionaries({axis: positions for axis in AXES}),
       targets=st.dictionaries(st.sampled_from(AXES + ("B",)), positions, max_size=5),
       axis_limits=st.dictionaries(st.sampled_from(AXES), limits),
       feed=st.none() | st.floats(0.0, 50000.0),
       feed_mode=st.sampled_from(["G93", "G94", "G95"]),
       exact_stop=st.booleans(), moving=st.booleans(),
       feed_pct=st.floats(0.0, 120.0), rapid_pct=st.floats(0.0, 120.0),
       spindle_rpm=st.floats(-12000.0, 12000.0),
       fgroup=st.none() | st.frozensets(st.sampled_from(AXES + ("B",))))
def test_straight_equals_move(start, targets, axis_limits, feed, feed_mode, exact_stop, moving, feed_pct,
                              rapid_pct, spindle_rpm, fgroup) -> None:
    general, fast = Planner(MotionLimits(axis_limits)), Planner(MotionLimits(axis_limits))
    general.moving = fast.moving = moving
    timed = general.move(start, Move(dict(targets), feed, feed_mode, exact_stop, fgroup=fgroup),
                         Overrides(feed_pct, rapid_pct), spindle_rpm)
    deltas = [(axis, target - start.get(axis, 0.0)) for axis, target in targets.items()
              if abs(target - start.get(axis, 0.0)) > EPSILON_MM]
    duration_s, feed_mm_min, length_mm, law = fast.straight(deltas, feed, feed_mode, exact_stop, feed_pct,
                                                            rapid_pct, spindle_rpm, fgroup)
    assert (duration_s, feed_mm_min, length_mm) == (timed.duration_s, timed.feed_mm_min, timed.length_mm) or \
        (math.isnan(duration_s) and math.isnan(timed.duration_s))
    assert fast.moving == general.moving
    assert (law is None) == (timed.law is None)
    if law is not None and timed.law is not None and math.isfinite(duration_s):
        law = time_law(law)
        shares = [law.fraction(share * duration_s) for share in (0.0, 0.25, 0.5, 0.75, 1.0)]
        assert shares == [timed.law.fraction(share * duration_s) for share in (0.0, 0.25, 0.5, 0.75, 1.0)]
        # the law runs from the start to the end of the path in the block's time, never back
        assert shares == sorted(shares) and shares[0] == 0.0 and shares[-1] == pytest.approx(1.0, abs=1e-6)
