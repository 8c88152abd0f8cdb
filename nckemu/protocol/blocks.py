"""Block transfer (functions 0x1A..0x1F: download and upload of PLC blocks) and the block lists of the
PLC-type PI services (``_INSE``, ``_DELE``).

A download is driven by the programming device's request (0x1A), after which the *PLC* sends the
jobs: it asks for the block (0x1B download block, answered by the programming device with the block
bytes) and closes the transfer (0x1C download ended). An upload stays with the programming device:
start upload (0x1D, answered with an upload id and the block length), upload (0x1E, answered with
block bytes), end upload (0x1F).

Job parameter: function, a status byte, a 16-bit error code, 4 bytes (the upload id in 0x1E/0x1F),
then, except for 0x1E/0x1F, the length and the file name: ``_`` (whole block; ``$`` block header),
the block type as two characters (``0A`` = DB), its number in five digits and the file system
(``P`` passive, ``A`` active, ``B`` both); 0x1A adds a second part (length, ``1``, load memory and
MC7 code length in six digits each). Answers carry the function alone (0x1A, 0x1C, 0x1F), function
and status (0x1B, 0x1E, whose data part is a 16-bit length, 2 unknown bytes and the block bytes), or
the fixed part and the block length as text (0x1D).

A PLC PI service's parameter block is the number of blocks, one unknown byte, and each block's
8-character name (``0A00001P`` = DB 1 in the passive file system).

Sources: Wireshark's s7comm dissector (``s7comm_decode_plc_controls_updownload``,
``s7comm_decode_pi_service``; function, block type and file system names); tshark 4.0.17's decoding
of the frames of ``tests/traces/test_field_corpus.py``.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from .errors import NckProtocolError, NckTruncatedError
from .s7 import Function

# The block transfer functions as plain ints (they are compared with raw parameter bytes).
REQUEST_DOWNLOAD = int(Function.REQUEST_DOWNLOAD)
DOWNLOAD_BLOCK = int(Function.DOWNLOAD_BLOCK)
DOWNLOAD_ENDED = int(Function.DOWNLOAD_ENDED)
START_UPLOAD = int(Function.START_UPLOAD)
UPLOAD = int(Function.UPLOAD)
END_UPLOAD = int(Function.END_UPLOAD)
FUNCTIONS = frozenset(range(REQUEST_DOWNLOAD, END_UPLOAD + 1))

BLOCK_TYPE_NAMES = {"08": "OB", "09": "CMod", "0A": "DB", "0B": "SDB", "0C": "FC", "0D": "SFC", "0E": "FB",
                    "0F": "SFB"}
FILE_SYSTEM_NAMES = {"P": "passive", "A": "active", "B": "active and passive"}

_FIXED = struct.Struct(">BBHI")


@dataclass(frozen=True, slots=True)
class BlockName:
    """``0A00001P``: block type, number, file system; ``ident`` is the ``_``/``$`` of a transfer's name."""

    block_type: str
    number: int
    file_system: str
    ident: str = ""

    def __str__(self) -> str:
        return f"{self.ident}{self.block_type}{self.number:05d}{self.file_system}"

    @property
    def readable(self) -> str:
        kind = BLOCK_TYPE_NAMES.get(self.block_type.upper(), f"block type {self.block_type}")
        return f"{kind} {self.number}"


def _ascii(raw: bytes, what: str) -> str:
    try:
        return raw.decode("ascii")
    except UnicodeDecodeError:
        raise NckProtocolError(f"{what} is not ASCII") from None


def parse_block_name(text: str) -> BlockName:
    ident = ""
    if len(text) == 9:
        ident, text = text[0], text[1:]
    if len(text) != 8 or not text[2:7].isdigit() or not text[2:7].isascii():
        raise NckProtocolError(f"block name {text!r} is not <type><5 digits><file system>")
    return BlockName(text[:2], int(text[2:7]), text[7], ident)


def build_block_name(name: BlockName) -> str:
    if len(name.block_type) != 2 or len(name.file_system) != 1 or len(name.ident) > 1 \
            or not 0 <= name.number <= 99999:
        raise NckProtocolError(f"block name {name!r} does not fit <type><5 digits><file system>")
    return str(name)


@dataclass(frozen=True, slots=True)
class BlockControl:
    """The parameter of a block transfer job or answer. ``status`` None: the function byte alone;
    ``error_code`` None: function and status alone; ``file_name`` None: the fixed part alone."""

    function: int
    status: int | None = None
    error_code: int | None = None
    session: int = 0
    file_name: str | None = None
    part2: str | None = None


def parse_block_control(parameter: bytes) -> BlockControl:
    if not parameter or parameter[0] not in FUNCTIONS:
        raise NckProtocolError("not a block transfer parameter (0x1A..0x1F)")
    function = parameter[0]
    if len(parameter) == 1:
        return BlockControl(function)
    if len(parameter) == 2:
        return BlockControl(function, parameter[1])
    if len(parameter) < _FIXED.size:
        raise NckTruncatedError(f"block transfer parameter of {len(parameter)} bytes")
    _function, status, error_code, session = _FIXED.unpack_from(parameter)
    parts: list[str] = []
    offset = _FIXED.size
    while offset < len(parameter) and len(parts) < 2:
        length = parameter[offset]
        end = offset + 1 + length
        if end > len(parameter):
            raise NckTruncatedError(f"block transfer name announces {length} bytes beyond the parameter")
        parts.append(_ascii(parameter[offset + 1:end], "block transfer name"))
        offset = end
    if offset != len(parameter):
        raise NckProtocolError(f"{len(parameter) - offset} bytes after a block transfer parameter")
    return BlockControl(function, status, error_code, session, parts[0] if parts else None,
                        parts[1] if len(parts) > 1 else None)


def build_block_control(control: BlockControl) -> bytes:
    if control.status is None:
        return bytes([control.function])
    if control.error_code is None:
        return bytes([control.function, control.status])
    raw = _FIXED.pack(control.function, control.status, control.error_code, control.session)
    for part in (control.file_name, control.part2):
        if part is None:
            break
        encoded = part.encode("ascii")
        if len(encoded) > 255:
            raise NckProtocolError("block transfer name of more than 255 characters")
        raw += bytes([len(encoded)]) + encoded
    return raw


def describe_block_control(control: BlockControl) -> str:
    """``_0A00001P (DB 1, passive)``, an upload id, or nothing."""
    if control.file_name is not None:
        try:
            name = parse_block_name(control.file_name)
        except NckProtocolError:
            return control.file_name
        where = FILE_SYSTEM_NAMES.get(name.file_system, f"file system {name.file_system}")
        return f"{control.file_name} ({name.readable}, {where})"
    if control.function in (UPLOAD, END_UPLOAD) and control.error_code is not None:
        return f"upload id {control.session}"
    return ""


def parse_block_list(block: bytes) -> tuple[BlockName, ...]:
    """The parameter block of ``_INSE``/``_DELE``: count, one unknown byte, 8-character names."""
    if len(block) < 2:
        raise NckTruncatedError("PI block list shorter than its count")
    count = block[0]
    if len(block) != 2 + 8 * count:
        raise NckProtocolError(f"PI block list of {count} names in {len(block) - 2} bytes")
    return tuple(parse_block_name(_ascii(block[2 + 8 * i:10 + 8 * i], "PI block name")) for i in range(count))


def build_block_list(names: tuple[BlockName, ...]) -> bytes:
    if len(names) > 255:
        raise NckProtocolError("a PI block list holds up to 255 blocks")
    raw = bytes([len(names), 0])
    for name in names:
        if name.ident:
            raise NckProtocolError("PI block names carry no _ or $")
        raw += build_block_name(name).encode("ascii")
    return raw
