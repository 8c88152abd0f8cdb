"""The channel as a state machine (issue 41): whatever mix of select, unselect, NC start, NC stop, reset,
mode changes, DB21/DB11 edges and time, the channel never reaches an impossible state, and the PLC's
DB21.DBB35 and DB11.DBB6 always say what the channel says."""

from __future__ import annotations

from hypothesis import strategies as st
from hypothesis.stateful import invariant, rule

from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import parse_machine
from nckemu.emulator.machine.nck.channel import (
    CHAN_ACTIVE,
    CHAN_INTERRUPTED,
    CHAN_RESET,
    PROG_ABORTED,
    PROG_INTERRUPTED,
    PROG_RUNNING,
    PROG_STOPPED,
    PROG_WAITING,
)
from nckemu.emulator.machine.plc.channel_signals import MODE_ACTIVE_BITS, state_byte
from nckemu.protocol.addresses import S7Area
from tests.emulator.machine.nck.channel_rules import MACHINE, ChannelCommandRules
from tests.emulator.machine.nck.channel_rules import PROGRAMS as COMMON_PROGRAMS

PROGRAMS = {**COMMON_PROGRAMS, "/_N_MPF_DIR/_N_MISSING_MPF": None}


class ChannelMachine(ChannelCommandRules):
    def __init__(self) -> None:
        super().__init__()
        self.clock = SimulatedClock()
        self.emulator = Emulator(parse_machine(MACHINE, "states.toml"), clock=self.clock)
        for path, text in PROGRAMS.items():
            if text is not None:
                self.emulator.nck.programs.write(path, text)
        self.channel = self.emulator.nck.channels[1]
        self.changes: list[str] = []
        self.channel.on_change.append(self.changes.append)
        self.counters = (0, 0, 0)

    @rule(path=st.sampled_from(sorted(PROGRAMS)))
    def select(self, path: str) -> None:
        self._try(lambda: self.channel.select(path))

    @rule(mode=st.integers(0, 2))
    def mode(self, mode: int) -> None:
        self._try(lambda: self.channel.set_mode(mode))

    @rule(value=st.integers(0, 7))
    def db11_byte0(self, value: int) -> None:
        self.emulator.plc.write(S7Area.DB, 11, 0, bytes([value]))

    @rule(seconds=st.floats(0.05, 30.0))
    def time_passes(self, seconds: float) -> None:
        end = self.clock.now_s() + seconds
        while self.clock.now_s() < end:
            self.clock.advance(min(0.5, end - self.clock.now_s()))
            self.emulator.step_machine(self.clock.now_s())

    @invariant()
    def state_is_possible(self) -> None:
        state, channel = self.channel.state, self.channel
        assert state.status in (CHAN_RESET, CHAN_ACTIVE, CHAN_INTERRUPTED)
        if state.status == CHAN_RESET:
            assert state.program_status == PROG_ABORTED and channel.run is None
            assert self.emulator.nck.programs.running == ""
        elif state.status == CHAN_ACTIVE:
            assert state.program_status in (PROG_RUNNING, PROG_WAITING) and channel.run is not None
            assert not channel.alarms and state.mode != 0
            assert self.emulator.nck.programs.running == channel.selected
        else:
            assert state.program_status in (PROG_STOPPED, PROG_INTERRUPTED) and channel.run is not None
        if channel.alarms:
            assert state.status != CHAN_ACTIVE
        assert state.mode in (0, 1, 2)
        assert channel.net_time_s >= 0.0

    @invariant()
    def plc_says_what_the_channel_says(self) -> None:
        plc = self.emulator.plc
        assert plc.read(S7Area.DB, 21, 35, 1)[0] == state_byte(self.channel)
        assert plc.read(S7Area.DB, 11, 6, 1)[0] == MODE_ACTIVE_BITS[self.channel.state.mode]

    @invariant()
    def counters_only_count_up_and_changes_alternate(self) -> None:
        state = self.channel.state
        counters = (state.start_counter, state.end_counter, state.reset_counter)
        assert all(new >= old for new, old in zip(counters, self.counters, strict=True))
        self.counters = counters
        life = [change for change in self.changes if change not in ("selected", "unselected")]
        for before, after in zip(life, life[1:], strict=False):
            # a run starts, is interrupted and resumed, and ends or is aborted: never two starts in a row
            assert (before, after) != ("started", "started")
            if after == "resumed":
                assert before == "interrupted"


TestChannelStates = ChannelMachine.TestCase
