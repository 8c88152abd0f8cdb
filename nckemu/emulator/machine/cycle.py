"""A served machine's cycle on the server's clock: the hook a living machine hangs its work on.

The emulator does not know what a cycle does (a recording row, a PLC program: ``nckemu.plcsim.live``
supplies that); it runs ``step(k, t_s)`` for cycle k at simulated time ``t_s = k * cycle_s`` on a
:class:`~nckemu.emulator.machine.clock.LiveClock`, which it holds at ``t_s`` until the step is done. So the
model's time never passes a cycle that has not run, whatever the speed: what a client reads at
simulated time t is what an offline run on a simulated clock has at t. Many machines' pacers share
one event loop (a fleet); each has its own clock.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

from nckemu.emulator.machine.clock import LiveClock

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.live")

Step = Callable[[int, float], Awaitable[None]]


@dataclass
class PacerStats:
    cycles: int = 0
    step_wall_s: float = 0.0        # wall time spent in steps
    max_step_wall_s: float = 0.0
    max_lag_s: float = 0.0          # largest simulated lag seen at the start of a cycle


class CyclePacer:
    """Run ``step(k, k * cycle_s)`` for k = 0, 1, ... on ``clock``; ``await start()`` / ``await stop()``.

    Ahead of time the pacer sleeps; behind it runs cycles back to back (yielding to the loop between
    them, so clients are answered) until it has caught up. Behind by more than ``max_lag_wall_s`` of
    wall time, it lets simulated time slip rather than race to catch up, and counts that.
    """

    def __init__(self, clock: LiveClock, cycle_s: float, step: Step, *, max_lag_wall_s: float = 2.0,
                 first_cycle: int = 0) -> None:
        if not cycle_s > 0:
            raise ValueError("a cycle must be longer than 0 s")
        self.clock = clock
        self.cycle_s = float(cycle_s)
        self.step = step
        self.max_lag_wall_s = max_lag_wall_s
        # A pacer started on a clock that already runs begins at the cycle the clock has reached.
        self.first_cycle = first_cycle
        self.stats = PacerStats()
        self._task: asyncio.Task[None] | None = None
        self.error: BaseException | None = None

    @property
    def running(self) -> bool:
        return self._task is not None and not self._task.done()

    async def start(self) -> CyclePacer:
        self.clock.hold(self.first_cycle * self.cycle_s)
        self.clock.start()
        self._task = asyncio.create_task(self._run(), name="nckemu-cycle")
        return self

    async def stop(self) -> None:
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            try:
                await task
            except asyncio.CancelledError:
                pass
        self.clock.settle()
        self.clock.release()

    async def _run(self) -> None:
        clock, stats = self.clock, self.stats
        k = self.first_cycle
        try:
            while True:
                t_s = k * self.cycle_s
                clock.hold(t_s)
                wait_s = clock.wall_until_s(t_s)
                if wait_s > 0:
                    while wait_s > 0:
                        await asyncio.sleep(wait_s)
                        wait_s = clock.wall_until_s(t_s)
                else:
                    await asyncio.sleep(0)  # behind: let the clients in between cycles
                    lag_s = clock.lag_s()
                    stats.max_lag_s = max(stats.max_lag_s, lag_s)
                    if lag_s > self.max_lag_wall_s * clock.speed:
                        if clock.slips == 0:
                            log.warning("the machine cannot keep up with %gx: %.1f s of simulated time behind; "
                                        "simulated time slips (the live page and -v show the lag)", clock.speed,
                                        lag_s)
                        clock.slip()
                started = time.perf_counter()
                await self.step(k, t_s)
                spent = time.perf_counter() - started
                stats.cycles = k + 1 - self.first_cycle
                stats.step_wall_s += spent
                stats.max_step_wall_s = max(stats.max_step_wall_s, spent)
                k += 1
        except asyncio.CancelledError:
            raise
        except BaseException as exc:  # a step that raises stops the cycle, never the server
            self.error = exc
            log.error("the machine's cycle stopped at %.1f s: %s", k * self.cycle_s, exc)
