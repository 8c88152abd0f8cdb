"""The PLC's interface to the NCK channels: NC start, NC stop, reset and mode requests in, the
channel's state out (docs/programs.md, programs.md 10).

- DB21 (DB22 ... for channels 2 ...), PLC -> NCK: rising edges of DBX7.1 NC start, DBX7.3 NC stop,
  DBX7.7 reset, from any writer (an S7 client, the user's STL program, an OPC UA write).
- DB21.DBB35, NCK -> PLC: .0 program running, .1 waiting, .2 stopped, .3 interrupted, .4 aborted,
  .5 channel active, .6 channel interrupted, .7 channel reset (.0 .4 .5 .7 from the sources, the others
  by the 802S's byte order: inference).
- DB11 (mode group 1): rising edges of DBX0.0 AUTOMATIC, DBX0.1 MDA, DBX0.2 JOG request a mode; DBB6
  shows the active one in the same bit order (DBX6.0 AUTOMATIC, 6.1 MDA, 6.2 JOG: inference).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from nckemu.emulator.machine.nck.channel_states import (
    CHAN_ACTIVE,
    CHAN_INTERRUPTED,
    CHAN_RESET,
    MODE_AUTOMATIC,
    MODE_JOG,
    MODE_MDA,
    PROG_ABORTED,
    PROG_INTERRUPTED,
    PROG_RUNNING,
    PROG_STOPPED,
    PROG_WAITING,
)
from nckemu.errors import NckError

if TYPE_CHECKING:
    from nckemu.emulator.machine.nck.channel import Channel

log = logging.getLogger("nckemu.emulator.plc.channel_signals")

MODE_GROUP_DB = 11
FIRST_CHANNEL_DB = 21
CHANNEL_DB_BYTES = 400
MODE_GROUP_DB_BYTES = 64
BYTE_CONTROL = 7
BIT_START, BIT_STOP, BIT_RESET = 1, 3, 7
BYTE_STATE = 35
BYTE_MODE_REQUEST = 0
BYTE_MODE_ACTIVE = 6
# DB11.DBX0.n requests mode: bit -> opMode; DBB6 shows the active mode in the same bit order.
MODE_REQUEST_BITS = {0: MODE_AUTOMATIC, 1: MODE_MDA, 2: MODE_JOG}
MODE_ACTIVE_BITS = {mode: 1 << bit for bit, mode in MODE_REQUEST_BITS.items()}
# DB21.DBB35: the program's status in bits 0-4, the channel's in bits 5-7.
_PROGRAM_STATE_BITS = {PROG_RUNNING: 0x01, PROG_WAITING: 0x02, PROG_STOPPED: 0x04, PROG_INTERRUPTED: 0x08,
                       PROG_ABORTED: 0x10}
_CHANNEL_STATE_BITS = {CHAN_ACTIVE: 0x20, CHAN_INTERRUPTED: 0x40, CHAN_RESET: 0x80}


def state_byte(channel: Channel) -> int:
    state = channel.state
    return _PROGRAM_STATE_BITS.get(state.program_status, 0) | _CHANNEL_STATE_BITS.get(state.status, 0)


class ChannelSignals:
    """Edges of the PLC's control bits to the channels' calls, their state back into the DBs."""

    def __init__(self, blocks: dict[int, bytearray], channels: dict[int, Channel],
                 tell_written: Callable[[int, int, int], None]) -> None:
        self.blocks = blocks
        self.channels = channels
        self._tell_written = tell_written
        for number in channels:
            blocks.setdefault(FIRST_CHANNEL_DB + number - 1, bytearray(CHANNEL_DB_BYTES))
        blocks.setdefault(MODE_GROUP_DB, bytearray(MODE_GROUP_DB_BYTES))
        self._control = {number: blocks[FIRST_CHANNEL_DB + number - 1][BYTE_CONTROL] for number in channels}
        self._mode_request = blocks[MODE_GROUP_DB][BYTE_MODE_REQUEST]
        for channel in channels.values():
            channel.state_listeners.append(self.show)
            self.show(channel)

    def watches(self, db_number: int, start: int, size: int) -> bool:
        if db_number == MODE_GROUP_DB:
            return start <= BYTE_MODE_REQUEST < start + size
        number = db_number - FIRST_CHANNEL_DB + 1
        return number in self.channels and start <= BYTE_CONTROL < start + size

    def written(self, db_number: int) -> None:
        """After a write that covered a control byte: act on its rising edges."""
        if db_number == MODE_GROUP_DB:
            now = self.blocks[MODE_GROUP_DB][BYTE_MODE_REQUEST]
            rising, self._mode_request = now & ~self._mode_request, now
            for bit, mode in MODE_REQUEST_BITS.items():
                if rising & (1 << bit):
                    self._call(lambda mode=mode: [c.set_mode(mode) for c in self.channels.values()],
                               f"mode request {mode}")
            return
        number = db_number - FIRST_CHANNEL_DB + 1
        now = self.blocks[db_number][BYTE_CONTROL]
        rising, self._control[number] = now & ~self._control[number], now
        channel = self.channels[number]
        # reset first: a write that sets reset and start together resets, then starts
        if rising & (1 << BIT_RESET):
            self._call(channel.reset, f"DB{db_number}.DBX7.7 reset")
        if rising & (1 << BIT_STOP):
            self._call(channel.stop, f"DB{db_number}.DBX7.3 NC stop")
        if rising & (1 << BIT_START):
            self._call(channel.start, f"DB{db_number}.DBX7.1 NC start")

    def _call(self, action: Callable[[], Any], what: str) -> None:
        try:
            action()
        except NckError as exc:  # the control's refusal is its alarm; the write itself succeeded
            log.info("%s refused: %s", what, exc)

    def show(self, channel: Channel) -> None:
        db_number = FIRST_CHANNEL_DB + channel.number - 1
        block = self.blocks.get(db_number)
        if block is not None and len(block) > BYTE_STATE:
            value = state_byte(channel)
            if block[BYTE_STATE] != value:
                block[BYTE_STATE] = value
                self._tell_written(db_number, BYTE_STATE, 1)
        if channel.number == 1:
            mode_block = self.blocks[MODE_GROUP_DB]
            value = MODE_ACTIVE_BITS.get(channel.state.mode, 0)
            if mode_block[BYTE_MODE_ACTIVE] != value:
                mode_block[BYTE_MODE_ACTIVE] = value
                self._tell_written(MODE_GROUP_DB, BYTE_MODE_ACTIVE, 1)
