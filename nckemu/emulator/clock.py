"""Injectable time, so the compensation engine and simulations can run faster than real time."""

from __future__ import annotations

import time
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
