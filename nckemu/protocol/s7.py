"""S7comm PDUs: header, setup communication, read var and write var with mixed item syntaxes.

The formats are declared once with construct (``HEADER``, ``S7ANY_ITEM``, ``NCK_ITEM``,
``DATA_ITEM_HEADER``...). The parse/build functions below are hand-written on ``struct`` because
they sit on the server's hot path; ``tests/protocol`` checks them against the declarations.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

from construct import Bytes, Const, If, Int8ub, Int16ub, Int24ub, Struct, this

from .addresses import (
    NCK_SYNTAX_IDS,
    Address,
    NckAddress,
    S7AnyAddress,
    SyntaxId,
    UnsupportedAddress,
)
from .errors import NckProtocolError, NckTruncatedError

PROTOCOL_ID = 0x32
VAR_SPEC = 0x12


class Rosctr(IntEnum):
    JOB = 0x01
    ACK = 0x02
    ACK_DATA = 0x03
    USERDATA = 0x07


class Function(IntEnum):
    CPU_SERVICES = 0x00
    READ_VAR = 0x04
    WRITE_VAR = 0x05
    REQUEST_DOWNLOAD = 0x1A
    DOWNLOAD_BLOCK = 0x1B
    DOWNLOAD_ENDED = 0x1C
    START_UPLOAD = 0x1D
    UPLOAD = 0x1E
    END_UPLOAD = 0x1F
    PI_SERVICE = 0x28
    PLC_STOP = 0x29
    SETUP_COMMUNICATION = 0xF0


# ---------------------------------------------------------------- declarations (construct)
HEADER = Struct(
    "protocol_id" / Const(PROTOCOL_ID, Int8ub),
    "rosctr" / Int8ub,
    "redundancy_id" / Int16ub,
    "pdu_ref" / Int16ub,
    "parameter_length" / Int16ub,
    "data_length" / Int16ub,
    "error_class" / If(lambda ctx: ctx.rosctr in (2, 3), Int8ub),
    "error_code" / If(lambda ctx: ctx.rosctr in (2, 3), Int8ub),
    "parameter" / Bytes(this.parameter_length),
    "data" / Bytes(this.data_length),
)
SETUP_COMMUNICATION = Struct(
    "function" / Const(Function.SETUP_COMMUNICATION, Int8ub),
    "reserved" / Int8ub,
    "max_amq_calling" / Int16ub,
    "max_amq_called" / Int16ub,
    "pdu_length" / Int16ub,
)
S7ANY_ITEM = Struct(
    "var_spec" / Const(VAR_SPEC, Int8ub),
    "length" / Const(10, Int8ub),
    "syntax_id" / Const(SyntaxId.S7ANY, Int8ub),
    "transport_size" / Int8ub,
    "count" / Int16ub,
    "db_number" / Int16ub,
    "area" / Int8ub,
    "address" / Int24ub,  # byte address << 3 | bit address
)
NCK_ITEM = Struct(
    "var_spec" / Const(VAR_SPEC, Int8ub),
    "length" / Const(8, Int8ub),
    "syntax_id" / Int8ub,  # 0x82 NCK, 0x83 NCK_M, 0x84 NCK_I
    "area_unit" / Int8ub,  # area << 5 | unit
    "column" / Int16ub,
    "line" / Int16ub,
    "module" / Int8ub,
    "line_count" / Int8ub,
)
DATA_ITEM_HEADER = Struct(
    "return_code" / Int8ub,
    "transport_size" / Int8ub,
    "length" / Int16ub,  # bits for transport sizes 3, 4, 5; bytes otherwise
)

# ---------------------------------------------------------------- fast path
_HEADER_10 = struct.Struct(">BBHHHH")
_HEADER_12 = struct.Struct(">BBHHHHBB")
_SETUP = struct.Struct(">BBHHH")
_S7ANY = struct.Struct(">BBBBHHBBH")  # var spec .. area, then the 24-bit address as byte + word
_NCK = struct.Struct(">BBBBHHBB")
_DATA_HEADER = struct.Struct(">BBH")

# Data transport sizes whose length field counts bits.
BIT_LENGTH_TRANSPORT_SIZES = frozenset({0x03, 0x04, 0x05})
# Return codes of data items followed by data: success in answers, 0x00 in write jobs. An error item
# has no data even where its length says otherwise: a real S7-300 answers a read of missing objects
# with ``0A 00 00 04`` and nothing after it, and Wireshark reads data only after 0xFF and 0x00.
DATA_RETURN_CODES = frozenset({0x00, 0xFF})


@dataclass(frozen=True, slots=True)
class S7Pdu:
    rosctr: int
    pdu_ref: int
    parameter: bytes = b""
    data: bytes = b""
    error_class: int = 0
    error_code: int = 0


@dataclass(frozen=True, slots=True)
class SetupCommunication:
    max_amq_calling: int
    max_amq_called: int
    pdu_length: int


@dataclass(frozen=True, slots=True)
class DataItem:
    """A data item of a read answer or a write job: return code, transport size, value bytes."""

    return_code: int
    transport_size: int
    data: bytes


@dataclass(frozen=True, slots=True)
class ReadVarRequest:
    items: tuple[Address, ...]


@dataclass(frozen=True, slots=True)
class ReadVarResponse:
    items: tuple[DataItem, ...]


@dataclass(frozen=True, slots=True)
class WriteVarRequest:
    items: tuple[Address, ...]
    values: tuple[DataItem, ...]


@dataclass(frozen=True, slots=True)
class WriteVarResponse:
    return_codes: tuple[int, ...]


def has_error_fields(rosctr: int) -> bool:
    return rosctr in (Rosctr.ACK, Rosctr.ACK_DATA)


def parse_pdu(raw: bytes) -> S7Pdu:
    """One S7 PDU (the COTP DT payload); lengths must add up exactly."""
    if len(raw) < 10:
        raise NckTruncatedError(f"S7 PDU of {len(raw)} bytes is shorter than its header")
    protocol_id, rosctr, _redundancy, pdu_ref, parameter_length, data_length = _HEADER_10.unpack_from(raw)
    if protocol_id != PROTOCOL_ID:
        raise NckProtocolError(f"S7 protocol ID 0x{protocol_id:02X}, expected 0x32")
    if rosctr not in (1, 2, 3, 7):
        raise NckProtocolError(f"S7 ROSCTR {rosctr} is not job, ack, ack_data or userdata")
    error_class = error_code = 0
    offset = 10
    if rosctr == 2 or rosctr == 3:
        if len(raw) < 12:
            raise NckTruncatedError("S7 ack header shorter than 12 bytes")
        error_class, error_code = raw[10], raw[11]
        offset = 12
    end = offset + parameter_length + data_length
    if end != len(raw):
        if end > len(raw):
            raise NckTruncatedError(f"S7 header announces {end} bytes, the PDU has {len(raw)}")
        raise NckProtocolError(f"S7 PDU has {len(raw) - end} bytes beyond its announced lengths")
    parameter = raw[offset:offset + parameter_length]
    data = raw[offset + parameter_length:end]
    return S7Pdu(rosctr, pdu_ref, parameter, data, error_class, error_code)


def build_pdu(pdu: S7Pdu) -> bytes:
    if has_error_fields(pdu.rosctr):
        header = _HEADER_12.pack(PROTOCOL_ID, pdu.rosctr, 0, pdu.pdu_ref, len(pdu.parameter),
                                 len(pdu.data), pdu.error_class, pdu.error_code)
    else:
        header = _HEADER_10.pack(PROTOCOL_ID, pdu.rosctr, 0, pdu.pdu_ref, len(pdu.parameter),
                                 len(pdu.data))
    return header + pdu.parameter + pdu.data


# ---------------------------------------------------------------- setup communication
def parse_setup_communication(parameter: bytes) -> SetupCommunication:
    if len(parameter) != _SETUP.size or parameter[0] != Function.SETUP_COMMUNICATION:
        raise NckProtocolError("setup communication parameter must be 8 bytes starting with 0xF0")
    _function, _reserved, calling, called, pdu_length = _SETUP.unpack_from(parameter)
    return SetupCommunication(calling, called, pdu_length)


def build_setup_communication(setup: SetupCommunication) -> bytes:
    return _SETUP.pack(Function.SETUP_COMMUNICATION, 0, setup.max_amq_calling, setup.max_amq_called,
                       setup.pdu_length)


# ---------------------------------------------------------------- items
def _parse_item(parameter: bytes, offset: int) -> tuple[Address, int]:
    if offset + 2 > len(parameter):
        raise NckTruncatedError("item header cut short")
    var_spec, length = parameter[offset], parameter[offset + 1]
    end = offset + 2 + length
    if end > len(parameter):
        raise NckTruncatedError(f"item announces {length} bytes beyond the parameter")
    if length == 0:
        raise NckProtocolError("item with an empty address specification")
    syntax_id = parameter[offset + 2]
    if var_spec == VAR_SPEC and syntax_id == SyntaxId.S7ANY and length == 10:
        _v, _l, _s, transport_size, count, db_number, area, address_high, address_low = \
            _S7ANY.unpack_from(parameter, offset)
        address = (address_high << 16) | address_low
        return S7AnyAddress(transport_size, count, db_number, area, address >> 3, address & 7), end
    if var_spec == VAR_SPEC and syntax_id in NCK_SYNTAX_IDS and length == 8:
        _v, _l, syntax, area_unit, column, line, module, line_count = _NCK.unpack_from(parameter, offset)
        return NckAddress.from_wire(syntax, area_unit, column, line, module, line_count), end
    return UnsupportedAddress(var_spec, syntax_id, parameter[offset + 2:end]), end


def build_item(address: Address) -> bytes:
    if isinstance(address, NckAddress):
        return _NCK.pack(VAR_SPEC, 8, address.syntax_id, address.area_unit, address.column,
                         address.line, address.module, address.line_count)
    if isinstance(address, S7AnyAddress):
        bit_address = (address.byte_address << 3) | address.bit_address
        return _S7ANY.pack(VAR_SPEC, 10, SyntaxId.S7ANY, address.transport_size, address.count,
                           address.db_number, address.area, bit_address >> 16, bit_address & 0xFFFF)
    if isinstance(address, UnsupportedAddress):
        if not address.raw or len(address.raw) > 255:
            raise NckProtocolError("an unsupported item needs 1..255 bytes of address specification")
        return bytes([address.var_spec, len(address.raw)]) + address.raw
    raise TypeError(f"not an item address: {address!r}")


def _parse_items(parameter: bytes, function: int) -> tuple[Address, ...]:
    if len(parameter) < 2 or parameter[0] != function:
        raise NckProtocolError(f"parameter does not start with function 0x{function:02X}")
    count = parameter[1]
    if count == 0:
        raise NckProtocolError("a read/write job with no items")
    return parse_items_to_end(parameter, 2, count)


def parse_items_to_end(data: bytes, offset: int, count: int) -> tuple[Address, ...]:
    """``count`` item addresses from ``offset`` to the end of ``data`` (a fill byte after each odd-length
    item but the last): read and write jobs, cyclic subscriptions."""
    items: list[Address] = []
    for index in range(count):
        start = offset
        item, offset = _parse_item(data, offset)
        items.append(item)
        if index < count - 1 and (offset - start) % 2:
            offset += 1  # fill byte after an odd-length item
    if offset != len(data):
        raise NckProtocolError(f"{len(data) - offset} bytes after the last of {count} items")
    return tuple(items)


def _build_items(function: int, items: tuple[Address, ...]) -> bytes:
    if not 1 <= len(items) <= 255:
        raise NckProtocolError(f"{len(items)} items: a job carries 1..255")
    return bytes([function, len(items)]) + build_items(items)


def build_items(items: tuple[Address, ...]) -> bytes:
    """Item addresses one after the other, a fill byte after each odd-length one but the last."""
    parts = []
    last = len(items) - 1
    for index, item in enumerate(items):
        encoded = build_item(item)
        parts.append(encoded)
        if index < last and len(encoded) % 2:
            parts.append(b"\x00")
    return b"".join(parts)


def data_item_length_field(item: DataItem) -> int:
    if item.transport_size in BIT_LENGTH_TRANSPORT_SIZES:
        if item.transport_size == 0x03:
            return len(item.data)  # BIT: one bit per byte sent
        return len(item.data) * 8
    return len(item.data)


def _parse_data_items(data: bytes, count: int) -> tuple[DataItem, ...]:
    items, offset = parse_data_items_at(data, 0, count)
    if offset != len(data):
        raise NckProtocolError(f"{len(data) - offset} bytes after the last of {count} data items")
    return items


def parse_data_items_at(data: bytes, offset: int, count: int) -> tuple[tuple[DataItem, ...], int]:
    """``count`` data items from ``offset`` on (fill bytes between them, none after the last) and where
    they end: read answers, and the associated values of alarm messages and cyclic data, which more
    fields may follow."""
    items: list[DataItem] = []
    for index in range(count):
        if offset + 4 > len(data):
            raise NckTruncatedError(f"data item {index + 1} of {count} cut short")
        return_code, transport_size, length = _DATA_HEADER.unpack_from(data, offset)
        offset += 4
        if return_code not in DATA_RETURN_CODES:
            size = 0  # an error item: no data follows, whatever its length says
        elif transport_size in BIT_LENGTH_TRANSPORT_SIZES:
            size = length if transport_size == 0x03 else (length + 7) // 8
        else:
            size = length
        if offset + size > len(data):
            raise NckTruncatedError(f"data item {index + 1} announces {size} bytes beyond the data")
        items.append(DataItem(return_code, transport_size, data[offset:offset + size]))
        offset += size
        if index < count - 1 and size % 2:
            if offset >= len(data):
                raise NckTruncatedError(f"fill byte after data item {index + 1} missing")
            offset += 1
    return tuple(items), offset


def build_data_items(items: tuple[DataItem, ...]) -> bytes:
    parts: list[bytes] = []
    last = len(items) - 1
    for index, item in enumerate(items):
        length = data_item_length_field(item)
        if length > 0xFFFF:
            raise NckProtocolError(f"data item {index + 1} too long ({len(item.data)} bytes)")
        parts.append(_DATA_HEADER.pack(item.return_code, item.transport_size, length))
        parts.append(item.data)
        if index < last and len(item.data) % 2:
            parts.append(b"\x00")
    return b"".join(parts)


# ---------------------------------------------------------------- read var
def parse_read_var_request(parameter: bytes) -> ReadVarRequest:
    return ReadVarRequest(_parse_items(parameter, Function.READ_VAR))


def build_read_var_request(request: ReadVarRequest) -> bytes:
    return _build_items(Function.READ_VAR, request.items)


def build_read_var_response(response: ReadVarResponse) -> tuple[bytes, bytes]:
    return bytes([Function.READ_VAR, len(response.items)]), build_data_items(response.items)


def parse_read_var_response(parameter: bytes, data: bytes) -> ReadVarResponse:
    if len(parameter) != 2 or parameter[0] != Function.READ_VAR:
        raise NckProtocolError("read var answer parameter must be 04 <count>")
    return ReadVarResponse(_parse_data_items(data, parameter[1]))


# Whole PDUs on the hot path (server answers to polled reads, trace decoding): the header is checked
# byte by byte in place instead of building an S7Pdu; both are tested against the general path.
_READ_ANSWER_HEAD = struct.Struct(">BBHHHHBBBB")  # ACK_DATA header, no error, then 04 <count>
# Plain ints: comparing a byte with an IntEnum member costs several times more.
_JOB = int(Rosctr.JOB)
_READ_VAR = int(Function.READ_VAR)
_ACK_DATA = int(Rosctr.ACK_DATA)


def peek_read_var_job(buffer: bytes, offset: int = 0) -> tuple[int, bytes] | None:
    """(PDU reference, parameter) of a read-var job PDU at ``buffer[offset:]`` that has no data part
    and whose lengths add up; None for anything else (the general path then parses it)."""
    if len(buffer) - offset < 12 or buffer[offset] != PROTOCOL_ID or buffer[offset + 1] != _JOB \
            or buffer[offset + 10] != _READ_VAR or buffer[offset + 8] or buffer[offset + 9] \
            or (buffer[offset + 6] << 8 | buffer[offset + 7]) != len(buffer) - offset - 10:
        return None
    return buffer[offset + 4] << 8 | buffer[offset + 5], buffer[offset + 10:]


def peek_read_var_answer(pdu: bytes) -> int | None:
    """The item count of an error-free read-var answer PDU whose lengths add up, else None; its data
    items start at ``READ_ANSWER_DATA_OFFSET``."""
    if len(pdu) < READ_ANSWER_DATA_OFFSET or pdu[10] or pdu[11] or (pdu[6] << 8 | pdu[7]) != 2 \
            or len(pdu) != READ_ANSWER_DATA_OFFSET + (pdu[8] << 8 | pdu[9]) or pdu[12] != _READ_VAR:
        return None
    return pdu[13]


READ_ANSWER_DATA_OFFSET = _READ_ANSWER_HEAD.size


def build_read_var_answer(pdu_ref: int, item_count: int, data: bytes) -> bytes:
    """The ACK_DATA PDU answering a read-var job, around already built data items."""
    return _READ_ANSWER_HEAD.pack(PROTOCOL_ID, _ACK_DATA, 0, pdu_ref, 2, len(data), 0, 0,
                                  _READ_VAR, item_count) + data


# ---------------------------------------------------------------- write var
def parse_write_var_request(parameter: bytes, data: bytes) -> WriteVarRequest:
    items = _parse_items(parameter, Function.WRITE_VAR)
    return WriteVarRequest(items, _parse_data_items(data, len(items)))


def build_write_var_request(request: WriteVarRequest) -> tuple[bytes, bytes]:
    if len(request.items) != len(request.values):
        raise NckProtocolError(f"{len(request.items)} items but {len(request.values)} values")
    return _build_items(Function.WRITE_VAR, request.items), build_data_items(request.values)


def build_write_var_response(response: WriteVarResponse) -> tuple[bytes, bytes]:
    return bytes([Function.WRITE_VAR, len(response.return_codes)]), bytes(response.return_codes)


def parse_write_var_response(parameter: bytes, data: bytes) -> WriteVarResponse:
    if len(parameter) != 2 or parameter[0] != Function.WRITE_VAR:
        raise NckProtocolError("write var answer parameter must be 05 <count>")
    if len(data) != parameter[1]:
        raise NckProtocolError(f"write var answer: {parameter[1]} items but {len(data)} return codes")
    return WriteVarResponse(tuple(data))
