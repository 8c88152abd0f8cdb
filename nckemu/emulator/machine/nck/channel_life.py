"""A channel's program life as one table: (where it is, what happened) -> where it goes, and what it tells.

h11 keeps a connection's states and the events between them in tables, so that every change is one
lookup and an impossible one is an error rather than a quiet mix of fields. Here the places are those
the control reports (chanStatus, progStatus, channel_states.py), with "ended" apart from "reset":
BTSS says progStatus 5 "aborted" after a reset and after a normal end alike, but the live page and
the OPC UA face can tell them apart. Only ``Channel`` moves along this table.
"""

from __future__ import annotations

from enum import Enum

from nckemu.emulator.machine.nck.channel_states import (
    CHAN_ACTIVE,
    CHAN_INTERRUPTED,
    CHAN_RESET,
    PROG_ABORTED,
    PROG_INTERRUPTED,
    PROG_RUNNING,
    PROG_STOPPED,
    PROG_WAITING,
)


class Life(Enum):
    """Where a channel's program is; the value is what BTSS reports (chanStatus, progStatus)."""

    RESET = "reset"              # never run since the last reset, or reset while running
    ENDED = "ended"              # the last run reached M2/M30 or its last block
    RUNNING = "running"
    WAITING = "waiting"          # running, but waiting (for the PLC's answer to an M function, a spindle)
    STOPPED = "stopped"          # NC stop, M0/M1: resumes where it stopped
    INTERRUPTED = "interrupted"  # a program alarm: held until a reset clears it

    @property
    def reported(self) -> tuple[int, int]:
        return _REPORTED[self]

    @property
    def active(self) -> bool:
        return self in (Life.RUNNING, Life.WAITING)

    @property
    def at_rest(self) -> bool:
        """In reset (chanStatus 0): a program may be selected, the mode changed freely."""
        return self in (Life.RESET, Life.ENDED)


_REPORTED = {
    Life.RESET: (CHAN_RESET, PROG_ABORTED),
    Life.ENDED: (CHAN_RESET, PROG_ABORTED),
    Life.RUNNING: (CHAN_ACTIVE, PROG_RUNNING),
    Life.WAITING: (CHAN_ACTIVE, PROG_WAITING),
    Life.STOPPED: (CHAN_INTERRUPTED, PROG_STOPPED),
    Life.INTERRUPTED: (CHAN_INTERRUPTED, PROG_INTERRUPTED),
}


class Event(Enum):
    START = "start"              # NC start with a program selected, from reset
    RESUME = "resume"            # NC start of an interrupted run
    WORK = "work"                # active without a program (a recording says the machine works)
    WAIT = "wait"
    GO_ON = "go on"
    STOP = "stop"                # NC stop, M0/M1
    ALARM = "alarm"              # a program alarm
    END = "end"                  # M2/M30, the last block, or the older end-of-program command
    RESET = "reset"


# (where, event) -> (where next, the change told to on_change listeners or None). A pair not in the table
# is not a change the channel makes (the callers ask before: a stop of a channel that is not active is
# nothing).
_AT_REST = (Life.RESET, Life.ENDED)
_ACTIVE = (Life.RUNNING, Life.WAITING)
_HELD = (Life.STOPPED, Life.INTERRUPTED)
TRANSITIONS: dict[tuple[Life, Event], tuple[Life, str | None]] = {
    **{(where, Event.START): (Life.RUNNING, "started") for where in _AT_REST},
    **{(where, Event.RESUME): (Life.RUNNING, "resumed") for where in _HELD},
    **{(where, Event.WORK): (Life.RUNNING, None) for where in (*_AT_REST, *_HELD, *_ACTIVE)},
    (Life.RUNNING, Event.WAIT): (Life.WAITING, None),
    (Life.WAITING, Event.GO_ON): (Life.RUNNING, None),
    **{(where, Event.STOP): (Life.STOPPED, "interrupted") for where in _ACTIVE},
    **{(where, Event.ALARM): (Life.INTERRUPTED, "interrupted") for where in _ACTIVE},
    **{(where, Event.END): (Life.ENDED, "ended") for where in Life},
    **{(where, Event.RESET): (Life.RESET, "aborted") for where in (*_ACTIVE, *_HELD)},
    # A reset in reset counts, clears alarms and keeps what the last run came to (ended or not).
    (Life.RESET, Event.RESET): (Life.RESET, None),
    (Life.ENDED, Event.RESET): (Life.ENDED, None),
}


class LifeError(RuntimeError):
    """A change the table does not have: the channel's own fault, never a client's."""


def next_life(where: Life, event: Event) -> tuple[Life, str | None]:
    try:
        return TRANSITIONS[(where, event)]
    except KeyError:
        raise LifeError(f"a channel {where.value} has no change for {event.value}") from None
