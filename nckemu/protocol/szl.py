"""Userdata (ROSCTR 7): CPU functions (read SZL), block functions (list blocks), time (read clock).

Request parameter ``00 01 12 04 11 44 01 00`` (head, length 4, method request, type request and
group 4 "CPU functions", subfunction 1 "read SZL", sequence); data ``FF 09 00 04`` + SZL ID + index.
Answer parameter ``00 01 12 08 12 84 01 <seq> 00 00 <error code>``; data ``FF 09 len`` + the SZL
(ID, index, record length, record count, records), or ``0A 00 00 00`` with an error code.

Every other group answers in the same form, ``12 8<group> <subfunction>`` in the parameter; an
error travels in the parameter's last two bytes with data ``0A 00 00 00`` (C snap7's
``SZLNotAvailable`` answer; python-snap7 3.3's client reads the error from parameter bytes 10-11;
tshark 4.0 decodes group 7 and group 3 answers of this form without "malformed": notes/catalogue.md
section 5 (a)).
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime

from . import alarms, userdata
from .errors import NckProtocolError, NckServiceError, NckTruncatedError
from .userdata import METHOD_REQUEST, METHOD_RESPONSE, TYPE_PUSH, TYPE_REQUEST, TYPE_RESPONSE

GROUP_BLOCK_FUNCTIONS = userdata.GROUP_BLOCK
GROUP_CPU_FUNCTIONS = userdata.GROUP_CPU
GROUP_TIME_FUNCTIONS = userdata.GROUP_TIME
SUBFUNCTION_READ_SZL = 0x01
SUBFUNCTION_LIST_BLOCKS = 0x01
SUBFUNCTION_READ_CLOCK = 0x01
# Userdata error codes for an SZL the CPU does not have. Wireshark 4.0 gives both the text
# "Information function unavailable"; its 2015 plugin named 0xD401 "invalid SZL ID" and 0xD402
# "invalid index"; C snap7 answers 0xD402 for every SZL it lacks (notes/catalogue.md 5 (b)).
ERROR_SZL_NOT_AVAILABLE = 0xD401
ERROR_SZL_INVALID_INDEX = 0xD402
# Data part of every userdata error answer: return code 0x0A "object does not exist", no data.
ERROR_DATA = b"\x0A\x00\x00\x00"
# Block types of the "list blocks" answer, in the order S7 CPUs and C snap7 list them: OB, DB, SDB,
# FC, SFC, FB, SFB (python-snap7 3.3 requires exactly these seven entries, 28 bytes). Each entry's
# type is two ASCII characters, "0" and these codes ("0A" = DB, as in block names: protocol/blocks.py).
BLOCK_TYPES = (0x38, 0x41, 0x42, 0x43, 0x44, 0x45, 0x46)
BLOCK_TYPE_DB = 0x41


@dataclass(frozen=True, slots=True)
class UserdataRequest:
    """A userdata request of any group: the dispatcher picks the service by group and subfunction."""

    group: int
    subfunction: int
    sequence_number: int = 0
    data: bytes = b""


def parse_userdata_request(parameter: bytes, data: bytes) -> UserdataRequest:
    head = userdata.parse_userdata_parameter(parameter)
    # pyS7 (0.x) sends its SZL reads with type 0 ("push") and the request method; it works against
    # real CPUs, which go by the method, so we do too.
    if head.method != METHOD_REQUEST or head.type not in (TYPE_REQUEST, TYPE_PUSH):
        raise NckProtocolError("userdata is not a request")
    return UserdataRequest(head.group, head.subfunction, head.sequence, data)


def build_userdata_response(request: UserdataRequest, data: bytes, error_code: int = 0
                            ) -> tuple[bytes, bytes]:
    """Answer parameter ``00 01 12 08 12 8<group> <subfunction> <seq> 00 00 <error>`` and ``data``."""
    parameter = userdata.build_userdata_parameter(userdata.UserdataParameter(
        METHOD_RESPONSE, TYPE_RESPONSE, request.group, request.subfunction, request.sequence_number & 0xFF,
        long=True, error_code=error_code))
    return parameter, data


# Bytes around each part of an answer in several PDUs: S7 header (10), long parameter (12), data header (4).
PART_OVERHEAD = 10 + 12 + 4


def is_next_part_request(head: userdata.UserdataParameter) -> bool:
    """The client's request for the next part of a long answer: method 0x12 with type request and the
    8-byte parameter carrying the answer's sequence number (python-snap7 3.3's
    ``build_userdata_followup_request``; the two-part SZL of icsnpp-s7comm's snap7.pcap)."""
    return head.method == METHOD_RESPONSE and head.type == TYPE_REQUEST and head.long


def split_userdata_answer(group: int, subfunction: int, data: bytes, room: int, sequence: int
                          ) -> list[tuple[bytes, bytes]]:
    """One userdata answer's data part (``FF 09 len`` + payload) as parameter/data pairs of at most
    ``room`` payload bytes each: every part but the last says "last data unit: no" (1) and all carry
    ``sequence`` (as sequence number and data unit reference), which the client's next-part requests
    name. A CPU answers a long SZL so (snap7.pcap: sequence 2, last data unit 1, then 0)."""
    if len(data) < 4 or room <= 0:
        raise NckProtocolError("userdata answer to split has no data header or no room")
    return_code, transport_size = data[0], data[1]
    payload = data[4:]
    chunks = [payload[offset:offset + room] for offset in range(0, len(payload), room)] or [b""]
    parts = []
    for index, chunk in enumerate(chunks):
        more = index < len(chunks) - 1
        parameter = userdata.build_userdata_parameter(userdata.UserdataParameter(
            METHOD_RESPONSE, TYPE_RESPONSE, group, subfunction, sequence & 0xFF, long=True,
            data_unit_ref=sequence & 0xFF, last_data_unit=1 if more else 0))
        parts.append((parameter, struct.pack(">BBH", return_code, transport_size, len(chunk)) + chunk))
    return parts


def build_userdata_error_response(request: UserdataRequest, error_code: int) -> tuple[bytes, bytes]:
    return build_userdata_response(request, ERROR_DATA, error_code)


def build_block_counts(counts: Mapping[int, int]) -> bytes:
    """Data of the "list blocks" answer: ``FF 09 00 1C`` + ``30 <type> <count>`` for the seven types."""
    entries = b"".join(struct.pack(">BBH", 0x30, block_type, min(counts.get(block_type, 0), 0xFFFF))
                       for block_type in BLOCK_TYPES)
    return struct.pack(">BBH", 0xFF, 0x09, len(entries)) + entries


def parse_block_counts(data: bytes) -> dict[int, int]:
    if len(data) < 4 or data[0] != 0xFF:
        raise NckProtocolError("block list answer without return code 0xFF")
    (length,) = struct.unpack_from(">H", data, 2)
    body = data[4:4 + length]
    if len(body) != length or length % 4:
        raise NckTruncatedError("block list shorter than announced or not in 4-byte entries")
    return {body[i + 1]: int.from_bytes(body[i + 2:i + 4], "big") for i in range(0, length, 4)}


def _bcd(value: int) -> int:
    return (value // 10) << 4 | value % 10


def _from_bcd(value: int) -> int:
    high, low = value >> 4, value & 0x0F
    if high > 9 or low > 9:
        raise NckProtocolError(f"0x{value:02X} is not BCD")
    return high * 10 + low


def build_clock(moment: datetime) -> bytes:
    """Data of the "read clock" answer: ``FF 09 00 0A`` + reserved, century, year, month, day, hour,
    minute, second (BCD), milliseconds as three BCD digits and the weekday (1 = Sunday) in the low
    nibble of the last byte (the S7 clock format; python-snap7 3.3's ``parse_get_clock_response``)."""
    milliseconds = moment.microsecond // 1000
    weekday = (moment.isoweekday() % 7) + 1  # ISO Monday 1 .. Sunday 7 -> S7 Sunday 1 .. Saturday 7
    clock = bytes([0x00, _bcd(moment.year // 100), _bcd(moment.year % 100), _bcd(moment.month),
                   _bcd(moment.day), _bcd(moment.hour), _bcd(moment.minute), _bcd(moment.second),
                   _bcd(milliseconds // 10), (milliseconds % 10) << 4 | weekday])
    return struct.pack(">BBH", 0xFF, 0x09, len(clock)) + clock


def clock_year(century_byte: int, year_byte: int) -> int:
    """The year of an S7 clock: the BCD year byte alone, 90..99 as 1990.., 00..89 as 2000..2089 (the
    DATE_AND_TIME range). The byte before it is not a century: S7-300 CPUs send 0x19 there in 2014
    and 2016 (``iti/s7comm_reading_setting_plc_time.pcap``, ``iti/snap7_s300_everything.pcapng``), and
    Wireshark's s7comm dissector ignores it too ("first byte of BCD coded year, should be ignored")."""
    del century_byte
    year = _from_bcd(year_byte)
    return year + (1900 if year >= 90 else 2000)


def parse_clock(data: bytes) -> datetime:
    if len(data) < 14 or data[0] != 0xFF or data[3] != 10:
        raise NckProtocolError("read clock answer is not FF 09 00 0A + 10 bytes")
    c = data[4:14]
    year = clock_year(c[1], c[2])
    milliseconds = _from_bcd(c[8]) * 10 + (c[9] >> 4)
    return datetime(year, _from_bcd(c[3]), _from_bcd(c[4]), _from_bcd(c[5]), _from_bcd(c[6]),
                    _from_bcd(c[7]), milliseconds * 1000)


@dataclass(frozen=True, slots=True)
class SzlReadRequest:
    szl_id: int
    szl_index: int
    sequence_number: int = 0


@dataclass(frozen=True, slots=True)
class SzlReadResponse:
    szl_id: int
    szl_index: int
    payload: bytes  # record length, record count and the records
    error_code: int = 0
    sequence_number: int = 0


def parse_szl_request(parameter: bytes, data: bytes) -> SzlReadRequest:
    request = parse_userdata_request(parameter, data)
    if request.group != GROUP_CPU_FUNCTIONS or request.subfunction != SUBFUNCTION_READ_SZL:
        raise NckServiceError(f"userdata group {request.group} subfunction {request.subfunction} not served",
                              error_class=0x81, error_code=0x04)
    return szl_request_of(request)


def szl_request_of(request: UserdataRequest) -> SzlReadRequest:
    """The SZL ID and index of a group 4 / subfunction 1 request."""
    if len(request.data) < 8:
        raise NckTruncatedError("SZL request data shorter than 8 bytes")
    szl_id, szl_index = struct.unpack_from(">HH", request.data, 4)
    return SzlReadRequest(szl_id, szl_index, request.sequence_number)


def build_szl_request(request: SzlReadRequest) -> tuple[bytes, bytes]:
    parameter = bytes([0x00, 0x01, 0x12, 0x04, METHOD_REQUEST, (TYPE_REQUEST << 4) | GROUP_CPU_FUNCTIONS,
                       SUBFUNCTION_READ_SZL, request.sequence_number & 0xFF])
    return parameter, struct.pack(">BBHHH", 0xFF, 0x09, 4, request.szl_id, request.szl_index)


def _response_parameter(sequence: int, error_code: int) -> bytes:
    request = UserdataRequest(GROUP_CPU_FUNCTIONS, SUBFUNCTION_READ_SZL, sequence)
    return build_userdata_response(request, b"", error_code)[0]


def build_szl_response(request: SzlReadRequest, szl: bytes) -> tuple[bytes, bytes]:
    """``szl`` is the whole list: ID, index, record length, record count and the records."""
    if len(szl) > 0xFFFF:
        raise NckProtocolError("SZL answer too long")
    return _response_parameter(request.sequence_number, 0), struct.pack(">BBH", 0xFF, 0x09, len(szl)) + szl


def build_szl_error_response(request: SzlReadRequest, error_code: int = ERROR_SZL_NOT_AVAILABLE
                             ) -> tuple[bytes, bytes]:
    return _response_parameter(request.sequence_number, error_code), b"\x0A\x00\x00\x00"


def parse_szl_response(parameter: bytes, data: bytes) -> SzlReadResponse:
    if len(parameter) < 12 or parameter[:3] != b"\x00\x01\x12":
        raise NckProtocolError("userdata answer parameter head is not 00 01 12")
    (error_code,) = struct.unpack_from(">H", parameter, 10)
    if len(data) < 4:
        raise NckTruncatedError("SZL answer data shorter than 4 bytes")
    _rc, _ts, length = struct.unpack_from(">BBH", data)
    body = data[4:4 + length]
    if len(body) != length:
        raise NckTruncatedError("SZL answer shorter than announced")
    if error_code or length < 4:
        return SzlReadResponse(0, 0, b"", error_code, parameter[7])
    szl_id, szl_index = struct.unpack_from(">HH", body)
    return SzlReadResponse(szl_id, szl_index, body[4:], 0, parameter[7])


# ---------------------------------------------------------------- SZL records by name (trace show)
SZL_NAMES = {0x0000: "all SZL IDs", 0x0011: "module identification", 0x0111: "module identification (one record)",
             0x001C: "component identification", 0x011C: "component identification (one record)",
             0x0131: "communication capability", 0x0132: "communication status", 0x0232: "protection level",
             0x0424: "current mode", 0x00A0: "diagnostic buffer"}
# SZL 0x0424 "bzu_id": the requested mode in the low nibble, the previous one in the high nibble; the
# names tshark 4.0.17 gives them (read off its decoding of every value).
CPU_MODES = {0x1: "STOP (update)", 0x2: "STOP (memory reset)", 0x3: "STOP (self initialization)",
             0x4: "STOP (internal)", 0x5: "Startup (complete restart)", 0x7: "Restart", 0x8: "RUN", 0xA: "HOLD",
             0xD: "DEFECT"}


@dataclass(frozen=True, slots=True)
class SzlList:
    """An SZL as the answer carries it: ID, index, record length and the records."""

    szl_id: int
    szl_index: int
    record_length: int
    records: tuple[bytes, ...]

    @property
    def name(self) -> str:
        return SZL_NAMES.get(self.szl_id, f"SZL 0x{self.szl_id:04X}")


def parse_szl_list(body: bytes) -> SzlList:
    """The body of an SZL answer (after return code, transport size, length): ID, index, record length,
    record count, records. A list announced longer than carried (the first part of a long answer) keeps
    the whole records there are."""
    if len(body) < 8:
        raise NckTruncatedError("SZL shorter than its 8-byte header")
    szl_id, szl_index, record_length, count = struct.unpack_from(">HHHH", body)
    if record_length == 0 and count:
        raise NckProtocolError(f"SZL 0x{szl_id:04X} announces {count} records of 0 bytes")
    whole = min(count, (len(body) - 8) // record_length) if record_length else 0
    if whole == count and 8 + count * record_length != len(body):
        raise NckProtocolError(f"SZL 0x{szl_id:04X}: {len(body) - 8} bytes for {count} records of {record_length}")
    records = tuple(body[8 + i * record_length:8 + (i + 1) * record_length] for i in range(whole))
    return SzlList(szl_id, szl_index, record_length, records)


def build_szl_list(szl_list: SzlList) -> bytes:
    if any(len(record) != szl_list.record_length for record in szl_list.records):
        raise NckProtocolError("every SZL record has the list's record length")
    return struct.pack(">HHHH", szl_list.szl_id, szl_list.szl_index, szl_list.record_length,
                       len(szl_list.records)) + b"".join(szl_list.records)


def _ascii(raw: bytes) -> str:
    return raw.split(b"\x00", 1)[0].decode("ascii", "replace").strip()


def describe_szl_record(szl_id: int, record: bytes) -> str:
    """One record by name, for the SZL IDs the emulator serves (0x0011, 0x001C, 0x0131, 0x0232, 0x0424)
    and the list of IDs (0x0000); other records as hex."""
    kind = szl_id & 0x00FF
    try:
        if szl_id == 0x0000 and len(record) == 2:
            return f"0x{int.from_bytes(record, 'big'):04X}"
        if kind == 0x11 and len(record) == 28:
            index, order = int.from_bytes(record[:2], "big"), _ascii(record[2:22])
            module_type, version1, version2 = struct.unpack_from(">HHH", record, 22)
            return f"index {index}: {order!r} type 0x{module_type:04X} versions 0x{version1:04X} 0x{version2:04X}"
        if kind == 0x1C and len(record) == 34:
            return f"index {int.from_bytes(record[:2], 'big')}: {_ascii(record[2:])!r}"
        if kind == 0x24 and len(record) == 20:
            event_id, _ae, modes = struct.unpack_from(">HBB", record)
            requested, previous = modes & 0x0F, modes >> 4
            return (f"event 0x{event_id:04X} mode {CPU_MODES.get(requested, f'unknown (0x{requested:X})')}, "
                    f"previously {CPU_MODES.get(previous, f'unknown (0x{previous:X})')}")
        if kind == 0xA0 and len(record) == alarms.DIAGNOSTIC_LENGTH:
            return alarms.describe_diagnostic_message(alarms.parse_diagnostic_message(record))
        if szl_id == 0x0131 and len(record) == 40 and record[:2] == b"\x00\x01":
            pdu, connections, mpi_bps, bus_bps = struct.unpack_from(">HHII", record, 2)
            return f"index 1: max PDU {pdu}, {connections} connections, MPI {mpi_bps} bit/s, K-bus {bus_bps} bit/s"
        if szl_id == 0x0232 and len(record) == 40 and record[:2] == b"\x00\x04":
            key, password, effective, switch = struct.unpack_from(">HHHH", record, 2)
            return (f"index 4: protection key switch {key}, password {password}, effective {effective}, "
                    f"mode switch {switch}")
    except (struct.error, UnicodeDecodeError, NckProtocolError):
        pass
    return record.hex()


def describe_szl_list(szl_list: SzlList, *, complete: bool = True) -> str:
    """``module identification (SZL 0x0011 index 0x0000): 3 records: index 1: '6ES7 ...' ...``."""
    head = f"{szl_list.name} (SZL 0x{szl_list.szl_id:04X} index 0x{szl_list.szl_index:04X})"
    count = len(szl_list.records)
    records = "; ".join(describe_szl_record(szl_list.szl_id, r) for r in szl_list.records)
    text = f"{head}: {count} record{'s' if count != 1 else ''}"
    if not complete:
        text += " in this part"
    return f"{text}: {records}" if records else text


# ---------------------------------------------------------------- block lists by name
BLOCK_TYPE_NAMES = {0x38: "OB", 0x41: "DB", 0x42: "SDB", 0x43: "FC", 0x44: "SFC", 0x45: "FB", 0x46: "SFB"}


def describe_block_counts(counts: Mapping[int, int]) -> str:
    """``OB 1, DB 2, SDB 0, ...`` from the "list blocks" answer."""
    return ", ".join(f"{BLOCK_TYPE_NAMES.get(t, f'type 0x{t:02X}')} {n}" for t, n in counts.items())


@dataclass(frozen=True, slots=True)
class BlockEntry:
    """One block of the "list blocks of type" answer: number, flags, language."""

    number: int
    flags: int
    language: int


def parse_blocks_of_type(body: bytes) -> tuple[BlockEntry, ...]:
    """The body of a "list blocks of type" answer (after return code, transport size, length)."""
    if len(body) % 4:
        raise NckProtocolError(f"block list of {len(body)} bytes, not whole 4-byte entries")
    return tuple(BlockEntry(*struct.unpack_from(">HBB", body, offset)) for offset in range(0, len(body), 4))


def build_blocks_of_type(entries: tuple[BlockEntry, ...]) -> bytes:
    return b"".join(struct.pack(">HBB", e.number, e.flags, e.language) for e in entries)


def block_type_of_request(body: bytes) -> str | None:
    """The block type a "list blocks of type" request asks for (``30 41`` = DB), by name."""
    if len(body) != 2 or body[0] != 0x30:
        return None
    return BLOCK_TYPE_NAMES.get(body[1], f"type 0x{body[1]:02X}")
