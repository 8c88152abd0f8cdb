"""The NCK's alarm list: pending alarms (number, time, parameters, text) and the log of alarm events.

The list is what ``/Nck/State/numAlarms`` counts and what the alarm list variables read: SALA (by time,
line 1 = the oldest pending alarm), SALAL (the last one raised), SALAP (by priority) and SALUC (alarm
events, newest first). Alarms are raised by the emulator itself (the retained-state alarm, see
``core.py``); a text alone is accepted for the callers that predate numbers.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from nckemu.emulator.machine.clock import Clock

# nckemu's own alarm numbers: no Siemens alarm says "retained data could not be written" (assumed).
ALARM_RETAINED_STATE = 700999
ALARM_DEFAULT = 700000
MAX_EVENTS = 256


@dataclass(frozen=True)
class Alarm:
    number: int
    text: str
    time_s: float = 0.0
    parameters: tuple[str, ...] = ()
    # Lower is more urgent; the sources give no priority scheme (assumed: all alike, then by time).
    priority: int = 1


@dataclass(frozen=True)
class AlarmEvent:
    alarm: Alarm
    raised: bool          # False: cleared
    time_s: float


class Alarms:
    def __init__(self, clock: Clock | None = None) -> None:
        self._clock = clock
        self.pending: list[Alarm] = []
        self.events: deque[AlarmEvent] = deque(maxlen=MAX_EVENTS)
        # Told of each alarm raised or cleared (the OPC UA face sends them as alarm events).
        self.listeners: list[Callable[[AlarmEvent], None]] = []

    def _tell(self, event: AlarmEvent) -> None:
        self.events.appendleft(event)
        for listener in self.listeners:
            listener(event)

    def _now(self) -> float:
        return self._clock.now_s() if self._clock is not None else 0.0

    def raise_alarm(self, text: str, number: int = ALARM_DEFAULT, parameters: tuple[str, ...] = (),
                    priority: int = 1) -> Alarm:
        for alarm in self.pending:
            if alarm.text == text:
                return alarm
        alarm = Alarm(number, text, self._now(), tuple(parameters), priority)
        self.pending.append(alarm)
        self._tell(AlarmEvent(alarm, True, alarm.time_s))
        return alarm

    def clear(self, text: str) -> None:
        for alarm in list(self.pending):
            if alarm.text == text:
                self.pending.remove(alarm)
                self._tell(AlarmEvent(alarm, False, self._now()))

    @property
    def active(self) -> list[str]:
        return [alarm.text for alarm in self.pending]

    @property
    def count(self) -> int:
        return len(self.pending)

    # ------------------------------------------------------------------ the list variables
    def by_time(self, line: int) -> Alarm | None:
        """SALA line ``line`` (1-based): the pending alarms, oldest first."""
        return self.pending[line - 1] if 1 <= line <= len(self.pending) else None

    def last(self) -> Alarm | None:
        """SALAL: the alarm raised last."""
        return self.pending[-1] if self.pending else None

    def by_priority(self, line: int) -> Alarm | None:
        """SALAP line ``line``: most urgent first, then oldest first."""
        ordered = sorted(self.pending, key=lambda alarm: (alarm.priority, alarm.time_s))
        return ordered[line - 1] if 1 <= line <= len(ordered) else None

    def event(self, line: int) -> AlarmEvent | None:
        """SALUC line ``line``: alarm events (raised or cleared), newest first."""
        return self.events[line - 1] if 1 <= line <= len(self.events) else None


def alarm_number(alarm: Alarm | AlarmEvent | None) -> int:
    """The number a list line shows; 0 for a line past the end of the list (assumed)."""
    if alarm is None:
        return 0
    return alarm.alarm.number if isinstance(alarm, AlarmEvent) else alarm.number
