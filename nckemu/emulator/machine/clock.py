"""Injectable time, so the compensation engine and simulations can run faster than real time."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Protocol


class Clock(Protocol):
    def now_s(self) -> float: ...


class MonotonicClock:
    """Wall time as the server sees it (monotonic, seconds)."""

    def __init__(self) -> None:
        self._start_s = time.monotonic()

    def now_s(self) -> float:
        return time.monotonic() - self._start_s


class SimulatedClock:
    """Time that moves only when told to."""

    def __init__(self, start_s: float = 0.0) -> None:
        self._now_s = float(start_s)

    def now_s(self) -> float:
        return self._now_s

    def advance(self, dt_s: float) -> None:
        if dt_s < 0:
            raise ValueError("a simulated clock does not run backwards")
        self._now_s += dt_s

    def set(self, t_s: float) -> None:
        if t_s < self._now_s:
            raise ValueError("a simulated clock does not run backwards")
        self._now_s = float(t_s)


class LiveClock:
    """Simulated time running at ``speed`` times the wall clock, never past a hold point.

    A served machine that lives (a recording playing, a PLC program cycling) runs on this clock: the
    machine's cycle driver (:class:`nckemu.emulator.machine.cycle.CyclePacer`) holds it at the start of the next
    cycle until that cycle has run, so every value a client reads at simulated time t comes from a
    model that has run every cycle up to t, exactly as an offline run on a :class:`SimulatedClock`
    would have it. Until :meth:`start` the clock stands at ``start_s``.
    """

    def __init__(self, speed: float = 1.0, start_s: float = 0.0,
                 wall_s: Callable[[], float] = time.monotonic) -> None:
        if not speed > 0:
            raise ValueError("a live clock needs a positive speed")
        self._speed = float(speed)
        self._wall_s = wall_s
        self._anchor_s = float(start_s)
        self._anchor_wall_s: float | None = None
        self._hold_s = math.inf
        self.slips = 0            # how often the clock gave up waiting and let simulated time slip

    @property
    def speed(self) -> float:
        return self._speed

    @speed.setter
    def speed(self, speed: float) -> None:
        if not speed > 0:
            raise ValueError("a live clock needs a positive speed")
        self._reanchor()
        self._speed = float(speed)

    @property
    def running(self) -> bool:
        return self._anchor_wall_s is not None

    def start(self) -> None:
        if self._anchor_wall_s is None:
            self._anchor_wall_s = self._wall_s()

    def free_s(self) -> float:
        """Where simulated time would be without the hold point."""
        if self._anchor_wall_s is None:
            return self._anchor_s
        return self._anchor_s + (self._wall_s() - self._anchor_wall_s) * self._speed

    def now_s(self) -> float:
        free_s = self.free_s()
        return free_s if free_s < self._hold_s else self._hold_s

    def hold(self, at_s: float) -> None:
        """Do not pass ``at_s`` (the start of a cycle not yet run); never below the time already shown."""
        self._hold_s = max(at_s, self.now_s())

    def release(self) -> None:
        self._hold_s = math.inf

    def wall_until_s(self, t_s: float) -> float:
        """Wall seconds until the free-running time reaches ``t_s`` (0 when it has)."""
        return max(0.0, (t_s - self.free_s()) / self._speed)

    def lag_s(self) -> float:
        """Simulated seconds the held clock is behind the free-running one."""
        return max(0.0, self.free_s() - self.now_s())

    def settle(self) -> None:
        """Run on from the time shown now (a pacer that stops: the time its cycles reached, not the
        free-running time it was catching up with)."""
        self._reanchor()

    def slip(self) -> None:
        """Give up the lag: simulated time goes on from where it stands (the machine could not keep up)."""
        self._reanchor()
        self.slips += 1

    def _reanchor(self) -> None:
        if self._anchor_wall_s is None:
            return
        self._anchor_s = self.now_s()
        self._anchor_wall_s = self._wall_s()
