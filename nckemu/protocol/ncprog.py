"""NC program transfer: the userdata group "NC programming" and the PLC-block upload of an NC file.

Parameter (userdata, ROSCTR 7): ``00 01 12``, the length of what follows (4 short, 8 long), the
method (0x11 with the short form, 0x12 with the long one), the type-and-group byte (0x7F NC request,
0x3F NC push, 0xBF NC response), the subfunction and the transfer's sequence number (the NC assigns
it in its first answer, the client repeats it); the long form adds the data unit reference, the
"last data unit" byte (0 = this is the last, 1 = more follow) and a 16-bit error code.

Data: return code (0xFF), transport size (0x09), a 16-bit length and the payload, which is per
subfunction: a file name (request download); window + one byte (answer to request download,
continue download, continue upload); ``00 FB`` + a piece of the transfer content (download block);
``00 00`` (download ended); window + ``00`` + file name (start upload); two bytes + a piece of the
content (answer to start upload, upload push). An error answer carries ``0A 00 00 00``.

Transfer content (what the pieces add up to): 8 ASCII digits giving the number of bytes after the
first 24, a 16-byte time stamp (``yyMMddHHmmss`` and four spaces), the line ``;$PATH=<directory>``
ended by LF, then the program text.

PLC-block path: jobs 0x1D/0x1E/0x1F (``protocol/blocks.py``) with an NC file name; the 0x1E answer's
data is a 16-bit length, two bytes (``00 FB``) and the bytes.

Sources: Wireshark's s7comm dissector (subfunction names, the reassembly and the content fields),
libnodave's NC transfer functions (what a client sends and checks), tshark 4.0.17's decoding of the
byte vectors in ``tests/protocol/test_ncprog.py``; the byte meanings and what is inferred are
listed in docs/programs-transfer.md.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime
from enum import IntEnum

from construct import Bytes, Const, ConstructError, GreedyBytes, If, Int8ub, Int16ub, Struct, this

from .errors import NckProtocolError, NckTruncatedError
from .userdata import GROUP_NC_PROGRAMMING
from .userdata import SUBFUNCTION_NAMES as USERDATA_SUBFUNCTION_NAMES

PARAMETER_HEAD = b"\x00\x01\x12"
METHOD_SHORT = 0x11
METHOD_LONG = 0x12
# The type-and-group byte (parameter byte 5): tshark 4.0 reads the high nibble as the type (7 NC
# request, 3 NC push, 11 NC response) and the low one as group 15 "NC programming".
NC_REQUEST = 0x7F
NC_PUSH = 0x3F
NC_RESPONSE = 0xBF
NC_TYPES = frozenset({NC_REQUEST, NC_PUSH, NC_RESPONSE})
TYPE_NAMES = {NC_REQUEST: "NC Request", NC_PUSH: "NC Push", NC_RESPONSE: "NC Response"}

# "last data unit": 0 = this is the last, 1 = more follow.
LAST_DATA_UNIT = 0x00
MORE_DATA_UNITS = 0x01
RETURN_CODE_SUCCESS = 0xFF
RETURN_CODE_OBJECT_DOES_NOT_EXIST = 0x0A
TRANSPORT_SIZE_OCTET_STRING = 0x09
# The two bytes before each piece of content in a download block (libnodave sends them; Wireshark
# strips them before reassembly). What they mean is not known; uploads carry the same two here.
CHUNK_PREFIX = b"\x00\xFB"
# The data part of an error answer (return code "object does not exist", no payload).
ERROR_DATA = b"\x0A\x00\x00\x00"
# The 2-byte error codes an NC transfer answers with. No source gives the codes an NCK puts there
# (reference programs.md §5, §12.2: UNCONFIRMED); these are S7 codes whose meaning fits and that
# tshark names, so a capture reads well. A client only tests "not 0" (libnodave).
ERROR_NO_SUCH_FILE = 0xD209      # "(at least) one of the given blocks not found on the module"
ERROR_STORE_FULL = 0x8301        # "insufficient memory space or work memory on the module"
ERROR_NOT_A_FILE_NAME = 0xD201   # "syntax error in block name" (``..``, spaces, not _N_..._MPF)
ERROR_IN_USE = 0x8001            # "service cannot be performed while the block is in the current status"
ERROR_BAD_CONTENT = 0xD202       # "syntax error in function parameters" (header, length, $PATH line)
ERROR_SEQUENCE = 0x8401          # "invalid service sequence" (no such transfer on this connection)
ERROR_TEXTS = {
    ERROR_NO_SUCH_FILE: "no such file or directory", ERROR_STORE_FULL: "the program store is full",
    ERROR_NOT_A_FILE_NAME: "not an NC file name", ERROR_IN_USE: "the program is running",
    ERROR_BAD_CONTENT: "the transfer's header is not valid (length, time stamp, $PATH line), or a "
                       "definition file with an error (the NCK's alarm list names its line)",
    ERROR_SEQUENCE: "no such transfer (sequence)",
}
# Window sizes the clients use: libnodave's upload asks for 20 pushes before its continue upload.
UPLOAD_WINDOW = 20
HEADER_BYTES = 24
STAMP_BYTES = 16
LENGTH_DIGITS = 8
PATH_PREFIX = b";$PATH="
# libnodave's limit for a file name in the request (32 characters).
MAX_NAME_BYTES = 32
# Room left for a download block's content in a PDU: header 10, long parameter 12, data header 4,
# the two prefix bytes (libnodave: PDU size - 28).
BLOCK_OVERHEAD = 10 + 12 + 4 + 2


class NcSubfunction(IntEnum):
    REQUEST_DOWNLOAD = 1
    DOWNLOAD_BLOCK = 2
    CONTINUE_DOWNLOAD = 3
    DOWNLOAD_ENDED = 4
    START_UPLOAD = 6
    UPLOAD = 7
    CONTINUE_UPLOAD = 8


# tshark's names, as the userdata table has them for the group.
SUBFUNCTION_NAMES = USERDATA_SUBFUNCTION_NAMES[GROUP_NC_PROGRAMMING]

# ---------------------------------------------------------------- declarations (construct)
NC_PARAMETER = Struct(
    "head" / Const(PARAMETER_HEAD),
    "length" / Int8ub,  # 4 short, 8 long
    "method" / Int8ub,
    "type" / Int8ub,
    "subfunction" / Int8ub,
    "sequence" / Int8ub,
    "data_unit_ref" / If(this.length == 8, Int8ub),
    "last_data_unit" / If(this.length == 8, Int8ub),
    "error_code" / If(this.length == 8, Int16ub),
)
NC_DATA = Struct(
    "return_code" / Int8ub,
    "transport_size" / Int8ub,
    "length" / Int16ub,
    "payload" / Bytes(this.length),
)
UPLOAD_DATA = Struct(  # the data part of a 0x1E answer
    "length" / Int16ub,
    "prefix" / Bytes(2),
    "content" / GreedyBytes,
)


@dataclass(frozen=True, slots=True)
class NcParameter:
    """The parameter of an NC programming userdata PDU (the last three fields exist in the long form)."""

    type: int
    subfunction: int
    sequence: int = 0
    long: bool = False
    data_unit_ref: int = 0
    last_data_unit: int = LAST_DATA_UNIT
    error_code: int = 0
    method: int | None = None  # None: 0x11 for the short form, 0x12 for the long one

    @property
    def wire_method(self) -> int:
        if self.method is not None:
            return self.method
        return METHOD_LONG if self.long else METHOD_SHORT

    @property
    def is_last(self) -> bool:
        return self.last_data_unit == LAST_DATA_UNIT


def is_nc_parameter(parameter: bytes) -> bool:
    """Whether a userdata parameter belongs to the NC programming group (cheap, no parsing)."""
    return len(parameter) >= 8 and parameter[:3] == PARAMETER_HEAD and parameter[5] in NC_TYPES


def parse_nc_parameter(parameter: bytes) -> NcParameter:
    if len(parameter) < 8:
        raise NckTruncatedError(f"NC programming parameter of {len(parameter)} bytes")
    if parameter[3] not in (4, 8) or len(parameter) != 4 + parameter[3]:
        raise NckProtocolError(f"NC programming parameter announces {parameter[3]} bytes, has {len(parameter) - 4}")
    try:
        fields = NC_PARAMETER.parse(parameter)
    except ConstructError as exc:
        raise NckProtocolError(f"not an NC programming parameter: {exc}") from None
    if fields.type not in NC_TYPES:
        raise NckProtocolError(f"type 0x{fields.type:02X} is not NC programming")
    # The method kept only where it is not the one of its form (0x11 short, 0x12 long).
    if fields.length == 4:
        method = None if fields.method == METHOD_SHORT else fields.method
        return NcParameter(fields.type, fields.subfunction, fields.sequence, method=method)
    method = None if fields.method == METHOD_LONG else fields.method
    return NcParameter(fields.type, fields.subfunction, fields.sequence, True, fields.data_unit_ref,
                       fields.last_data_unit, fields.error_code, method=method)


def build_nc_parameter(parameter: NcParameter) -> bytes:
    values = (parameter.wire_method, parameter.type, parameter.subfunction, parameter.sequence)
    if not all(0 <= value <= 0xFF for value in values):
        raise NckProtocolError(f"NC programming parameter field out of range: {parameter}")
    return NC_PARAMETER.build({
        "length": 8 if parameter.long else 4, "method": parameter.wire_method, "type": parameter.type,
        "subfunction": parameter.subfunction, "sequence": parameter.sequence,
        "data_unit_ref": parameter.data_unit_ref, "last_data_unit": parameter.last_data_unit,
        "error_code": parameter.error_code})


@dataclass(frozen=True, slots=True)
class NcData:
    """The data part: return code, transport size and the payload (the length is the payload's)."""

    payload: bytes
    return_code: int = RETURN_CODE_SUCCESS
    transport_size: int = TRANSPORT_SIZE_OCTET_STRING


def parse_nc_data(data: bytes) -> NcData:
    if len(data) < 4:
        raise NckTruncatedError(f"NC programming data part of {len(data)} bytes")
    try:
        fields = NC_DATA.parse(data)
    except ConstructError:
        raise NckTruncatedError("NC programming data part shorter than its length") from None
    if 4 + fields.length != len(data):
        raise NckProtocolError(f"NC programming data part announces {fields.length} bytes, has {len(data) - 4}")
    return NcData(fields.payload, fields.return_code, fields.transport_size)


def build_nc_data(data: NcData) -> bytes:
    if len(data.payload) > 0xFFFF:
        raise NckProtocolError("NC programming payload over 65535 bytes")
    return NC_DATA.build({"return_code": data.return_code, "transport_size": data.transport_size,
                          "length": len(data.payload), "payload": data.payload})


# ---------------------------------------------------------------- payloads
def _name(raw: bytes) -> str:
    try:
        return raw.decode("ascii")
    except UnicodeDecodeError:
        raise NckProtocolError("NC file name is not ASCII") from None


def build_name(name: str) -> bytes:
    try:
        raw = name.encode("ascii")
    except UnicodeEncodeError:
        raise NckProtocolError(f"NC file name {name!r} is not ASCII") from None
    if not raw or len(raw) > MAX_NAME_BYTES:
        raise NckProtocolError(f"NC file name {name!r}: 1 to {MAX_NAME_BYTES} characters")
    return raw


def parse_name(payload: bytes) -> str:
    """The payload of a request download: the file name alone."""
    if not payload:
        raise NckProtocolError("request download without a file name")
    return _name(payload)


@dataclass(frozen=True, slots=True)
class Window:
    """How many telegrams may go unacknowledged, and the byte after it (0 in every capture known)."""

    count: int
    extra: int = 0


def parse_window(payload: bytes) -> Window:
    if len(payload) != 2:
        raise NckProtocolError(f"window payload of {len(payload)} bytes, not 2")
    return Window(payload[0], payload[1])


def build_window(window: Window) -> bytes:
    if not (0 <= window.count <= 0xFF and 0 <= window.extra <= 0xFF):
        raise NckProtocolError(f"window {window} out of range")
    return bytes([window.count, window.extra])


def parse_chunk(payload: bytes) -> bytes:
    """A download block's or an upload piece's content (the two leading bytes dropped)."""
    if len(payload) < 2:
        raise NckTruncatedError("NC transfer piece shorter than its two leading bytes")
    return payload[2:]


def build_chunk(content: bytes, prefix: bytes = CHUNK_PREFIX) -> bytes:
    return prefix + content


@dataclass(frozen=True, slots=True)
class StartUpload:
    name: str
    window: int = UPLOAD_WINDOW
    extra: int = 0


def parse_start_upload(payload: bytes) -> StartUpload:
    if len(payload) < 3:
        raise NckProtocolError("start upload without a file name")
    return StartUpload(_name(payload[2:]), payload[0], payload[1])


def build_start_upload(request: StartUpload) -> bytes:
    return build_window(Window(request.window, request.extra)) + build_name(request.name)


# ---------------------------------------------------------------- transfer content
@dataclass(frozen=True, slots=True)
class TransferContent:
    """What a download's blocks or an upload's pieces add up to. ``length`` None: eight spaces
    (what Wireshark expects of a directory); ``stamp`` is the 16 characters as sent."""

    path: str
    text: bytes
    stamp: str = " " * STAMP_BYTES
    length: int | None = -1  # -1: the number of bytes after the header, computed on build


_DIGITS = re.compile(rb"[0-9]{8}")


def parse_transfer_content(content: bytes) -> TransferContent:
    """Raises NckProtocolError where the header is not 8 digits (or spaces), a 16-byte stamp and a
    ``;$PATH=`` line ended by LF, or where the length does not match the bytes that follow."""
    if len(content) < HEADER_BYTES:
        raise NckTruncatedError(f"NC transfer content of {len(content)} bytes, shorter than its header")
    raw_length = content[:LENGTH_DIGITS]
    length: int | None
    if raw_length == b" " * LENGTH_DIGITS:
        length = None
    elif _DIGITS.fullmatch(raw_length):
        length = int(raw_length)
    else:
        raise NckProtocolError(f"NC transfer length {raw_length!r} is not 8 digits")
    try:
        stamp = content[LENGTH_DIGITS:HEADER_BYTES].decode("ascii")
    except UnicodeDecodeError:
        raise NckProtocolError("NC transfer time stamp is not ASCII") from None
    body = content[HEADER_BYTES:]
    end = body.find(b"\n")
    if not body.startswith(PATH_PREFIX) or end < 0:
        raise NckProtocolError("NC transfer content without a ;$PATH= line ended by LF")
    raw_path = body[len(PATH_PREFIX):end]
    if raw_path.endswith(b"\r"):
        raise NckProtocolError("NC transfer path line ends in CR LF, not LF")
    if length is not None and length != len(body):
        raise NckProtocolError(f"NC transfer announces {length} bytes, carries {len(body)}")
    return TransferContent(_name(raw_path), body[end + 1:], stamp, length)


def build_transfer_content(content: TransferContent) -> bytes:
    stamp = content.stamp.encode("ascii")
    if len(stamp) != STAMP_BYTES:
        raise NckProtocolError(f"NC transfer time stamp {content.stamp!r} is not {STAMP_BYTES} characters")
    path = content.path.encode("ascii")
    if b"\n" in path or b"\r" in path:
        raise NckProtocolError("NC transfer path with a line end")
    body = PATH_PREFIX + path + b"\n" + content.text
    if content.length is None:
        head = b" " * LENGTH_DIGITS
    else:
        length = len(body) if content.length == -1 else content.length
        if not 0 <= length <= 99_999_999:
            raise NckProtocolError(f"NC transfer of {length} bytes does not fit 8 digits")
        head = b"%08d" % length
    return head + stamp + body


def stamp_of(year: int, month: int, day: int, hour: int, minute: int, second: int) -> str:
    """The 16-character time stamp libnodave writes: ``yyMMddHHmmss`` and four spaces."""
    return f"{year % 100:02d}{month:02d}{day:02d}{hour:02d}{minute:02d}{second:02d}    "


def stamp_at(moment: datetime) -> str:
    """``stamp_of`` of a moment."""
    return stamp_of(moment.year, moment.month, moment.day, moment.hour, moment.minute, moment.second)


def is_nc_file_name(name: str) -> bool:
    """An NC file (``_N_..``, or a path) rather than a PLC block, as an upload names it."""
    return name.upper().startswith("_N_") or name.startswith("/")


def split_content(content: bytes, room: int) -> list[bytes]:
    """``content`` in pieces of at most ``room`` bytes (one empty piece for empty content)."""
    if room <= 0:
        raise NckProtocolError("no room for NC transfer content in the PDU")
    return [content[offset:offset + room] for offset in range(0, len(content), room)] or [b""]


# ---------------------------------------------------------------- PLC-block path (0x1E answer data)
@dataclass(frozen=True, slots=True)
class UploadData:
    content: bytes
    prefix: bytes = CHUNK_PREFIX


def parse_upload_data(data: bytes) -> UploadData:
    if len(data) < 4:
        raise NckTruncatedError(f"upload data of {len(data)} bytes")
    fields = UPLOAD_DATA.parse(data)
    if fields.length != len(fields.content):
        raise NckProtocolError(f"upload data announces {fields.length} bytes, carries {len(fields.content)}")
    return UploadData(fields.content, fields.prefix)


def build_upload_data(data: UploadData) -> bytes:
    if len(data.prefix) != 2 or len(data.content) > 0xFFFF:
        raise NckProtocolError("upload data: two prefix bytes and at most 65535 content bytes")
    return UPLOAD_DATA.build({"length": len(data.content), "prefix": data.prefix, "content": data.content})


def describe(parameter: NcParameter) -> str:
    """``NC Request -> Request download`` (tshark's wording for type and subfunction)."""
    kind = TYPE_NAMES.get(parameter.type, f"type 0x{parameter.type:02X}")
    try:
        name = SUBFUNCTION_NAMES[NcSubfunction(parameter.subfunction)]
    except (ValueError, KeyError):
        name = f"subfunction {parameter.subfunction}"
    return f"{kind} -> {name}"
