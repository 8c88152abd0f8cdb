"""The umati program and job states on the real channel (issue 43): whatever mix of select, unselect, NC
start, NC stop, reset, DB21 edges, time, and a recording running the channel without a program, the
tracker the OPC UA face reads (``production.ProgramTracker``) takes only transitions the MachineTool
NodeSet declares, and its states say what the channel says: Running while the channel is active,
Interrupted while it is interrupted, Initializing, Ended or Aborted in reset."""

from __future__ import annotations

import pytest
from hypothesis import strategies as st
from hypothesis.stateful import invariant, rule

from nckemu.emulator.faces.opcua import nodesets
from nckemu.emulator.faces.opcua.production import ProgramTracker
from nckemu.emulator.faces.opcua.program_states import (
    ABORTED,
    ENDED,
    INITIALIZING,
    INTERRUPTED,
    RUNNING,
    Step,
)
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import parse_machine
from nckemu.emulator.machine.nck.channel import CHAN_ACTIVE, CHAN_INTERRUPTED, CHAN_RESET
from tests.emulator.faces.opcua.test_program_states import Transitions, _transitions
from tests.emulator.machine.nck.channel_rules import MACHINE, ChannelCommandRules
from tests.emulator.machine.nck.channel_rules import PROGRAMS as COMMON_PROGRAMS

PROGRAMS = {**COMMON_PROGRAMS, "/_N_MPF_DIR/_N_SHORT_MPF": b"G4 F0.5\nM30\n"}
pytestmark = pytest.mark.skipif(nodesets.find() is None, reason=nodesets.how_to_get())
LEGAL: dict[str, Transitions] = {}


class TrackedChannel(ChannelCommandRules):
    def __init__(self) -> None:
        super().__init__()
        if not LEGAL:
            LEGAL["program"] = _transitions("ProductionProgramStateMachineType")[0]
            LEGAL["job"] = _transitions("ProductionJobStateMachineType")[0]
        self.clock = SimulatedClock()
        self.emulator = Emulator(parse_machine(MACHINE, "umati_states.toml"), clock=self.clock)
        for path, text in PROGRAMS.items():
            self.emulator.nck.programs.write(path, text)
        self.channel = self.emulator.nck.channels[1]
        self.tracker = ProgramTracker(self.emulator, 1)
        self.steps: dict[str, list[Step]] = {"program": [], "job": []}
        self.tracker.listeners.append(lambda program, job: (self.steps["program"].extend(program),
                                                            self.steps["job"].extend(job)))
        self.tracker.start()

    @rule(path=st.sampled_from(sorted(PROGRAMS)))
    def select(self, path: str) -> None:
        self._try(lambda: self.channel.select(path))

    @rule(parts=st.integers(0, 3))
    def parts_planned(self, parts: int) -> None:
        self.channel.state.required_parts = float(parts)

    @rule()
    def recording_runs(self) -> None:
        """A recording's turning spindle: the channel active without a program (from reset)."""
        if self.channel.state.status == CHAN_RESET:
            self._try(self.channel.run_without_program)

    @rule()
    def recording_ends(self) -> None:
        """A recording's spindle standing long: the run without a program ends with a part."""
        if self.channel.state.status == CHAN_ACTIVE and self.channel.run is None:
            self.channel.end_program()

    @rule(seconds=st.floats(0.05, 30.0))
    def time_passes(self, seconds: float) -> None:
        end = self.clock.now_s() + seconds
        while self.clock.now_s() < end:
            self.clock.advance(min(0.5, end - self.clock.now_s()))
            self.emulator.step_machine(self.clock.now_s())

    @invariant()
    def transitions_are_the_nodeset_s(self) -> None:
        for key, machine in (("program", self.tracker.program), ("job", self.tracker.job)):
            state = INITIALIZING
            for step in self.steps[key]:
                assert LEGAL[key][step.name] == (step.from_state, step.to_state), step
                assert step.from_state == state, (key, self.steps[key])
                state = step.to_state
            assert machine.state == state

    @invariant()
    def states_say_what_the_channel_says(self) -> None:
        status, program, job = self.channel.state.status, self.tracker.program.state, self.tracker.job.state
        if status == CHAN_ACTIVE:
            assert program == RUNNING and job == RUNNING
        elif status == CHAN_INTERRUPTED:
            assert program == INTERRUPTED and job == INTERRUPTED
        else:
            assert program in (INITIALIZING, ENDED, ABORTED)
            assert job in (INITIALIZING, RUNNING, ENDED, ABORTED)   # Running: between a job's runs


TestTrackedChannel = TrackedChannel.TestCase
