"""Counted as the control counts (issue 49): a program with no block counts no part, a normal end is
"ended" on the live page's status (progStatus 5 either way), a reset "aborted"."""

from __future__ import annotations

import pytest

from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.nck.channel_states import PROG_ABORTED
from nckemu.emulator.machine.offline import run_offline
from nckemu.emulator.machine.status import machine_status
from nckemu.errors import NckPiStateError

MAIN = "/_N_MPF_DIR/_N_SHOP_MPF"


def _emulator(text: bytes, **programs: bytes) -> Emulator:
    emulator = Emulator(None, clock=SimulatedClock())
    emulator.nck.programs.write(MAIN, text)
    for path, sub in programs.items():
        emulator.nck.programs.write(path, sub)
    return emulator


@pytest.mark.parametrize("text", [b"", b"; only a comment\n\n   ; and another\n", b"%_N_SHOP_MPF\n;$PATH=/_N_MPF_DIR\n",
                                  b"\xef\xbb\xbf; a byte-order mark and a comment\r\n"])
def test_a_program_without_blocks_counts_no_part(text: bytes) -> None:
    emulator = _emulator(text)
    for _ in range(3):
        result = run_offline(emulator, MAIN)
        assert result.outcome == "ended" and result.blocks == 0
    state = emulator.nck.channels[1].state
    assert (state.actual_parts, state.total_parts, state.end_counter) == (0.0, 0.0, 3)


def test_a_normal_end_is_ended_and_a_reset_aborted() -> None:
    emulator = _emulator(b"G4 F1\nM30\n")
    channel = emulator.nck.channels[1]
    assert machine_status(emulator)["channel"]["program"] == "aborted"   # nothing has run since power-on
    result = run_offline(emulator, MAIN)
    assert result.outcome == "ended" and result.parts == 1.0
    assert channel.state.program_status == PROG_ABORTED                  # BTSS: 5 as after a reset
    assert machine_status(emulator)["channel"]["program"] == "ended"
    channel.reset()                                                      # a reset in reset changes nothing
    assert machine_status(emulator)["channel"]["program"] == "ended"
    channel.start()
    assert machine_status(emulator)["channel"]["program"] == "running"
    channel.reset()
    assert machine_status(emulator)["channel"]["program"] == "aborted"


def test_a_subprogram_in_use_is_not_replaced_or_deleted() -> None:
    sub = "/_N_SPF_DIR/_N_SUB_SPF"
    emulator = _emulator(b"SUB\nG4 F1\nM30\n", **{sub: b"G4 F100\nRET\n"})
    channel, programs = emulator.nck.channels[1], emulator.nck.programs
    channel.select(MAIN)
    channel.start()
    clock = emulator.clock
    assert isinstance(clock, SimulatedClock)
    clock.set(1.0)
    emulator.step_machine(1.0)
    assert channel.state.program == sub                                  # the run is in the subprogram
    with pytest.raises(NckPiStateError, match="in use"):
        programs.write(sub, b"M17\n")
    with pytest.raises(NckPiStateError, match="in use"):
        programs.delete(sub)
    with pytest.raises(NckPiStateError, match="running"):
        programs.write(MAIN, b"M30\n")
    programs.write("/_N_SPF_DIR/_N_OTHER_SPF", b"M17\n")                 # any other program may change
    assert programs.read(sub) == b"G4 F100\nRET\n"
    channel.reset()
    programs.write(sub, b"M17\n")
    assert programs.read(sub) == b"M17\n"
