"""LiveClock as a state machine: whatever the pacer and the wall do, simulated time never runs
backwards, never passes a hold point, and runs at the speed when free."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.machine.clock import LiveClock


class FakeWall:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


actions = st.lists(st.one_of(
    st.tuples(st.just("wall"), st.floats(0.0, 5.0)),
    st.tuples(st.just("hold"), st.floats(-10.0, 5000.0)),
    st.tuples(st.just("release"), st.just(0.0)),
    st.tuples(st.just("slip"), st.just(0.0)),
    st.tuples(st.just("speed"), st.floats(0.1, 1000.0)),
), max_size=60)


@given(actions, st.floats(0.5, 1000.0))
def test_monotonic_held_and_free(steps: list[tuple[str, float]], speed: float) -> None:
    wall = FakeWall()
    clock = LiveClock(speed, wall_s=wall)
    assert clock.now_s() == 0.0
    wall.t += 3.0
    assert clock.now_s() == 0.0, "a clock not started stands"
    clock.start()
    last = clock.now_s()
    hold = math.inf
    for action, value in steps:
        if action == "wall":
            before_free = clock.free_s()
            wall.t += value
            assert clock.free_s() >= before_free
            assert math.isclose(clock.free_s() - before_free, value * clock.speed, rel_tol=1e-9, abs_tol=1e-6)
        elif action == "hold":
            clock.hold(value)
            hold = max(value, last)
        elif action == "release":
            clock.release()
            hold = math.inf
        elif action == "slip":
            clock.slip()
        else:
            clock.speed = value
        now = clock.now_s()
        assert now >= last - 1e-9, "simulated time never runs backwards"
        assert now <= hold + 1e-9, "nor past the point it is held at"
        assert clock.lag_s() >= 0.0
        last = now


def test_wall_until_and_lag() -> None:
    wall = FakeWall()
    clock = LiveClock(60.0, wall_s=wall)
    clock.start()
    clock.hold(120.0)
    assert clock.wall_until_s(120.0) == 2.0
    wall.t += 3.0                      # free at 180 s, held at 120 s
    assert clock.now_s() == 120.0 and clock.lag_s() == 60.0
    clock.slip()                       # the machine could not keep up: go on from 120 s
    assert clock.slips == 1 and clock.now_s() == 120.0 and clock.lag_s() == 0.0
    clock.release()
    wall.t += 1.0
    assert clock.now_s() == 180.0
