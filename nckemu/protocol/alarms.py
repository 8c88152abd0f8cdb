"""Alarm and diagnostic payloads of userdata group 4 (CPU functions): what a CPU pushes when a message
block (ALARM_8, ALARM_S, NOTIFY...) changes state, what an HMI sends to lock, acknowledge or query
them, and the 20-byte diagnostic buffer entry.

Layout as Wireshark's s7comm dissector reads it (``s7comm_decode_ud_cpu_alarm_main``, names as it gives
them), checked against the public WinCC/S7-400 capture (iti ``wincc_s400_production.pcapng``):

- indications (ALARM_8, NOTIFY, ALARM_SQ, ALARM_S, NOTIFY_8, ALARM ack): an 8-byte S7 timestamp
  (BCD year, month, day, hour, minute, second, three digits of milliseconds and the weekday);
  SCAN indications put two unknown bytes before and after it; requests (lock, unlock, ack, query)
  have none;
- a function identifier and the number of message objects;
- each object: ``12 <length> <syntax id>``, then by syntax id: the number of associated values and
  the 4-byte event ID; the event state and state (ALARM_IND, NOTIFY_IND); acknowledge state going and
  coming (those and ALARM_ACK); event going, coming, last changed and a reserved byte (NOTIFY_IND);
  the associated values, as read-answer data items (ALARM_IND, NOTIFY_IND). The alarm query object
  (syntax 0x1A) carries an unknown byte, the query type, another unknown byte and an alarm type or
  event ID. Each state byte is one bit per signal, SIG_1 in bit 0.
- in a response, each object is only a return code.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from datetime import datetime

from .errors import NckProtocolError, NckTruncatedError
from .s7 import DataItem, build_data_items, parse_data_items_at

SUBFUNCTION_DIAGNOSTIC_MESSAGE = 0x03
SUBFUNCTION_ALARM8_IND = 0x05
SUBFUNCTION_NOTIFY_IND = 0x06
SUBFUNCTION_SCAN_IND = 0x09
SUBFUNCTION_ALARMACK_IND = 0x0C
SUBFUNCTION_ALARMSQ_IND = 0x11
SUBFUNCTION_ALARMS_IND = 0x12
SUBFUNCTION_NOTIFY8_IND = 0x16
SUBFUNCTION_ALARM_QUERY = 0x13
# Subfunctions whose alarm message starts with the time the message came.
TIMESTAMPED = frozenset({SUBFUNCTION_ALARM8_IND, SUBFUNCTION_NOTIFY_IND, SUBFUNCTION_ALARMACK_IND,
                         SUBFUNCTION_ALARMSQ_IND, SUBFUNCTION_ALARMS_IND, SUBFUNCTION_NOTIFY8_IND})
# Subfunctions that carry an alarm message at all (indications, lock/unlock, ack, query).
ALARM_SUBFUNCTIONS = TIMESTAMPED | {SUBFUNCTION_SCAN_IND, 0x07, 0x08, 0x0B, 0x0D, 0x0E, SUBFUNCTION_ALARM_QUERY}

SYNTAX_ALARM_LOCKFREE = 0x15
SYNTAX_ALARM_IND = 0x16
SYNTAX_ALARM_ACK = 0x19
SYNTAX_ALARM_QUERYREQ = 0x1A
SYNTAX_NOTIFY_IND = 0x1C
SYNTAX_NAMES = {SYNTAX_ALARM_LOCKFREE: "ALARM_LOCKFREE", SYNTAX_ALARM_IND: "ALARM_IND", SYNTAX_ALARM_ACK: "ALARM_ACK",
                SYNTAX_ALARM_QUERYREQ: "ALARM_QUERYREQ", SYNTAX_NOTIFY_IND: "NOTIFY_IND"}
QUERY_BY_ALARM_TYPE = 1
QUERY_BY_EVENT_ID = 3
ALARM_TYPE_NAMES = {1: "SCAN", 2: "ALARM_8", 4: "ALARM_S"}

TIMESTAMP_LENGTH = 8
_VAR_SPEC = 0x12


def _bcd(value: int) -> int:
    return (value // 10) << 4 | value % 10


def _from_bcd(value: int, what: str) -> int:
    high, low = value >> 4, value & 0x0F
    if high > 9 or low > 9:
        raise NckProtocolError(f"{what}: 0x{value:02X} is not BCD")
    return high * 10 + low


def parse_timestamp(raw: bytes) -> datetime | None:
    """An 8-byte S7 timestamp (BCD; years 90..99 are 1990.., 00..89 are 2000..); all zero: none (an
    alarm that has not gone yet). The weekday nibble is not checked."""
    if len(raw) < TIMESTAMP_LENGTH:
        raise NckTruncatedError("S7 timestamp shorter than 8 bytes")
    if not any(raw[:TIMESTAMP_LENGTH]):
        return None
    year = _from_bcd(raw[0], "year")
    milliseconds = _from_bcd(raw[6], "milliseconds") * 10 + _from_bcd(raw[7] >> 4, "milliseconds")
    try:
        return datetime(year + (1900 if year >= 90 else 2000), _from_bcd(raw[1], "month"), _from_bcd(raw[2], "day"),
                        _from_bcd(raw[3], "hour"), _from_bcd(raw[4], "minute"), _from_bcd(raw[5], "second"),
                        milliseconds * 1000)
    except ValueError as exc:
        raise NckProtocolError(f"S7 timestamp {raw[:TIMESTAMP_LENGTH].hex()}: {exc}") from None


def build_timestamp(moment: datetime | None) -> bytes:
    """The 8-byte S7 timestamp of ``moment`` (1990..2089, milliseconds); None: eight zero bytes."""
    if moment is None:
        return bytes(TIMESTAMP_LENGTH)
    if not 1990 <= moment.year <= 2089:
        raise NckProtocolError(f"an S7 timestamp holds the years 1990..2089, not {moment.year}")
    milliseconds = moment.microsecond // 1000
    weekday = moment.isoweekday() % 7 + 1  # S7: Sunday 1 .. Saturday 7
    return bytes([_bcd(moment.year % 100), _bcd(moment.month), _bcd(moment.day), _bcd(moment.hour),
                  _bcd(moment.minute), _bcd(moment.second), _bcd(milliseconds // 10),
                  (milliseconds % 10) << 4 | weekday])


def signals(state: int) -> list[str]:
    """``SIG_1``.. for the bits set in a state byte, as tshark lists them."""
    return [f"SIG_{bit + 1}" for bit in range(8) if state >> bit & 1]


@dataclass(frozen=True, slots=True)
class AlarmObject:
    """One message object. Fields a syntax id does not carry stay 0 (empty); an object of an unknown
    syntax id keeps its bytes in ``raw``."""

    syntax_id: int
    event_id: int = 0
    event_state: int = 0
    state: int = 0
    ack_going: int = 0
    ack_coming: int = 0
    event_going: int = 0
    event_coming: int = 0
    event_last_changed: int = 0
    values: tuple[DataItem, ...] = ()
    value_count: int = 0          # as announced (ALARM_LOCKFREE and ALARM_ACK announce values they omit)
    query_type: int = 0
    query_unknown: bytes = b""    # the two unknown bytes of a query object
    raw: bytes = b""
    return_code: int | None = None  # a response's object

    @property
    def syntax_name(self) -> str:
        return SYNTAX_NAMES.get(self.syntax_id, f"syntax 0x{self.syntax_id:02X}")


@dataclass(frozen=True, slots=True)
class AlarmMessage:
    function: int
    objects: tuple[AlarmObject, ...]
    timestamp: datetime | None = None
    timestamped: bool = False     # the message starts with a timestamp (indications)
    scan_unknown: bytes = b""     # SCAN indications: 2 bytes before and 2 after the timestamp


def _parse_object(data: bytes, offset: int, response: bool) -> tuple[AlarmObject, int]:
    if response:
        if offset >= len(data):
            raise NckTruncatedError("alarm response object missing")
        return AlarmObject(0, return_code=data[offset]), offset + 1
    if offset + 3 > len(data):
        raise NckTruncatedError("alarm message object header cut short")
    var_spec, length, syntax_id = data[offset:offset + 3]
    if var_spec != _VAR_SPEC or length == 0:
        raise NckProtocolError(f"alarm message object starts {data[offset:offset + 2].hex()}, not 12 <length>")
    end = offset + 2 + length
    if end > len(data):
        raise NckTruncatedError(f"alarm message object announces {length} bytes beyond the data")
    position = offset + 3
    if syntax_id == SYNTAX_ALARM_QUERYREQ:
        if length != 8:
            raise NckProtocolError(f"alarm query object of {length} bytes, not 8")
        unknown1, query_type, unknown2, event_id = struct.unpack_from(">BBBI", data, position)
        return AlarmObject(syntax_id, event_id, query_type=query_type,
                           query_unknown=bytes([unknown1, unknown2])), end
    if syntax_id not in (SYNTAX_ALARM_LOCKFREE, SYNTAX_ALARM_IND, SYNTAX_NOTIFY_IND, SYNTAX_ALARM_ACK):
        return AlarmObject(syntax_id, raw=data[position:end]), end
    if position + 5 > end:
        raise NckProtocolError(f"alarm message object of {length} bytes has no room for its event ID")
    count, event_id = struct.unpack_from(">BI", data, position)
    position += 5
    indicated = syntax_id in (SYNTAX_ALARM_IND, SYNTAX_NOTIFY_IND)
    names = (["event_state", "state"] if indicated else []) \
        + (["ack_going", "ack_coming"] if syntax_id != SYNTAX_ALARM_LOCKFREE else []) \
        + (["event_going", "event_coming", "event_last_changed", "reserved"] if syntax_id == SYNTAX_NOTIFY_IND else [])
    if position + len(names) > end:
        raise NckProtocolError(f"alarm message object of {length} bytes has no room for its states")
    fields = dict(zip(names, data[position:position + len(names)], strict=True))
    fields.pop("reserved", None)
    position += len(names)
    if position != end:
        raise NckProtocolError(f"alarm message object announces {length} bytes, its fields take {position - offset - 2}")
    values: tuple[DataItem, ...] = ()
    if indicated and count:
        values, end = parse_data_items_at(data, position, count)
    return AlarmObject(syntax_id, event_id, values=values, value_count=count, **fields), end


def parse_alarm_message(data: bytes, subfunction: int, *, response: bool = False) -> AlarmMessage:
    """The alarm message in a userdata data part's payload (after return code, transport size, length)."""
    offset = 0
    timestamp = None
    scan_unknown = b""
    timestamped = not response and subfunction in TIMESTAMPED | {SUBFUNCTION_SCAN_IND}
    if timestamped:
        if subfunction == SUBFUNCTION_SCAN_IND:
            scan_unknown = data[:2]
            offset = 2
        timestamp = parse_timestamp(data[offset:offset + TIMESTAMP_LENGTH])
        offset += TIMESTAMP_LENGTH
        if subfunction == SUBFUNCTION_SCAN_IND:
            scan_unknown += data[offset:offset + 2]
            offset += 2
            if len(scan_unknown) != 4:
                raise NckTruncatedError("SCAN indication cut short")
    if offset + 2 > len(data):
        raise NckTruncatedError("alarm message without function and object count")
    function, count = data[offset], data[offset + 1]
    offset += 2
    objects = []
    for _ in range(count):
        parsed, offset = _parse_object(data, offset, response)
        objects.append(parsed)
    if offset != len(data):
        raise NckProtocolError(f"{len(data) - offset} bytes after the alarm message's {count} objects")
    return AlarmMessage(function, tuple(objects), timestamp, timestamped, scan_unknown)


def _build_object(item: AlarmObject) -> bytes:
    if item.return_code is not None:
        return bytes([item.return_code])
    if item.syntax_id == SYNTAX_ALARM_QUERYREQ:
        unknown = item.query_unknown or b"\x00\x00"
        body = struct.pack(">BBBI", unknown[0], item.query_type, unknown[1], item.event_id)
    elif item.syntax_id in (SYNTAX_ALARM_LOCKFREE, SYNTAX_ALARM_IND, SYNTAX_NOTIFY_IND, SYNTAX_ALARM_ACK):
        body = struct.pack(">BI", item.value_count, item.event_id)
        if item.syntax_id in (SYNTAX_ALARM_IND, SYNTAX_NOTIFY_IND):
            body += bytes([item.event_state, item.state])
        if item.syntax_id != SYNTAX_ALARM_LOCKFREE:
            body += bytes([item.ack_going, item.ack_coming])
        if item.syntax_id == SYNTAX_NOTIFY_IND:
            body += bytes([item.event_going, item.event_coming, item.event_last_changed, 0])
        head = bytes([_VAR_SPEC, 1 + len(body), item.syntax_id])
        if item.syntax_id in (SYNTAX_ALARM_IND, SYNTAX_NOTIFY_IND) and item.value_count:
            if len(item.values) != item.value_count:
                raise NckProtocolError(f"{item.value_count} associated values announced, {len(item.values)} given")
            return head + body + build_data_items(item.values)
        return head + body
    else:
        body = item.raw
    if len(body) > 254:
        raise NckProtocolError("alarm message object longer than 254 bytes")
    return bytes([_VAR_SPEC, 1 + len(body), item.syntax_id]) + body


def build_alarm_message(message: AlarmMessage) -> bytes:
    head = b""
    if message.timestamped:
        stamp = build_timestamp(message.timestamp)
        head = message.scan_unknown[:2] + stamp + message.scan_unknown[2:] if message.scan_unknown else stamp
    if len(message.objects) > 255:
        raise NckProtocolError("an alarm message holds at most 255 objects")
    return head + bytes([message.function, len(message.objects)]) + b"".join(map(_build_object, message.objects))


def describe_alarm_message(message: AlarmMessage) -> str:
    """``EventID=0x000000af SIG_1 on, ack going SIG_2.. at 1994-01-06 00:27:20.397, values 0001 ffff``."""
    parts = []
    for item in message.objects:
        if item.return_code is not None:
            parts.append(f"return code 0x{item.return_code:02X}")
            continue
        if item.syntax_id == SYNTAX_ALARM_QUERYREQ:
            if item.query_type == QUERY_BY_ALARM_TYPE:
                parts.append(f"query by alarm type {ALARM_TYPE_NAMES.get(item.event_id, item.event_id)}")
            elif item.query_type == QUERY_BY_EVENT_ID:
                parts.append(f"query by EventID=0x{item.event_id:08x}")
            else:  # a query type tshark does not name either: its argument as it stands
                parts.append(f"query type {item.query_type} (0x{item.event_id:08x})")
            continue
        if item.raw:
            parts.append(f"{item.syntax_name} {item.raw.hex()}")
            continue
        text = f"EventID=0x{item.event_id:08x}"
        if item.syntax_id in (SYNTAX_ALARM_IND, SYNTAX_NOTIFY_IND):
            on = signals(item.event_state)
            text += f" On=[{','.join(on)}]" if on else " off"
        if item.syntax_id != SYNTAX_ALARM_LOCKFREE and (item.ack_going or item.ack_coming):
            text += f" ack going=[{','.join(signals(item.ack_going))}] coming=[{','.join(signals(item.ack_coming))}]"
        if item.values:
            text += " values " + " ".join(v.data.hex() if v.return_code == 0xFF else f"(0x{v.return_code:02X})"
                                          for v in item.values)
        parts.append(text)
    text = "; ".join(parts)
    if message.timestamp is not None:
        text += f" at {message.timestamp.isoformat(sep=' ', timespec='milliseconds')}"
    return text.strip()


@dataclass(frozen=True, slots=True)
class DiagnosticMessage:
    """A diagnostic buffer entry (subfunction 3 pushes; SZL 0x00A0 records): event ID, priority class,
    OB number, DatID, two info fields, time."""

    event_id: int
    priority_class: int
    ob_number: int
    dat_id: int
    info1: int
    info2: int
    timestamp: datetime | None


_DIAGNOSTIC = struct.Struct(">HBBHHI")
DIAGNOSTIC_LENGTH = _DIAGNOSTIC.size + TIMESTAMP_LENGTH


def parse_diagnostic_message(data: bytes) -> DiagnosticMessage:
    if len(data) != DIAGNOSTIC_LENGTH:
        raise NckProtocolError(f"diagnostic message of {len(data)} bytes, not {DIAGNOSTIC_LENGTH}")
    return DiagnosticMessage(*_DIAGNOSTIC.unpack_from(data), parse_timestamp(data[_DIAGNOSTIC.size:]))


def build_diagnostic_message(message: DiagnosticMessage) -> bytes:
    return _DIAGNOSTIC.pack(message.event_id, message.priority_class, message.ob_number, message.dat_id,
                            message.info1, message.info2) + build_timestamp(message.timestamp)


def describe_diagnostic_message(message: DiagnosticMessage) -> str:
    text = (f"EventID=0x{message.event_id:04x} OB {message.ob_number} priority {message.priority_class} "
            f"DatID 0x{message.dat_id:04x} info 0x{message.info1:04x} 0x{message.info2:08x}")
    if message.timestamp is not None:
        text += f" at {message.timestamp.isoformat(sep=' ', timespec='milliseconds')}"
    return text


MESSAGE_EVENTS = ((0x01, "MODE"), (0x02, "SYS"), (0x04, "USR"), (0x08, "-4-"), (0x10, "-5-"), (0x20, "-6-"),
                  (0x40, "-7-"), (0x80, "ALM"))
MESSAGE_ALARM_TYPES = {0x00: "SCAN_ABORT", 0x01: "SCAN_INITIATE", 0x04: "ALARM_ABORT", 0x05: "ALARM_INITIATE",
                       0x08: "ALARM_S_ABORT", 0x09: "ALARM_S_INITIATE", 0x0C: "AR_SEND_ABORT", 0x0D: "AR_SEND_INITIATE"}


def describe_message_service(data: bytes, request: bool) -> str:
    """A message service request (subscribed events, user name, alarm type) or its response (result)."""
    if request:
        if len(data) < 2:
            raise NckTruncatedError("message service request shorter than 2 bytes")
        events = ",".join(name for bit, name in MESSAGE_EVENTS if data[0] & bit)
        text = f"SubscribedEvents=({events})"
        user = data[2:10].rstrip(b"\x00 ").decode("ascii", "replace")
        if user:
            text += f" user {user!r}"
        if data[0] & 0x80 and len(data) > 10:
            text += f" AlmType={MESSAGE_ALARM_TYPES.get(data[10], f'0x{data[10]:02x}')}"
        return text
    if len(data) < 2:
        raise NckTruncatedError("message service response shorter than 2 bytes")
    text = f"result 0x{data[0]:02x}"
    if len(data) > 2:
        text += f" AlmType={MESSAGE_ALARM_TYPES.get(data[2], f'0x{data[2]:02x}')}"
    return text


ALARM_TYPE_ALARM_S = 4


@dataclass(frozen=True, slots=True)
class QueryEntry:
    """One alarm of an alarm query's answer. ALARM_S entries add the time and associated value the
    message came with and went with (an all-zero time: still active)."""

    alarm_type: int
    event_id: int
    event_state: int = 0
    ack_going: int = 0
    ack_coming: int = 0
    dataset_length: int = 0
    unknown: bytes = b"\x00\x00\x00"   # two bytes before the alarm type, one after the event ID
    coming: tuple[datetime | None, DataItem] | None = None
    going: tuple[datetime | None, DataItem] | None = None


@dataclass(frozen=True, slots=True)
class AlarmQueryResponse:
    function: int
    object_count: int
    return_code: int
    transport_size: int
    complete_length: int       # 0xFFFF: entries until a zero byte
    entries: tuple[QueryEntry, ...]
    rest: bytes = b""          # what follows the entries


_QUERY_ENTRY = struct.Struct(">B2sBIBBBB")


def _parse_stamped_value(data: bytes, offset: int) -> tuple[tuple[datetime | None, DataItem], int]:
    moment = parse_timestamp(data[offset:offset + TIMESTAMP_LENGTH])
    (value,), offset = parse_data_items_at(data, offset + TIMESTAMP_LENGTH, 1)
    return (moment, value), offset


def parse_alarm_query_response(data: bytes) -> AlarmQueryResponse:
    """The answer to an alarm query (subfunction 0x13): function, object count, return code, transport
    size, the complete length, then the alarms (Wireshark's ``s7comm_decode_ud_cpu_alarm_query_response``)."""
    if len(data) < 6:
        raise NckTruncatedError("alarm query answer shorter than 6 bytes")
    function, object_count, return_code, transport_size, complete_length = struct.unpack_from(">BBBBH", data)
    offset = 6
    entries = []
    remaining = complete_length
    while return_code == 0xFF and offset < len(data) and (
            data[offset] if complete_length == 0xFFFF else remaining > 0):
        start = offset
        if offset + _QUERY_ENTRY.size > len(data):
            raise NckTruncatedError("alarm query answer entry cut short")
        length, unknown1, alarm_type, event_id, unknown2, state, going, coming = _QUERY_ENTRY.unpack_from(data, offset)
        offset += _QUERY_ENTRY.size
        came = went = None
        if alarm_type == ALARM_TYPE_ALARM_S:
            came, offset = _parse_stamped_value(data, offset)
            went, offset = _parse_stamped_value(data, offset)
        entries.append(QueryEntry(alarm_type, event_id, state, going, coming, length, unknown1 + bytes([unknown2]),
                                  came, went))
        remaining -= offset - start
    return AlarmQueryResponse(function, object_count, return_code, transport_size, complete_length, tuple(entries),
                              data[offset:])


def build_alarm_query_response(response: AlarmQueryResponse) -> bytes:
    parts = [struct.pack(">BBBBH", response.function, response.object_count, response.return_code,
                         response.transport_size, response.complete_length)]
    for entry in response.entries:
        parts.append(_QUERY_ENTRY.pack(entry.dataset_length, entry.unknown[:2], entry.alarm_type, entry.event_id,
                                       entry.unknown[2], entry.event_state, entry.ack_going, entry.ack_coming))
        for stamped in (entry.coming, entry.going):
            if stamped is not None:
                parts.append(build_timestamp(stamped[0]) + build_data_items((stamped[1],)))
    parts.append(response.rest)
    return b"".join(parts)


def describe_alarm_query_response(response: AlarmQueryResponse) -> str:
    if response.return_code != 0xFF:
        return f"return code 0x{response.return_code:02X}"
    parts = []
    for entry in response.entries:
        kind = ALARM_TYPE_NAMES.get(entry.alarm_type, f"alarm type {entry.alarm_type}")
        text = f"{kind} EventID=0x{entry.event_id:08x}"
        on = signals(entry.event_state)
        text += f" On=[{','.join(on)}]" if on else " off"
        for label, stamped in (("came", entry.coming), ("went", entry.going)):
            if stamped is not None and stamped[0] is not None:
                text += f" {label} {stamped[0].isoformat(sep=' ', timespec='milliseconds')} ({stamped[1].data.hex()})"
        parts.append(text)
    count = len(parts)
    return f"{count} alarm{'s' if count != 1 else ''}" + (": " + "; ".join(parts) if parts else "")
