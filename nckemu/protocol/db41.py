"""The 840C command channel in DB41, as the emulator implements it.

ASSUMPTION. The 840C "Interface Description Part 1: Signals" (which defines the real DB41
handshake and error numbers) was not available. This layout is ours; every offset and number is in
this module so it can be corrected in one place (docs/840c-command-channel.md describes it).

  DB41.DBB0   function number (9 = temperature compensation)
  DB41.DBB1   handshake: bit 0 REQUEST (PLC sets), bit 1 DONE (NC sets), bit 2 ERROR (NC sets)
  DB41.DBW2   number of the user DB holding the data
  DB41.DBW4   first data word n of the user data in that DB (S5 DW n = S7 bytes 2n..2n+1)
  DB41.DBW6   error number (0 = none), set with ERROR

The PLC writes DBB0, DBW2, DBW4, then sets REQUEST. The NC processes the request at once, clears
REQUEST and sets DONE, or ERROR with an error number. The PLC clears DONE/ERROR before the next job.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

CHANNEL_DB = 41
OFFSET_FUNCTION = 0
OFFSET_HANDSHAKE = 1
OFFSET_USER_DB = 2
OFFSET_DATA_WORD = 4
OFFSET_ERROR = 6
CHANNEL_BYTES = 8

BIT_REQUEST = 0x01
BIT_DONE = 0x02
BIT_ERROR = 0x04

FUNCTION_TEMPERATURE_COMPENSATION = 9


class ChannelError(IntEnum):
    """Error numbers the emulated NC reports in DB41.DBW6 (assumed, see module docstring)."""

    NONE = 0
    UNKNOWN_FUNCTION = 1
    USER_DB_MISSING = 2
    USER_DB_TOO_SHORT = 3
    BAD_LENGTH_WORD = 4
    BAD_AXIS_NUMBER = 5
    AXIS_NOT_PRESENT = 6
    BAD_FLAGS = 7
    TAN_BETA_OUT_OF_RANGE = 8
    VALUE_OUT_OF_RANGE = 9
    P0_AT_AXIS_ZERO = 10
    OPTION_MISSING = 11


@dataclass(frozen=True)
class ChannelStatus:
    function: int
    request: bool
    done: bool
    error: bool
    user_db: int
    data_word: int
    error_number: int


def build_request(user_db: int, data_word: int, function: int = FUNCTION_TEMPERATURE_COMPENSATION,
                  request: bool = True) -> bytes:
    """The 8 bytes a PLC writes to DB41 at offset 0 to start a job."""
    return struct.pack(">BBHHH", function, BIT_REQUEST if request else 0, user_db, data_word, 0)


def parse_status(data: bytes) -> ChannelStatus:
    function, handshake, user_db, data_word, error_number = struct.unpack(">BBHHH", data[:CHANNEL_BYTES])
    return ChannelStatus(function, bool(handshake & BIT_REQUEST), bool(handshake & BIT_DONE),
                         bool(handshake & BIT_ERROR), user_db, data_word, error_number)
