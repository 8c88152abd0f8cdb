"""The NC commands and DB21 control bytes a channel state machine test throws at channel 1, shared by
the channel's own state machine and the umati program tracker's (each adds its own select rule)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable

from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, rule

from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.nck.channel import Channel
from nckemu.errors import NckError
from nckemu.protocol.addresses import S7Area

# The machine and the programs both state machines run: one linear axis and a spindle; a program that
# ends (with an M0 stop on the way), one that stops at an alarm and one that loops for ever.
MACHINE = """
name = "state machine mill"
[[axis]]
number = 1
name = "X1"
travel_mm = [-100.0, 100.0]
[[axis]]
number = 2
name = "SP1"
rotary = true
spindle = true
[program]
max_blocks_per_cycle = 50
"""
PROGRAMS: dict[str, bytes | None] = {
    "/_N_MPF_DIR/_N_GOOD_MPF": b"G0 X10\nS1000 M3\nM0\nG1 X20 F600\nG4 F1\nM5\nM30\n",
    "/_N_MPF_DIR/_N_BAD_MPF": b"G0 X10\nGOTOF NOWHERE\nM30\n",
    "/_N_MPF_DIR/_N_LOOP_MPF": b"L1:\nR1=R1+1\nGOTOB L1\n",
}


class ChannelCommandRules(RuleBasedStateMachine):
    """Rules on ``self.channel`` of ``self.emulator`` (set by the subclass); a refused command is fine."""

    emulator: Emulator
    channel: Channel

    def _try(self, action: Callable[[], object]) -> None:
        with contextlib.suppress(NckError):
            action()

    @rule()
    def unselect(self) -> None:
        self._try(self.channel.unselect)

    @rule()
    def start(self) -> None:
        self._try(self.channel.start)

    @rule()
    def stop(self) -> None:
        self._try(self.channel.stop)

    @rule()
    def reset(self) -> None:
        self._try(self.channel.reset)

    @rule(value=st.integers(0, 255))
    def db21_byte7(self, value: int) -> None:
        self.emulator.plc.write(S7Area.DB, 21, 7, bytes([value]))
