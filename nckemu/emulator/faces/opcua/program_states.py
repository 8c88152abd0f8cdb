"""The umati program and job state machines, driven by what a channel does with its program.

OPC 40501-1 gives the active program (``ProductionProgramStateMachineType``) and each production job
(``ProductionJobStateMachineType``) the same five states: Initializing (the initial state: not yet
started), Running, Interrupted (paused, can go on), Ended (finished normally) and Aborted (stopped for
good), and names each transition ``<From>To<To>``. This module knows only those names; the state and
transition nodes, their numbers and which transitions exist are read from the NodeSet where the face
builds the instance (``production.py``), and a test checks every transition taken here against the
NodeSet's FromState/ToState references.

A channel tells what happens with one word (``CHANNEL_EVENTS``, the channel's ``on_change``). How each
moves the machines (ours; docs/opcua.md "Programs over OPC UA"):

- selected, unselected: a finished program (Ended, Aborted) goes back to Initializing; the job too,
  and a job Running between its runs is abandoned (Aborted, then Initializing);
- started, resumed: Ended/Aborted -> Initializing -> Running, Initializing/Interrupted -> Running, for
  both; a job Running between its runs stays Running;
- interrupted: Running -> Interrupted, for both;
- ended: Running -> Ended (an Interrupted program passes through Running: there is no
  InterruptedToEnded); the job goes Running -> Running while runs remain (RunsPlanned = reqParts >
  RunsCompleted = actParts), else Running -> Ended;
- aborted: Running/Interrupted -> Aborted, for both (the job only when the program was aborted).

Anything else leaves a machine where it is (a reset in reset aborts nothing, an interrupt of a program
that does not run interrupts nothing), so any sequence of channel events gives legal transitions only.
"""

from __future__ import annotations

from dataclasses import dataclass

from nckemu.emulator.machine.nck.channel_states import (
    PROG_ABORTED,
    PROG_INTERRUPTED,
    PROG_RUNNING,
    PROG_STOPPED,
    PROG_WAITING,
)

INITIALIZING, RUNNING, INTERRUPTED, ENDED, ABORTED = "Initializing", "Running", "Interrupted", "Ended", "Aborted"
STATES = (INITIALIZING, RUNNING, INTERRUPTED, ENDED, ABORTED)
CHANNEL_EVENTS = ("selected", "unselected", "started", "interrupted", "resumed", "ended", "aborted")
_FINISHED = (ENDED, ABORTED)


@dataclass(frozen=True)
class Step:
    """One transition taken: its name (``RunningToEnded``), the state left and the state reached."""

    name: str
    from_state: str
    to_state: str


class _StateMachine:
    """A ProductionStateMachineType's current state and last transition; power-on: Initializing."""

    def __init__(self) -> None:
        self.state = INITIALIZING
        self.last: Step | None = None

    def _go(self, to_state: str, steps: list[Step]) -> None:
        step = Step(f"{self.state}To{to_state}", self.state, to_state)
        self.state, self.last = to_state, step
        steps.append(step)

    def _move(self, event: str, *, select_abandons_run: bool, another_run: bool) -> list[Step]:
        """The transitions ``event`` takes, in order (none when it changes nothing); a job abandons
        a run on a new selection and goes Running -> Running on an end while runs remain."""
        steps: list[Step] = []
        if event in ("selected", "unselected"):
            if select_abandons_run and self.state == RUNNING:
                self._go(ABORTED, steps)
            if self.state in _FINISHED:
                self._go(INITIALIZING, steps)
        elif event in ("started", "resumed"):
            if self.state in _FINISHED:
                self._go(INITIALIZING, steps)
            if self.state in (INITIALIZING, INTERRUPTED):
                self._go(RUNNING, steps)
        elif event == "interrupted":
            if self.state == RUNNING:
                self._go(INTERRUPTED, steps)
        elif event == "ended":
            if self.state == INTERRUPTED:
                self._go(RUNNING, steps)
            if self.state == RUNNING:
                self._go(RUNNING if another_run else ENDED, steps)
        elif event == "aborted":
            if self.state in (RUNNING, INTERRUPTED):
                self._go(ABORTED, steps)
        return steps


class ProgramStates(_StateMachine):
    """The ActiveProgram's state machine."""

    def on(self, event: str) -> list[Step]:
        """The transitions ``event`` takes, in order (none when it changes nothing)."""
        return self._move(event, select_abandons_run=False, another_run=False)


class JobStates(_StateMachine):
    """The production job's state machine: one job is the selected program run RunsPlanned times
    (every run its own job when RunsPlanned is 0, not valid)."""

    def on(self, event: str, runs_completed: float, runs_planned: float) -> list[Step]:
        """The transitions ``event`` takes, with the job's counters as they are after it."""
        more = runs_planned > 0 and runs_completed < runs_planned
        return self._move(event, select_abandons_run=True, another_run=more)


# progStatus (BTSS): 1 interrupted, 2 stopped, 3 running, 4 waiting, 5 aborted. A program waiting (a
# dwell, a wait mark) still runs: umati has no waiting state, CNC shows it (ActProgramStatus Waiting).
_PAUSED = (PROG_INTERRUPTED, PROG_STOPPED)
_RUNNING = (PROG_RUNNING, PROG_WAITING)
_ABORTED_STATUS = PROG_ABORTED


@dataclass(frozen=True)
class ChannelLook:
    """What a channel shows that tells its program's life: progStatus, the selected program and the
    parts counted (a normal end counts one)."""

    program_status: int
    selected: str
    total_parts: float


def events_between(before: ChannelLook, after: ChannelLook) -> list[str]:
    """The channel events that lead from one look to the next, for a channel that does not tell them
    itself (a recording driving the channel's state): best effort, each look a moment apart."""
    events: list[str] = []
    if after.selected != before.selected:
        events.append("selected" if after.selected else "unselected")
    was, now = before.program_status, after.program_status
    counted = after.total_parts > before.total_parts
    if now in _RUNNING and was not in _RUNNING:
        events.append("resumed" if was in _PAUSED else "started")
    elif now in _PAUSED and was not in _PAUSED:
        if was not in _RUNNING:
            events.append("started")
        events.append("interrupted")
    elif now == _ABORTED_STATUS and was != _ABORTED_STATUS:
        events.append("ended" if counted else "aborted")
    elif now == _ABORTED_STATUS and counted:  # a whole run between two looks
        events.extend(("started", "ended"))
    return events
