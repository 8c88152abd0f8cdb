"""Job/answer pairs of a capture, each item by variable name, return codes in words."""

from __future__ import annotations

import functools
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from nckemu.catalogue.table import display_name, spec_at
from nckemu.errors import NckError, ReturnCode
from nckemu.protocol import blocks, cyclic, ncprog, pi, s7, szl, userdata
from nckemu.protocol.addresses import NckAddress, NckArea, NckType, S7AnyAddress, UnsupportedAddress
from nckemu.protocol.codes import (
    RETURN_CODE_TEXTS,
    describe_header_error,
    describe_module,
    describe_service_header_error,
)
from nckemu.protocol.values import decode_nck_values, nck_value_format, nck_value_reader

from .contents import PUSH as PUSH_STAGE
from .contents import REQUEST, RESPONSE, Contents, UserdataState, userdata_contents
from .reader import Capture, Gap, TracePdu, collector_paused

FUNCTION_NAMES = {0x04: "read", 0x05: "write", 0x28: "PI", 0x29: "PLC stop", 0xF0: "setup", 0x00: "CPU services",
                  0x1A: "request download", 0x1B: "download block", 0x1C: "download ended", 0x1D: "start upload",
                  0x1E: "upload", 0x1F: "end upload"}
# The functions as tshark names them (Wireshark's s7comm dissector, ``param_functionnames``).
SERVICE_NAMES = {0x04: "Read Var", 0x05: "Write Var", 0x28: "PI-Service", 0x29: "PLC Stop", 0xF0: "Setup communication",
                 0x00: "CPU services", 0x1A: "Request download", 0x1B: "Download block", 0x1C: "Download ended",
                 0x1D: "Start upload", 0x1E: "Upload", 0x1F: "End upload"}
_SERVICE_BY_FUNCTION = {FUNCTION_NAMES[code]: name for code, name in SERVICE_NAMES.items()}
PUSH = "push"
S7COMM_PLUS = "S7comm-plus"
_S7COMM_PLUS_ID = 0x72
S7_AREA_NAMES = {0x84: "DB", 0x81: "I", 0x82: "Q", 0x83: "M", 0x80: "P", 0x1C: "C", 0x1D: "T"}
# S7ANY transport sizes (the item's type) as Wireshark's s7comm dissector defines them: name, bytes per
# element, and the S7 letter of that width (M102.3, MB100, MW100, MD300; DB5.DBX0.1, DB5.DBB0 ...).
S7_TRANSPORT_SIZES: dict[int, tuple[str, int, str]] = {
    0x01: ("BIT", 1, "X"), 0x02: ("BYTE", 1, "B"), 0x03: ("CHAR", 1, "B"), 0x04: ("WORD", 2, "W"),
    0x05: ("INT", 2, "W"), 0x06: ("DWORD", 4, "D"), 0x07: ("DINT", 4, "D"), 0x08: ("REAL", 4, "D"),
    0x09: ("DATE", 2, "W"), 0x0A: ("TOD", 4, "D"), 0x0B: ("TIME", 4, "D"), 0x0C: ("S5TIME", 2, "W"),
    0x0F: ("DATE_AND_TIME", 8, "B"), 0x1C: ("COUNTER", 2, ""), 0x1D: ("TIMER", 2, ""),
    0x1E: ("IEC COUNTER", 1, "B"), 0x1F: ("IEC TIMER", 1, "B"), 0x20: ("HS COUNTER", 1, "B"),
}
# Values of one element, big-endian as S7 sends them (struct codes); BIT is one byte 0 or 1.
_S7_VALUE_CODES = {0x01: "B", 0x02: "B", 0x04: "H", 0x05: "h", 0x06: "I", 0x07: "i", 0x08: "f"}
_S7_DB_AREAS = {0x84: "DB", 0x85: "DI"}


def s7any_name(address: S7AnyAddress) -> str:
    """An S7ANY item as S7 tools write it: ``M102.3`` (a bit), ``MB100``, ``MW100``, ``MD300 REAL``,
    ``DB5.DBX0.1``, ``DB3.DBD4 REAL``, ``PIW420``, ``C5``, ``T3``; the type where the width does not say
    it (BYTE, WORD, DWORD and BIT go without), `` xN`` for N elements. The same fields as tshark's
    ``(M 102.3 BIT 1)``: area, DB, byte, bit, transport size and count."""
    kind, _size, width = S7_TRANSPORT_SIZES.get(address.transport_size, (f"ts 0x{address.transport_size:02X}", 1, "B"))
    count = f" x{address.count}" if address.count != 1 else ""
    if address.area in (0x1C, 0x1D):  # counters and timers: a number, not a byte address
        typed = "" if kind == ("COUNTER" if address.area == 0x1C else "TIMER") else f" {kind}"
        return f"{S7_AREA_NAMES[address.area]}{address.byte_address << 3 | address.bit_address}{typed}{count}"
    db_area = _S7_DB_AREAS.get(address.area)
    if db_area is not None:
        prefix, area = f"{db_area}{address.db_number}.", db_area
    else:
        prefix, area = "", S7_AREA_NAMES.get(address.area, f"area 0x{address.area:02X} ")
        if area == "P":
            area = "PI"  # direct peripheral access: PIW420 as read (a write names PQ)
    if width == "X":
        where = f"{prefix}{area if not db_area else area + 'X'}{address.byte_address}.{address.bit_address}"
    else:
        where = f"{prefix}{area}{width}{address.byte_address}"
        if address.bit_address:
            where += f".{address.bit_address}"  # not on a byte boundary: say so, as tshark does
    typed = "" if kind in ("BIT", "BYTE", "WORD", "DWORD") else f" {kind}"
    return f"{where}{typed}{count}"


def s7any_value(address: S7AnyAddress, data: bytes) -> Any:
    """The value of an S7ANY item by its transport size (a list for several elements), None for the
    types shown as bytes."""
    code = _S7_VALUE_CODES.get(address.transport_size)
    if code is None or not data:
        return None
    size = struct.calcsize(code)
    if len(data) != size * address.count:
        return None
    values = list(struct.unpack(f">{address.count}{code}", data))
    return values[0] if address.count == 1 else values


@dataclass(slots=True)
class Item:
    target: object   # the parsed item address
    name: str
    return_code: int | None = None
    value: Any = None
    raw: str = ""
    data_transport_size: int | None = None  # the answer's (or write job's) data item transport size

    @property
    def address(self) -> dict[str, Any]:
        return _address_json(self.target)

    def to_json(self) -> dict[str, Any]:
        return {**self.address, "name": self.name, "return_code": self.return_code,
                "return_text": RETURN_CODE_TEXTS.get(self.return_code, "") if self.return_code is not None else None,
                "value": self.value, "raw": self.raw, "data_transport_size": self.data_transport_size}


@dataclass(slots=True)
class Exchange:
    """A job and its answer (None when the answer is missing), a push (``function`` "push": userdata a
    CPU sends on its own, never answered), or a connection's S7comm-plus frames (not decoded). Jobs
    are what ROSCTR says they are, from either side: in a block download the PLC sends the jobs."""

    connection: int
    job: TracePdu
    answer: TracePdu | None
    function: str
    pdu_ref: int
    items: list[Item] = field(default_factory=list)
    detail: str = ""
    header_error: str = ""
    read_job: _ReadJob | None = field(default=None, repr=False, compare=False)  # a cached read job's decoders
    service: str = ""  # the function as tshark names it, where ``function`` does not say it
    # An NC transfer telegram's fields by tshark's names (``_NcTransfers``), of the job and of the answer.
    nc: dict[str, Any] = field(default_factory=dict)
    nc_answer: dict[str, Any] = field(default_factory=dict)

    @property
    def service_name(self) -> str:
        """The function, userdata group and subfunction as tshark names them."""
        return self.service or _SERVICE_BY_FUNCTION.get(self.function, self.function)

    def to_json(self) -> dict[str, Any]:
        return {"frame": self.job.frame, "answer_frame": self.answer.frame if self.answer else None,
                "time_s": self.job.time_s, "connection": self.connection, "function": self.function,
                "service": self.service_name, "sender": "client" if self.job.from_client else "server",
                "pdu_ref": self.pdu_ref, "detail": self.detail, "header_error": self.header_error or None,
                "items": [i.to_json() for i in self.items],
                **({"nc": self.nc, "nc_answer": self.nc_answer} if self.nc or self.nc_answer else {})}


def _address_json(address: object) -> dict[str, Any]:
    if isinstance(address, NckAddress):
        return {"kind": "nck", "syntax_id": address.syntax_id, "area": address.area, "unit": address.unit,
                "column": address.column, "line": address.line, "module": address.module,
                "line_count": address.line_count}
    if isinstance(address, S7AnyAddress):
        return {"kind": "s7any", "area": address.area, "db": address.db_number, "byte": address.byte_address,
                "bit": address.bit_address, "transport_size": address.transport_size, "count": address.count}
    assert isinstance(address, UnsupportedAddress)
    return {"kind": "unsupported", "syntax_id": address.syntax_id}


_NAMES: dict[object, tuple[str, NckType | None, int | None, str]] = {}


def name_of(address: object) -> tuple[str, NckType | None, int | None, str]:
    """Readable name, type, string length and unit of measure of an item address (cached)."""
    named = _NAMES.get(address)
    if named is None:
        named = _name_of(address)
        if len(_NAMES) < 65536:
            _NAMES[address] = named
    return named


def _name_of(address: object) -> tuple[str, NckType | None, int | None, str]:
    if isinstance(address, NckAddress):
        spec = spec_at(address)
        if spec is None:
            where = f"{NckArea(address.area).name}{address.unit}"
            return (f"NCK {where} col {address.column} line {address.line} ({describe_module(address.module)})",
                    None, None, "")
        return display_name(spec, address), spec.nck_type, spec.string_length, spec.unit
    if isinstance(address, S7AnyAddress):
        return s7any_name(address), None, None, ""
    assert isinstance(address, UnsupportedAddress)
    return f"syntax 0x{address.syntax_id:02X} item", None, None, ""


def _value(address: object, data: bytes, nck_type: NckType | None, length: int | None) -> Any:
    if isinstance(address, S7AnyAddress):
        return s7any_value(address, data)
    if isinstance(address, NckAddress) and nck_type is not None:
        try:
            values = decode_nck_values(nck_type, data, area=address.area, line_count=address.line_count,
                                       string_length=length)
        except NckError:
            return None
        return values[0] if len(values) == 1 else values
    return None


# Plain ints for the hot loop (comparing with an IntEnum member costs several times more).
_S7_PROTOCOL_ID = 0x32
_ROSCTR_JOB = int(s7.Rosctr.JOB)
_ROSCTR_ACK_DATA = int(s7.Rosctr.ACK_DATA)
_SUCCESS = int(ReturnCode.SUCCESS)


_ValueReader = Callable[[bytes], Any]


@dataclass(slots=True)
class _ReadJob:
    """A read job's items, decoded once for all the times a PLC or HMI polls them, and the layout of
    its all-good answer as learnt from the first one (then only the values differ)."""

    addresses: tuple[object, ...]
    names: tuple[str, ...]
    readers: tuple[_ValueReader | None, ...]
    value_formats: tuple[tuple[str, bool] | None, ...]
    # The answer from byte 6 on: its fixed parts (lengths, parameter, item headers) alternating with the
    # values, typed where every value is one number of the same byte order, else as bytes.
    answer_layout: struct.Struct | None = None
    answer_fixed: tuple[bytes, ...] = ()
    answer_typed: bool = False
    value_spans: tuple[tuple[int, int], ...] = ()

    def learn_answer(self, data: bytes, value_spans: list[tuple[int, int]]) -> None:
        fixed = []
        lengths = []
        position = 6  # after the PDU reference
        for value_start, value_end in value_spans:
            fixed.append(data[position:value_start])
            lengths.append((value_start - position, value_end - value_start))
            position = value_end
        if position != len(data) or not value_spans:
            return
        formats = self.value_formats
        typed = None not in formats and len({big_endian for _code, big_endian in formats}) == 1 and all(
            struct.calcsize("<" + code) == value_length
            for (code, _big_endian), (_fixed, value_length) in zip(formats, lengths, strict=True))
        if typed:
            layout = (">" if formats[0][1] else "<") + "6x" + "".join(
                f"{fixed_length}s{code}" for (fixed_length, _v), (code, _big) in zip(lengths, formats, strict=True))
        else:
            layout = ">6x" + "".join(f"{fixed_length}s{value_length}s" for fixed_length, value_length in lengths)
        self.answer_layout = struct.Struct(layout)
        self.answer_fixed = tuple(fixed)
        self.answer_typed = typed
        self.value_spans = tuple(value_spans)


# Read jobs by their parameter bytes.
_READ_JOBS: dict[bytes, _ReadJob] = {}
_MAX_CACHED_JOBS = 4096


def _read_job(parameter: bytes) -> _ReadJob:
    job = _READ_JOBS.get(parameter)
    if job is None:
        addresses, names, readers, value_formats = [], [], [], []
        for address in s7.parse_read_var_request(parameter).items:
            name, nck_type, length, _unit = name_of(address)
            reader = value_format = None
            if isinstance(address, NckAddress) and nck_type is not None:
                try:
                    reader = nck_value_reader(nck_type, area=address.area, line_count=address.line_count,
                                              string_length=length)
                except NckError:
                    reader = None
                value_format = nck_value_format(nck_type, area=address.area, line_count=address.line_count)
            elif isinstance(address, S7AnyAddress) and address.transport_size in _S7_VALUE_CODES:
                reader = functools.partial(s7any_value, address)
                if address.count == 1:
                    value_format = (_S7_VALUE_CODES[address.transport_size], True)
            addresses.append(address)
            names.append(name)
            readers.append(reader)
            value_formats.append(value_format)
        job = _ReadJob(tuple(addresses), tuple(names), tuple(readers), tuple(value_formats))
        if len(_READ_JOBS) < _MAX_CACHED_JOBS:
            _READ_JOBS[parameter] = job
    return job


def _fast_read_job(pdu: TracePdu, data: bytes) -> Exchange | None:
    """A read-var job with no data part, straight from the header (the hot path of field traces)."""
    peeked = s7.peek_read_var_job(data)
    if peeked is None:
        return None
    pdu_ref, parameter = peeked
    try:
        job = _read_job(parameter)
    except NckError:
        return None  # the general path reports the job it cannot decode
    return Exchange(pdu.connection, pdu, None, "read", pdu_ref,
                    list(map(Item, job.addresses, job.names)), "", "", job)


def _fill_items(items: list[Item], readers: tuple[_ValueReader | None, ...],
                results: list[tuple[int, bytes, int]]) -> None:
    for item, reader, (return_code, raw, transport_size) in zip(items, readers, results, strict=True):
        item.return_code = return_code
        item.raw = raw.hex()
        item.data_transport_size = transport_size
        if return_code == _SUCCESS and reader is not None:
            try:
                item.value = reader(raw)
            except NckError:
                item.value = None


def _fast_read_answer(exchange: Exchange, job: _ReadJob, data: bytes) -> bool:
    """Return codes and values of a read-var answer; False leaves it to the general path."""
    layout = job.answer_layout
    if layout is not None and len(data) == layout.size:
        parts = layout.unpack_from(data)
        if parts[0::2] == job.answer_fixed:  # all good, as the first time: only the values are new
            if job.answer_typed:
                for item, value, (start, end) in zip(exchange.items, parts[1::2], job.value_spans, strict=True):
                    item.return_code = _SUCCESS
                    item.value = value
                    item.raw = data[start:end].hex()
                    item.data_transport_size = data[start - 3]
                return True
            _fill_items(exchange.items, job.readers, [(_SUCCESS, raw, data[start - 3]) for raw, (start, _end)
                                                      in zip(parts[1::2], job.value_spans, strict=True)])
            return True
    item_count = len(exchange.items)
    if s7.peek_read_var_answer(data) != item_count:
        return False
    offset = s7.READ_ANSWER_DATA_OFFSET
    end = len(data)
    results = []
    spans = []
    for index in range(item_count):
        if offset + 4 > end:
            return False
        return_code, transport_size = data[offset], data[offset + 1]
        length = data[offset + 2] << 8 | data[offset + 3]
        if return_code != 0xFF and return_code:
            length = 0  # an error item: no data follows, whatever its length says
        elif transport_size in s7.BIT_LENGTH_TRANSPORT_SIZES and transport_size != 0x03:
            length = (length + 7) // 8  # the length is in bits (a BIT item's is its byte count)
        value_end = offset + 4 + length
        if value_end > end:
            return False
        results.append((return_code, data[offset + 4:value_end], transport_size))
        spans.append((offset + 4, value_end))
        offset = value_end + (length & 1 if index + 1 < item_count else 0)
    if offset != end:
        return False
    _fill_items(exchange.items, job.readers, results)
    if job.answer_layout is None and all(code == _SUCCESS for code, _raw, _size in results):
        job.learn_answer(data, spans)
    return True


def decode(capture: Capture) -> list[Exchange]:
    """Pair each client job with the answer bearing its PDU reference on the same connection."""
    with collector_paused():
        return _decode(capture)


def _decode(capture: Capture) -> list[Exchange]:
    open_jobs: dict[tuple[int, int], Exchange] = {}
    exchanges: list[Exchange] = []
    s7comm_plus: dict[int, list[Any]] = {}  # connection -> [its exchange, frame count]
    userdata_state = UserdataState()
    nc_transfers = _NcTransfers()
    for pdu in capture.pdus:
        if pdu.kind != "s7":
            continue
        data = pdu.data
        if len(data) > 14 and data[0] == _S7_PROTOCOL_ID:
            if pdu.from_client:
                if data[1] == _ROSCTR_JOB:
                    fast_job = _fast_read_job(pdu, data)
                    if fast_job is not None:
                        open_jobs[(pdu.connection, fast_job.pdu_ref)] = fast_job
                        exchanges.append(fast_job)
                        continue
            elif data[1] == _ROSCTR_ACK_DATA:
                key = (pdu.connection, data[4] << 8 | data[5])
                waiting = open_jobs.get(key)
                if waiting is not None and waiting.read_job is not None \
                        and _fast_read_answer(waiting, waiting.read_job, data):
                    del open_jobs[key]
                    waiting.answer = pdu
                    continue
        if data[:1] == b"\x72":
            plus = s7comm_plus.get(pdu.connection)
            if plus is None:
                plus = s7comm_plus[pdu.connection] = [Exchange(pdu.connection, pdu, None, S7COMM_PLUS, 0), 0]
                exchanges.append(plus[0])
            plus[1] += 1
            continue
        try:
            parsed = s7.parse_pdu(pdu.data)
        except NckError as exc:
            capture.problems.append(f"frame {pdu.frame}: not an S7 PDU ({exc})")
            continue
        # Jobs from the client are filed under the connection number, jobs from the server under its
        # negative: both sides number their own jobs.
        side = pdu.connection if pdu.from_client else -pdu.connection
        if parsed.rosctr == s7.Rosctr.USERDATA and ncprog.is_nc_parameter(parsed.parameter):
            exchange = nc_transfers.telegram(pdu, parsed, capture)
            if exchange is not None:
                open_jobs[(side, parsed.pdu_ref)] = exchange
                exchanges.append(exchange)
                continue
            waiting = open_jobs.pop((-side, parsed.pdu_ref), None)
            if waiting is None:
                capture.problems.append(f"frame {pdu.frame}: NC response without a request (PDU ref {parsed.pdu_ref})")
                continue
            waiting.answer = pdu
            nc_transfers.answer(waiting, parsed, capture)
            continue
        if parsed.rosctr == s7.Rosctr.USERDATA:
            exchange, answered = _describe_userdata(pdu, parsed, capture, userdata_state)
            if exchange is not None:
                open_jobs[(side, parsed.pdu_ref)] = exchange
                exchanges.append(exchange)
                continue
            if answered is None:
                continue
        elif parsed.rosctr == s7.Rosctr.JOB:
            exchange = _describe_job(pdu, parsed, capture)
            open_jobs[(side, parsed.pdu_ref)] = exchange
            exchanges.append(exchange)
            continue
        waiting = open_jobs.pop((-side, parsed.pdu_ref), None)
        if waiting is None:
            capture.problems.append(f"frame {pdu.frame}: answer without a job (PDU ref {parsed.pdu_ref})")
            continue
        waiting.answer = pdu
        _describe_answer(waiting, parsed, capture, userdata_state)
    for plus, count in s7comm_plus.values():
        plus.detail = f"protocol 0x72, not decoded ({count} frame{'s' if count != 1 else ''})"
    return exchanges


class _NcTransfers:
    """NC program transfers of a capture: each telegram's fields by tshark's names (type, function
    group, subfunction, sequence, data unit reference, last data unit, window, file name), and at the
    telegram that completes a transfer its content (length, time stamp, path, text), as Wireshark
    reassembles them by sequence number."""

    def __init__(self) -> None:
        self._names: dict[tuple[int, int], str] = {}  # (connection, sequence) -> file name
        self._pieces: dict[tuple[int, int], list[bytes]] = {}
        self._pending_names: dict[tuple[int, int], str] = {}  # (connection, PDU ref) -> requested name

    @staticmethod
    def _fields(parameter: ncprog.NcParameter) -> dict[str, Any]:
        fields: dict[str, Any] = {"s7comm.param.userdata.type": parameter.type >> 4,
                                  "s7comm.param.userdata.funcgroup": parameter.type & 0x0F,
                                  "s7comm.param.userdata.subfunc": parameter.subfunction,
                                  "s7comm.param.userdata.seq_num": parameter.sequence}
        if parameter.long:
            fields["s7comm.param.userdata.dataunitref"] = parameter.data_unit_ref
            fields["s7comm.param.userdata.lastdataunit"] = parameter.last_data_unit
        return fields

    def telegram(self, pdu: TracePdu, parsed: s7.S7Pdu, capture: Capture) -> Exchange | None:
        """A request or push as an exchange; None for a response (paired by the caller)."""
        try:
            parameter = ncprog.parse_nc_parameter(parsed.parameter)
        except NckError as exc:
            capture.problems.append(f"frame {pdu.frame}: NC programming parameter not decoded ({exc})")
            return Exchange(pdu.connection, pdu, None, "userdata", parsed.pdu_ref, service="NC programming")
        if parameter.type == ncprog.NC_RESPONSE:
            return None
        exchange = Exchange(pdu.connection, pdu, None, PUSH if parameter.type == ncprog.NC_PUSH else "userdata",
                            parsed.pdu_ref, service=f"NC programming -> {userdata.subfunction_name(userdata.GROUP_NC_PROGRAMMING, parameter.subfunction)}")
        exchange.nc = self._fields(parameter)
        exchange.detail = self._payload(exchange, exchange.nc, parameter, parsed.data, pdu, capture)
        return exchange

    def answer(self, exchange: Exchange, parsed: s7.S7Pdu, capture: Capture) -> None:
        assert exchange.answer is not None
        try:
            parameter = ncprog.parse_nc_parameter(parsed.parameter)
        except NckError as exc:
            capture.problems.append(f"frame {exchange.answer.frame}: NC programming answer not decoded ({exc})")
            return
        exchange.nc_answer = self._fields(parameter)
        if parameter.error_code:
            code = parameter.error_code
            meaning = ncprog.ERROR_TEXTS.get(code, "")
            exchange.header_error = describe_header_error(code >> 8, code & 0xFF) + (f" ({meaning})" if meaning else "")
            return
        if parameter.subfunction in (ncprog.NcSubfunction.REQUEST_DOWNLOAD, ncprog.NcSubfunction.START_UPLOAD):
            name = self._pending_names.pop((exchange.connection, exchange.pdu_ref), "")
            self._names[(exchange.connection, parameter.sequence)] = name
            self._pieces[(exchange.connection, parameter.sequence)] = []
        if parameter.subfunction == ncprog.NcSubfunction.DOWNLOAD_ENDED:
            exchange.detail += " -> stored"
            return
        detail = self._payload(exchange, exchange.nc_answer, parameter, parsed.data, exchange.answer, capture)
        exchange.detail += f" -> {detail}" if detail else " -> ok"

    def _payload(self, exchange: Exchange, fields: dict[str, Any], parameter: ncprog.NcParameter, raw: bytes,
                 pdu: TracePdu, capture: Capture) -> str:
        """The data part by subfunction into ``fields``; the words ``trace show`` prints."""
        try:
            data = ncprog.parse_nc_data(raw)
        except NckError as exc:
            capture.problems.append(f"frame {pdu.frame}: NC programming data not decoded ({exc})")
            return ""
        sub, payload = parameter.subfunction, data.payload
        key = (exchange.connection, parameter.sequence)
        try:
            if sub == ncprog.NcSubfunction.REQUEST_DOWNLOAD and parameter.type == ncprog.NC_REQUEST:
                name = ncprog.parse_name(payload)
                fields["s7comm.param.blockcontrol.filename"] = name
                self._pending_names[(exchange.connection, exchange.pdu_ref)] = name
                return f"file {name}"
            if sub == ncprog.NcSubfunction.START_UPLOAD and parameter.type == ncprog.NC_REQUEST:
                request = ncprog.parse_start_upload(payload)
                fields["s7comm.data.ncprg.unackcount"] = request.window
                fields["s7comm.param.blockcontrol.filename"] = request.name
                self._pending_names[(exchange.connection, exchange.pdu_ref)] = request.name
                return f"file {request.name}, window {request.window}"
            if sub in (ncprog.NcSubfunction.REQUEST_DOWNLOAD, ncprog.NcSubfunction.CONTINUE_DOWNLOAD,
                       ncprog.NcSubfunction.CONTINUE_UPLOAD):
                window = ncprog.parse_window(payload)
                fields["s7comm.data.ncprg.unackcount"] = window.count
                return f"sequence {parameter.sequence}, window {window.count}"
            if sub in (ncprog.NcSubfunction.DOWNLOAD_BLOCK, ncprog.NcSubfunction.START_UPLOAD,
                       ncprog.NcSubfunction.UPLOAD):
                chunk = ncprog.parse_chunk(payload)
                pieces = self._pieces.setdefault(key, [])
                pieces.append(chunk)
                words = (f"sequence {parameter.sequence}, unit {parameter.data_unit_ref}"
                         f"{' (last)' if parameter.is_last else ''}: {len(chunk)} bytes")
                if parameter.is_last:
                    words += self._complete(key, fields)
                return words
            if sub == ncprog.NcSubfunction.DOWNLOAD_ENDED:
                return f"sequence {parameter.sequence}"
        except NckError as exc:
            capture.problems.append(f"frame {pdu.frame}: NC transfer not decoded ({exc})")
        return ""

    def _complete(self, key: tuple[int, int], fields: dict[str, Any]) -> str:
        content = ncprog.parse_transfer_content(b"".join(self._pieces.pop(key, [])))
        fields["s7comm.data.ncprg.filelength"] = " " * 8 if content.length is None else f"{content.length:08d}"
        fields["s7comm.data.ncprg.filetime"] = content.stamp
        fields["s7comm.data.ncprg.filepath"] = f";$PATH={content.path}\n"
        fields["s7comm.data.ncprg.filedata"] = content.text.hex()
        fields["text"] = content.text.decode("latin-1")
        name = self._names.get(key, "")
        directory = content.length is None or content.path.rsplit("/", 1)[-1].upper() == name.upper()
        where = content.path if directory or not name else f"{content.path}/{name}"
        length = "blank (a directory)" if content.length is None else str(content.length)
        lines = content.text.count(b"\n")
        first = content.text.split(b"\n", 1)[0].decode("latin-1").strip()
        return (f"; {where}: length {length}, time {content.stamp.strip() or '-'}, "
                f"{len(content.text)} bytes, {lines} lines, first: {first!r}")




def _describe_userdata(pdu: TracePdu, parsed: s7.S7Pdu, capture: Capture, state: UserdataState
                       ) -> tuple[Exchange | None, userdata.UserdataParameter | None]:
    """A userdata request or push as a new exchange, or (None, its parameter) for a response."""
    try:
        header = userdata.parse_userdata_parameter(parsed.parameter)
    except NckError as exc:
        capture.problems.append(f"frame {pdu.frame}: userdata not decoded ({exc})")
        return Exchange(pdu.connection, pdu, None, "userdata", parsed.pdu_ref, service="Userdata"), None
    if header.type == userdata.TYPE_RESPONSE:
        return None, header
    service = userdata.describe(header.group, header.subfunction)
    exchange = Exchange(pdu.connection, pdu, None, PUSH if header.type == userdata.TYPE_PUSH else "userdata",
                        parsed.pdu_ref, service=service)
    if header.group == userdata.GROUP_CPU and header.subfunction == szl.SUBFUNCTION_READ_SZL \
            and header.method == userdata.METHOD_REQUEST:
        try:
            request = szl.parse_szl_request(parsed.parameter, parsed.data)
            exchange.detail = f"read SZL 0x{request.szl_id:04X} index 0x{request.szl_index:04X}"
        except NckError:
            pass
    elif header.type == userdata.TYPE_REQUEST and header.long:
        # The next part of a long answer (SZL lists over several PDUs): the answer's sequence number
        # in the 8-byte parameter form, data 0A 00 00 00 (python-snap7 reading SZL 0x001C).
        exchange.detail = f"next part of sequence {header.sequence}"
    else:
        stage = PUSH_STAGE if header.type == userdata.TYPE_PUSH else REQUEST
        _apply_contents(exchange, userdata_contents(header, parsed.data, stage, pdu.connection, state),
                        answer=False)
    return exchange, None


def _item_name(address: object) -> str:
    if isinstance(address, UnsupportedAddress):
        areas = cyclic.describe_dbread(address)
        if areas is not None:
            return f"DBREAD {areas}"
    return name_of(address)[0]


def _apply_contents(exchange: Exchange, contents: Contents | None, *, answer: bool) -> None:
    """A payload by name: its text after the exchange's (``->`` for an answer), its items by address."""
    if contents is None:
        return
    if contents.detail:
        if answer:
            exchange.detail += f"{' ' if exchange.detail else ''}-> {contents.detail}"
        else:
            exchange.detail = f"{exchange.detail}; {contents.detail}" if exchange.detail else contents.detail
    if contents.items:
        exchange.items = [Item(address, _item_name(address)) if value is None else
                          Item(address, _item_name(address), value.return_code, _value(address, value.data, None, None),
                               value.data.hex(),
                               value.transport_size)
                          for address, value in contents.items]


def _describe_job(pdu: TracePdu, parsed: s7.S7Pdu, capture: Capture) -> Exchange:
    function = parsed.parameter[0] if parsed.parameter else -1
    exchange = Exchange(pdu.connection, pdu, None, FUNCTION_NAMES.get(function, f"0x{function:02X}"), parsed.pdu_ref,
                        service=SERVICE_NAMES.get(function, f"Unknown function: 0x{function & 0xFF:02x}"))
    try:
        if function == s7.Function.READ_VAR:
            for address in s7.parse_read_var_request(parsed.parameter).items:
                exchange.items.append(Item(address, name_of(address)[0]))
        elif function == s7.Function.WRITE_VAR:
            request = s7.parse_write_var_request(parsed.parameter, parsed.data)
            for address, data_item in zip(request.items, request.values, strict=True):
                name, nck_type, length, _unit = name_of(address)
                if isinstance(address, S7AnyAddress) and address.area == 0x80:
                    name = "PQ" + name[2:]  # direct peripheral access written: an output
                exchange.items.append(Item(address, name, None, _value(address, data_item.data, nck_type, length),
                                           data_item.data.hex(), data_item.transport_size))
        elif function == s7.Function.PI_SERVICE:
            exchange.detail = _describe_pi(pi.parse_pi_request(parsed.parameter))
        elif function in blocks.FUNCTIONS:
            control = blocks.parse_block_control(parsed.parameter)
            exchange.detail = blocks.describe_block_control(control)
            name = control.file_name or ""
            if function == blocks.START_UPLOAD and ncprog.is_nc_file_name(name):
                # an NC file uploaded through the PLC-block jobs (libnodave's daveGetNCProgram)
                exchange.detail = f"NC file {name}"
                exchange.nc = {"s7comm.param.blockcontrol.filename": name}
        elif function == s7.Function.SETUP_COMMUNICATION:
            setup = s7.parse_setup_communication(parsed.parameter)
            exchange.detail = f"PDU {setup.pdu_length}, AMQ {setup.max_amq_calling}/{setup.max_amq_called}"
    except NckError as exc:
        capture.problems.append(f"frame {pdu.frame}: job not decoded ({exc})")
    return exchange


def _describe_answer(exchange: Exchange, parsed: s7.S7Pdu, capture: Capture,
                     state: UserdataState | None = None) -> None:
    if parsed.error_class or parsed.error_code:
        try:
            job = s7.parse_pdu(exchange.job.data)
            function = job.parameter[0] if job.parameter else -1
        except NckError:
            function = -1
        # worded for the service: a PI's or file transfer's 0xD201 is "no such program or file"
        exchange.header_error = describe_service_header_error(function, parsed.error_class, parsed.error_code)
        return
    try:
        if exchange.function == "read":
            response = s7.parse_read_var_response(parsed.parameter, parsed.data)
            for item, data_item in zip(exchange.items, response.items, strict=False):
                item.return_code = data_item.return_code
                item.raw = data_item.data.hex()
                item.data_transport_size = data_item.transport_size
                if data_item.return_code == _SUCCESS:
                    _name, nck_type, length, _unit = name_of(item.target)
                    item.value = _value(item.target, data_item.data, nck_type, length)
        elif exchange.function == "write":
            response = s7.parse_write_var_response(parsed.parameter, parsed.data)
            for item, code in zip(exchange.items, response.return_codes, strict=False):
                item.return_code = code
        elif exchange.function == "setup":
            setup = s7.parse_setup_communication(parsed.parameter)
            exchange.detail += f" -> PDU {setup.pdu_length}, AMQ {setup.max_amq_calling}/{setup.max_amq_called}"
        elif parsed.rosctr == s7.Rosctr.USERDATA:
            if exchange.function == PUSH:
                exchange.function = "userdata"  # answered: a request sent as type 0 (pyS7 sends SZL reads so)
            header = userdata.parse_userdata_parameter(parsed.parameter)
            if header.error_code:
                exchange.header_error = describe_header_error(header.error_code >> 8, header.error_code & 0xFF)
                return
            request = s7.parse_pdu(exchange.job.data)
            _apply_contents(exchange, userdata_contents(
                header, parsed.data, RESPONSE, exchange.connection, UserdataState() if state is None else state,
                userdata.parse_userdata_parameter(request.parameter), request.data), answer=True)
            if header.last_data_unit:
                exchange.detail += f"{' ' if exchange.detail else ''}-> more follows (sequence {header.sequence})"
        elif parsed.parameter and parsed.parameter[0] in blocks.FUNCTIONS:
            _describe_block_answer(exchange, blocks.parse_block_control(parsed.parameter), parsed.data)
    except NckError as exc:
        capture.problems.append(f"frame {exchange.answer.frame if exchange.answer else '?'}: answer not "
                                f"decoded ({exc})")


def _describe_pi(request: pi.PiServiceRequest) -> str:
    """``_N_SELECT("201", "/_N_MPF_DIR/_N_TEST_MPF")``; the PLC services' block list or argument as
    Wireshark decodes them: ``_INSE(0A00001P = DB 1 passive)``, ``P_PROGRAM("P_PROGRAM")``."""
    block = request.parameter_block
    if block is None:
        return f"{request.service}({', '.join(f'{chr(34)}{a}{chr(34)}' for a in request.arguments)})"
    if request.service in ("_INSE", "_DELE"):
        names = []
        for name in blocks.parse_block_list(block):
            where = blocks.FILE_SYSTEM_NAMES.get(name.file_system, f"file system {name.file_system}")
            names.append(f"{name} = {name.readable} {where}")
        return f"{request.service}({', '.join(names)})"
    if not block:
        return f"{request.service}()"
    return f'{request.service}("{block.decode("ascii", "replace")}")'


def _describe_block_answer(exchange: Exchange, control: blocks.BlockControl, data: bytes) -> None:
    if control.function == blocks.START_UPLOAD and control.file_name is not None:
        exchange.detail += f" -> upload id {control.session}, block length {control.file_name.lstrip('0') or '0'}"
    elif control.function in (blocks.DOWNLOAD_BLOCK, blocks.UPLOAD) and len(data) >= 4:
        more = " (more follows)" if control.status and control.status & 0x01 else ""
        exchange.detail += f" -> {len(data) - 4} bytes{more}"


def _address_from_json(address: dict[str, Any]) -> object:
    if address["kind"] == "nck":
        return NckAddress(address["area"], address["unit"], address["column"], address["line"], address["module"],
                          address["line_count"], address["syntax_id"])
    if address["kind"] == "s7any":
        return S7AnyAddress(address["transport_size"], address["count"], address["db"], address["area"],
                            address["byte"], address["bit"])
    return UnsupportedAddress(0x12, address["syntax_id"], b"")


def format_exchange(exchange: Exchange, start_s: float) -> list[str]:
    """The ``trace show`` lines of one exchange."""
    t = exchange.job.time_s - start_s
    head = f"{t:10.3f}s  c{exchange.connection}  #{exchange.job.frame:<6} {exchange.function:8}"
    lines = []
    if exchange.service and exchange.function in ("userdata", PUSH):
        head += f" {exchange.service}"
        if exchange.detail:
            head += ":"
    if exchange.detail:
        head += f" {exchange.detail}"
    if not exchange.job.from_client and exchange.function != PUSH:
        head += "  (job from the PLC)" if exchange.function != S7COMM_PLUS else ""
    if exchange.answer is None and exchange.function not in (PUSH, S7COMM_PLUS):
        head += "  [no answer]"
    elif exchange.header_error:
        head += f"  -> {exchange.header_error}"
    lines.append(head)
    for item in exchange.items:
        unit = name_of(item.target)[3]
        suffix = f" {unit}" if unit and unit != "1" else ""
        shown = f"{item.value:.6f}" if isinstance(item.value, float) else (item.value if item.value is not None
                                                                           else item.raw or "")
        if exchange.function == "write":
            text = f"    {item.name} := {shown}{suffix}"
            if item.return_code is not None:
                text += f"  -> {RETURN_CODE_TEXTS.get(item.return_code, hex(item.return_code))}"
        else:
            text = f"    {item.name}"
            if item.return_code == _SUCCESS:
                text += f" = {shown}{suffix}"
            elif item.return_code is not None:
                text += f"  -> {RETURN_CODE_TEXTS.get(item.return_code, hex(item.return_code))}"
        lines.append(text)
    return lines


def format_gap(gap: Gap, start_s: float) -> str:
    """The ``trace show`` line of bytes the capture lost, at the frame after them."""
    return f"{gap.time_s - start_s:10.3f}s  c{gap.connection}  #{gap.frame:<6} gap      {gap.describe()}"
