"""The payload codecs of userdata (alarm and diagnostic messages, S7 timestamps, cyclic subscriptions and
data, SZL lists, block lists): parse(build(v)) == v, build(parse(x)) == x where parse succeeds, and
garbage raises only our typed errors."""

from __future__ import annotations

from datetime import datetime

from hypothesis import given
from hypothesis import strategies as st

from nckemu.errors import NckError
from nckemu.protocol import alarms, cyclic, szl, userdata
from nckemu.protocol.addresses import S7AnyAddress, UnsupportedAddress
from nckemu.protocol.s7 import DataItem
from nckemu.traces.contents import PUSH, REQUEST, RESPONSE, UserdataState, userdata_contents

u8 = st.integers(0, 0xFF)
u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFFFFFF)

moments = st.builds(lambda d, ms: d.replace(microsecond=ms * 1000),
                    st.datetimes(datetime(1990, 1, 1), datetime(2089, 12, 31, 23, 59, 59)), st.integers(0, 999))
# Good items carry data (byte-length transport sizes); error items none, as the codec reads them.
data_items = st.one_of(
    st.builds(DataItem, return_code=st.just(0xFF), transport_size=st.sampled_from([0x04, 0x09, 0x07]),
              data=st.binary(max_size=12)).filter(lambda i: i.transport_size != 0x04 or len(i.data) < 0x2000),
    st.builds(DataItem, return_code=st.sampled_from([0x05, 0x0A]), transport_size=st.just(0x00), data=st.just(b"")))


@st.composite
def alarm_objects(draw: st.DrawFn) -> alarms.AlarmObject:
    syntax = draw(st.sampled_from([alarms.SYNTAX_ALARM_LOCKFREE, alarms.SYNTAX_ALARM_IND, alarms.SYNTAX_ALARM_ACK,
                                   alarms.SYNTAX_NOTIFY_IND, alarms.SYNTAX_ALARM_QUERYREQ, 0x30]))
    if syntax == alarms.SYNTAX_ALARM_QUERYREQ:
        return alarms.AlarmObject(syntax, draw(u32), query_type=draw(u8), query_unknown=draw(st.binary(min_size=2,
                                                                                                        max_size=2)))
    if syntax == 0x30:
        return alarms.AlarmObject(syntax, raw=draw(st.binary(min_size=1, max_size=20)))
    indicated = syntax in (alarms.SYNTAX_ALARM_IND, alarms.SYNTAX_NOTIFY_IND)
    values = tuple(draw(st.lists(data_items, max_size=4))) if indicated else ()
    return alarms.AlarmObject(
        syntax, draw(u32), draw(u8) if indicated else 0, draw(u8) if indicated else 0,
        draw(u8) if syntax != alarms.SYNTAX_ALARM_LOCKFREE else 0, draw(u8) if syntax != alarms.SYNTAX_ALARM_LOCKFREE else 0,
        *(draw(st.tuples(u8, u8, u8)) if syntax == alarms.SYNTAX_NOTIFY_IND else (0, 0, 0)),
        values=values, value_count=len(values) if indicated else draw(u8))


@st.composite
def alarm_messages(draw: st.DrawFn) -> tuple[int, bool, alarms.AlarmMessage]:
    response = draw(st.booleans())
    subfunction = draw(st.sampled_from(sorted(alarms.ALARM_SUBFUNCTIONS)))
    if response:
        objects = tuple(alarms.AlarmObject(0, return_code=code) for code in draw(st.lists(u8, max_size=5)))
    else:
        objects = tuple(draw(st.lists(alarm_objects(), max_size=4)))
    timestamped = not response and subfunction in alarms.TIMESTAMPED | {alarms.SUBFUNCTION_SCAN_IND}
    timestamp = draw(st.one_of(st.none(), moments)) if timestamped else None
    scan = draw(st.binary(min_size=4, max_size=4)) if timestamped and subfunction == alarms.SUBFUNCTION_SCAN_IND else b""
    return subfunction, response, alarms.AlarmMessage(draw(u8), objects, timestamp, timestamped, scan)


@given(st.one_of(st.none(), moments))
def test_timestamp_round_trip(moment: datetime | None) -> None:
    assert alarms.parse_timestamp(alarms.build_timestamp(moment)) == moment


@given(alarm_messages())
def test_alarm_message_round_trip(case: tuple[int, bool, alarms.AlarmMessage]) -> None:
    subfunction, response, message = case
    raw = alarms.build_alarm_message(message)
    assert alarms.parse_alarm_message(raw, subfunction, response=response) == message
    alarms.describe_alarm_message(message)


@given(st.binary(max_size=60), st.sampled_from(sorted(alarms.ALARM_SUBFUNCTIONS)), st.booleans())
def test_alarm_garbage_raises_typed_errors(raw: bytes, subfunction: int, response: bool) -> None:
    try:
        message = alarms.parse_alarm_message(raw, subfunction, response=response)
    except NckError:
        return
    alarms.describe_alarm_message(message)


@given(st.builds(alarms.DiagnosticMessage, u16, u8, u8, u16, u16, u32, st.one_of(st.none(), moments)))
def test_diagnostic_message_round_trip(message: alarms.DiagnosticMessage) -> None:
    raw = alarms.build_diagnostic_message(message)
    assert len(raw) == alarms.DIAGNOSTIC_LENGTH and alarms.parse_diagnostic_message(raw) == message


s7any = st.builds(S7AnyAddress, transport_size=st.sampled_from([0x01, 0x02, 0x04]), count=st.integers(1, 100),
                  db_number=u16, area=st.sampled_from([0x81, 0x82, 0x83, 0x84]), byte_address=st.integers(0, 0xFFFF),
                  bit_address=st.integers(0, 7))
dbread = st.lists(st.tuples(u8, u16, u16), min_size=1, max_size=10).map(
    lambda areas: UnsupportedAddress(0x12, cyclic.SYNTAX_DBREAD, bytes([cyclic.SYNTAX_DBREAD, len(areas)]) + b"".join(
        bytes([count]) + db.to_bytes(2, "big") + start.to_bytes(2, "big") for count, db, start in areas)))


@given(st.builds(cyclic.CyclicSubscription, u8, u8, st.lists(st.one_of(s7any, dbread), max_size=5).map(tuple)))
def test_cyclic_subscription_round_trip(subscription: cyclic.CyclicSubscription) -> None:
    raw = cyclic.build_subscription(subscription)
    assert cyclic.parse_subscription(raw) == subscription
    for item in subscription.items:
        if isinstance(item, UnsupportedAddress):
            assert cyclic.describe_dbread(item)


@given(st.lists(data_items, max_size=6).map(tuple))
def test_cyclic_data_round_trip(items: tuple[DataItem, ...]) -> None:
    assert cyclic.parse_cyclic_data(cyclic.build_cyclic_data(items)) == items


@given(st.binary(max_size=40))
def test_cyclic_garbage_raises_typed_errors(raw: bytes) -> None:
    for parse in (cyclic.parse_subscription, cyclic.parse_cyclic_data):
        try:
            parse(raw)
        except NckError:
            pass


@st.composite
def szl_lists(draw: st.DrawFn) -> szl.SzlList:
    length = draw(st.integers(1, 40))
    records = draw(st.lists(st.binary(min_size=length, max_size=length), max_size=5))
    szl_id = draw(st.sampled_from([0x0000, 0x0011, 0x001C, 0x0131, 0x0232, 0x0424, 0x00A0, 0x0D91]))
    return szl.SzlList(szl_id, draw(u16), length, tuple(records))


@given(szl_lists())
def test_szl_list_round_trip(szl_list: szl.SzlList) -> None:
    raw = szl.build_szl_list(szl_list)
    assert szl.parse_szl_list(raw) == szl_list
    szl.describe_szl_list(szl_list)


@given(st.lists(st.builds(szl.BlockEntry, u16, u8, u8), max_size=8).map(tuple))
def test_blocks_of_type_round_trip(entries: tuple[szl.BlockEntry, ...]) -> None:
    assert szl.parse_blocks_of_type(szl.build_blocks_of_type(entries)) == entries


@given(st.integers(0, 15), u8, st.sampled_from([REQUEST, RESPONSE, PUSH]), st.binary(max_size=60),
       st.booleans())
def test_contents_never_raise(group: int, subfunction: int, stage: str, payload: bytes, long: bool) -> None:
    """Whatever a userdata PDU carries, naming its contents gives a text or nothing, never an exception."""
    header = userdata.UserdataParameter(0x12, 8, group, subfunction, 1, long)
    data = bytes([0xFF, 0x09]) + len(payload).to_bytes(2, "big") + payload
    userdata_contents(header, data, stage, 1, UserdataState(), header if stage == RESPONSE else None, data)


@st.composite
def query_responses(draw: st.DrawFn) -> alarms.AlarmQueryResponse:
    entries = []
    for _ in range(draw(st.integers(0, 4))):
        alarm_type = draw(st.sampled_from([1, 2, alarms.ALARM_TYPE_ALARM_S]))
        stamped = (st.tuples(st.one_of(st.none(), moments), data_items) if alarm_type == alarms.ALARM_TYPE_ALARM_S
                   else st.none())
        # a dataset length of 0 never starts one (an open-ended list ends at a zero byte)
        entries.append(alarms.QueryEntry(alarm_type, draw(u32), draw(u8), draw(u8), draw(u8), draw(st.integers(1, 255)),
                                         draw(st.binary(min_size=3, max_size=3)), draw(stamped), draw(stamped)))
    body = b"".join(alarms.build_alarm_query_response(alarms.AlarmQueryResponse(0, 1, 0xFF, 9, 0, (e,)))[6:]
                    for e in entries)
    open_ended = draw(st.booleans())
    return alarms.AlarmQueryResponse(draw(u8), draw(u8), 0xFF, 0x09, 0xFFFF if open_ended else len(body),
                                     tuple(entries), b"\x00" if open_ended else b"")


@given(query_responses())
def test_alarm_query_response_round_trip(response: alarms.AlarmQueryResponse) -> None:
    raw = alarms.build_alarm_query_response(response)
    assert alarms.parse_alarm_query_response(raw) == response
    alarms.describe_alarm_query_response(response)


@given(st.binary(max_size=60))
def test_alarm_query_response_garbage_raises_typed_errors(raw: bytes) -> None:
    try:
        response = alarms.parse_alarm_query_response(raw)
    except NckError:
        return
    alarms.describe_alarm_query_response(response)  # (not rebuilt: a timestamp's weekday is not kept)
