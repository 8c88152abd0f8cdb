"""Every codec: parse(build(v)) == v, build(parse(x)) == x, and garbage raises only our typed errors."""

from __future__ import annotations

import math
import struct
from collections.abc import Callable

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from nckemu.errors import NckItemError
from nckemu.protocol import c840, cotp, db41, pi, s7, szl, tpkt
from nckemu.protocol.addresses import NckAddress, NckType, S7AnyAddress, UnsupportedAddress
from nckemu.protocol.errors import NckProtocolError
from nckemu.protocol.values import decode_nck_values, encode_nck_values

u8 = st.integers(0, 0xFF)
u16 = st.integers(0, 0xFFFF)

nck_addresses = st.builds(NckAddress, area=st.integers(0, 7), unit=st.integers(0, 31), column=u16, line=u16,
                          module=u8, line_count=u8, syntax_id=st.sampled_from([0x82, 0x83, 0x84]))
s7any_addresses = st.builds(S7AnyAddress, transport_size=u8, count=u16, db_number=u16, area=u8,
                            byte_address=st.integers(0, 0x1FFFFF), bit_address=st.integers(0, 7))
unsupported = st.builds(UnsupportedAddress, var_spec=st.just(0x12),
                        syntax_id=st.sampled_from([0xA2, 0xB0, 0x13, 0x15]),
                        raw=st.binary(min_size=1, max_size=20)).map(
    lambda a: UnsupportedAddress(a.var_spec, a.syntax_id, bytes([a.syntax_id]) + a.raw[1:]))
addresses = st.one_of(nck_addresses, s7any_addresses, unsupported)


def data_items() -> st.SearchStrategy[s7.DataItem]:
    octets = st.builds(s7.DataItem, return_code=st.sampled_from([0x00, 0xFF]), transport_size=st.just(0x09),
                       data=st.binary(max_size=40))
    bytes_as_bits = st.builds(s7.DataItem, return_code=st.just(0xFF), transport_size=st.just(0x04),
                              data=st.binary(max_size=40))
    errors = st.builds(s7.DataItem, return_code=st.sampled_from([0x01, 0x03, 0x05, 0x06, 0x07, 0x0A]),
                       transport_size=st.just(0), data=st.just(b""))
    return st.one_of(octets, bytes_as_bits, errors)


def only_typed_errors(parse: Callable[[bytes], object], data: bytes) -> None:
    try:
        parse(data)
    except (NckProtocolError, NckItemError):
        pass


@given(st.binary(max_size=300))
def test_tpkt_round_trip(payload: bytes) -> None:
    frame = tpkt.build_tpkt(payload)
    assert tpkt.parse_tpkt(frame) == payload
    if len(frame) >= tpkt.MIN_FRAME_BYTES:
        frames, rest = tpkt.split_frames(frame + frame[:3])
        assert frames == [frame] and rest == frame[:3]


connect_fields = dict(src_ref=u16, dst_ref=u16, class_option=u8,
                      calling_tsap=st.none() | st.binary(min_size=2, max_size=2),
                      called_tsap=st.none() | st.binary(min_size=2, max_size=2),
                      tpdu_size=st.none() | st.sampled_from([128, 256, 512, 1024, 2048, 4096, 8192]))
cotp_tpdus = st.one_of(
    st.builds(cotp.ConnectRequest, **connect_fields), st.builds(cotp.ConnectConfirm, **connect_fields),
    st.builds(cotp.DataTpdu, payload=st.binary(max_size=100), eot=st.booleans(), tpdu_number=st.integers(0, 127)),
    st.builds(cotp.DisconnectRequest, dst_ref=u16, src_ref=u16, reason=u8),
    st.builds(cotp.DisconnectConfirm, dst_ref=u16, src_ref=u16),
    st.builds(cotp.TpduError, dst_ref=u16, reject_cause=u8),
)


@given(cotp_tpdus)
def test_cotp_round_trip(tpdu: cotp.Cotp) -> None:
    encoded = cotp.build_cotp(tpdu)
    assert cotp.parse_cotp(encoded) == tpdu
    assert cotp.build_cotp(cotp.parse_cotp(encoded)) == encoded


@given(st.builds(cotp.ConnectRequest, **connect_fields))
def test_cotp_fast_path_agrees_with_the_construct_declaration(request: cotp.ConnectRequest) -> None:
    declared = cotp.CONNECT_TPDU.parse(cotp.build_cotp(request))
    assert (declared.code, declared.dst_ref, declared.src_ref) == (cotp.CODE_CR, request.dst_ref, request.src_ref)
    parameters = {p.code: p.value for p in declared.parameters}
    assert parameters.get(cotp.PARAM_CALLED_TSAP) == request.called_tsap


pdus = st.builds(s7.S7Pdu, rosctr=st.sampled_from([1, 2, 3, 7]), pdu_ref=u16, parameter=st.binary(max_size=60),
                 data=st.binary(max_size=60), error_class=u8, error_code=u8).map(
    lambda p: p if p.rosctr in (2, 3) else s7.S7Pdu(p.rosctr, p.pdu_ref, p.parameter, p.data))


@given(pdus)
def test_pdu_round_trip_and_declaration(pdu: s7.S7Pdu) -> None:
    raw = s7.build_pdu(pdu)
    assert s7.parse_pdu(raw) == pdu
    declared = s7.HEADER.parse(raw)
    assert (declared.pdu_ref, declared.parameter, declared.data) == (pdu.pdu_ref, pdu.parameter, pdu.data)


@given(st.builds(s7.SetupCommunication, u16, u16, u16))
def test_setup_round_trip(setup: s7.SetupCommunication) -> None:
    assert s7.parse_setup_communication(s7.build_setup_communication(setup)) == setup


@given(st.lists(addresses, min_size=1, max_size=20))
def test_read_request_round_trip_with_mixed_items(items: list[object]) -> None:
    request = s7.ReadVarRequest(tuple(items))  # type: ignore[arg-type]
    encoded = s7.build_read_var_request(request)
    assert s7.parse_read_var_request(encoded) == request
    assert s7.build_read_var_request(s7.parse_read_var_request(encoded)) == encoded


@given(nck_addresses)
def test_nck_item_agrees_with_the_construct_declaration(address: NckAddress) -> None:
    declared = s7.NCK_ITEM.parse(s7.build_item(address))
    assert (declared.area_unit >> 5, declared.area_unit & 31, declared.column, declared.line,
            declared.module, declared.line_count) == (address.area, address.unit, address.column,
                                                      address.line, address.module, address.line_count)


@given(st.lists(data_items(), min_size=1, max_size=12))
def test_read_response_round_trip(items: list[s7.DataItem]) -> None:
    response = s7.ReadVarResponse(tuple(items))
    parameter, data = s7.build_read_var_response(response)
    assert s7.parse_read_var_response(parameter, data) == response


@given(st.lists(st.tuples(addresses, data_items()), min_size=1, max_size=10))
def test_write_request_and_response_round_trip(pairs: list[tuple[object, s7.DataItem]]) -> None:
    request = s7.WriteVarRequest(tuple(p[0] for p in pairs), tuple(p[1] for p in pairs))  # type: ignore[arg-type]
    assert s7.parse_write_var_request(*s7.build_write_var_request(request)) == request
    response = s7.WriteVarResponse(tuple(0xFF if i % 2 else 0x0A for i in range(len(pairs))))
    assert s7.parse_write_var_response(*s7.build_write_var_response(response)) == response


ascii_text = st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=40)


@given(st.sampled_from(sorted(n for n in pi.PI_SERVICES if n.startswith("_N_"))), st.lists(ascii_text, max_size=6))
def test_pi_round_trip(service: str, arguments: list[str]) -> None:
    request = pi.PiServiceRequest(service, tuple(arguments))
    encoded = pi.build_pi_request(request)
    assert pi.parse_pi_request(encoded) == request
    declared = pi.PI_JOB.parse(encoded)
    assert declared.service == service


@given(st.none() | u8)
def test_pi_response_round_trip(status: int | None) -> None:
    response = pi.PiServiceResponse(status)
    assert pi.parse_pi_response(pi.build_pi_response(response)) == response


@given(u16, u16, u8)
def test_szl_request_round_trip(szl_id: int, index: int, sequence: int) -> None:
    request = szl.SzlReadRequest(szl_id, index, sequence)
    assert szl.parse_szl_request(*szl.build_szl_request(request)) == request
    body = bytes(4) + b"records"
    response = szl.parse_szl_response(*szl.build_szl_response(request, szl_id.to_bytes(2, "big")
                                                                + index.to_bytes(2, "big") + body))
    assert (response.szl_id, response.szl_index, response.payload) == (szl_id, index, body)


finite = st.floats(allow_nan=False, allow_infinity=False)
VALUE_STRATEGIES = {
    NckType.BOOL: st.booleans(), NckType.BYTE: st.integers(0, 255), NckType.WORD: u16,
    NckType.INT: st.integers(-(2**15), 2**15 - 1), NckType.DWORD: st.integers(0, 2**32 - 1),
    NckType.DINT: st.integers(-(2**31), 2**31 - 1), NckType.INT64: st.integers(-(2**63), 2**63 - 1),
    NckType.REAL8: finite, NckType.REAL4: finite.map(lambda v: struct.unpack("<f", struct.pack("<f", v))[0]
                                                     if abs(v) < 3e38 else 0.0),
}


@given(st.sampled_from(sorted(VALUE_STRATEGIES)), st.integers(0, 7), st.data())
def test_nck_values_round_trip(nck_type: NckType, area: int, data: st.DataObject) -> None:
    values = data.draw(st.lists(VALUE_STRATEGIES[nck_type], min_size=1, max_size=5))
    encoded = encode_nck_values(nck_type, values, area=area)
    decoded = decode_nck_values(nck_type, encoded, area=area, line_count=len(values))
    assert decoded == values or all(math.isclose(a, b) for a, b in zip(decoded, values, strict=True))


@given(st.lists(st.text(st.characters(min_codepoint=33, max_codepoint=126), max_size=16), min_size=1, max_size=3))
def test_nck_strings_round_trip(values: list[str]) -> None:
    encoded = encode_nck_values(NckType.STRING, values, area=2, string_length=16)
    assert decode_nck_values(NckType.STRING, encoded, area=2, line_count=len(values), string_length=16) == values


user_dbs = st.builds(c840.TempCompUserDb, axis=st.integers(1, 30), position_independent=st.booleans(),
                     position_dependent=st.booleans(), k_tcabs_units=st.integers(-c840.MAX_UNITS, c840.MAX_UNITS),
                     tan_beta_raw=st.integers(-c840.TAN_BETA_SCALE, c840.TAN_BETA_SCALE),
                     p0_units=st.integers(-c840.MAX_UNITS, c840.MAX_UNITS))
layouts = st.builds(c840.C840Layout, high_word_first=st.booleans(),
                    u_bit=st.sampled_from([15, 9]), a_bit=st.sampled_from([14, 8]))


@given(user_dbs, layouts)
def test_840c_user_db_round_trip(db: c840.TempCompUserDb, layout: c840.C840Layout) -> None:
    encoded = c840.build_user_db(db, layout)
    assert c840.parse_user_db(encoded, layout) == db
    assert c840.build_user_db(c840.parse_user_db(encoded, layout), layout) == encoded


@given(u16, u16, st.booleans())
def test_db41_request_round_trip(user_db: int, data_word: int, request: bool) -> None:
    status = db41.parse_status(db41.build_request(user_db, data_word, request=request))
    assert (status.user_db, status.data_word, status.request, status.function) == (user_db, data_word, request, 9)


PARSERS: dict[str, Callable[[bytes], object]] = {
    "tpkt.parse_tpkt": tpkt.parse_tpkt,
    "tpkt.split_frames": tpkt.split_frames,
    "cotp.parse_cotp": cotp.parse_cotp,
    "s7.parse_pdu": s7.parse_pdu,
    "s7.parse_setup_communication": s7.parse_setup_communication,
    "s7.parse_read_var_request": s7.parse_read_var_request,
    "s7.parse_read_var_response": lambda b: s7.parse_read_var_response(b[:2], b[2:]),
    "s7.parse_write_var_request": lambda b: s7.parse_write_var_request(b[:24], b[24:]),
    "s7.parse_write_var_response": lambda b: s7.parse_write_var_response(b[:2], b[2:]),
    "pi.parse_pi_request": pi.parse_pi_request,
    "pi.parse_pi_response": pi.parse_pi_response,
    "pi.parse_plc_stop_request": pi.parse_plc_stop_request,
    "szl.parse_szl_request": lambda b: szl.parse_szl_request(b[:8], b[8:]),
    "szl.parse_szl_response": lambda b: szl.parse_szl_response(b[:12], b[12:]),
    "c840.parse_user_db": c840.parse_user_db,
    "values.decode REAL8": lambda b: decode_nck_values(NckType.REAL8, b, area=3, line_count=2),
}


@pytest.mark.parametrize("name", sorted(PARSERS))
@given(data=st.binary(max_size=120))
def test_random_bytes_raise_only_typed_errors(name: str, data: bytes) -> None:
    only_typed_errors(PARSERS[name], data)


@given(st.lists(addresses, min_size=1, max_size=6), st.data())
def test_truncated_valid_requests_raise_only_typed_errors(items: list[object], data: st.DataObject) -> None:
    encoded = s7.build_read_var_request(s7.ReadVarRequest(tuple(items)))  # type: ignore[arg-type]
    cut = data.draw(st.integers(0, len(encoded) - 1))
    assume(cut < len(encoded))
    with pytest.raises(NckProtocolError):
        s7.parse_read_var_request(encoded[:cut])


# ---------------------------------------------------------------- whole-PDU peeks of the hot path
_any_pdu = st.builds(
    lambda rosctr, ref, parameter, data, error: s7.build_pdu(
        s7.S7Pdu(rosctr, ref, parameter, data, error >> 8, error & 0xFF)),
    st.sampled_from([s7.Rosctr.JOB, s7.Rosctr.ACK_DATA, s7.Rosctr.USERDATA]), st.integers(0, 0xFFFF),
    st.one_of(st.binary(max_size=20), st.builds(lambda n, rest: bytes([s7.Function.READ_VAR, n]) + rest,
                                                st.integers(0, 255), st.binary(max_size=20))),
    st.binary(max_size=12), st.sampled_from([0, 0x8500]))


@given(_any_pdu, st.binary(max_size=3))
def test_peek_read_var_job_agrees_with_parse_pdu(pdu: bytes, prefix: bytes) -> None:
    peeked = s7.peek_read_var_job(prefix + pdu, len(prefix))
    parsed = s7.parse_pdu(pdu)
    expected = parsed.rosctr == s7.Rosctr.JOB and not parsed.data and len(parsed.parameter) >= 2 \
        and parsed.parameter[0] == s7.Function.READ_VAR
    assert (peeked is not None) == expected
    if peeked is not None:
        assert peeked == (parsed.pdu_ref, parsed.parameter)


@given(_any_pdu)
def test_peek_read_var_answer_agrees_with_parse_pdu(pdu: bytes) -> None:
    parsed = s7.parse_pdu(pdu)
    expected = parsed.rosctr == s7.Rosctr.ACK_DATA and not parsed.error_class and not parsed.error_code \
        and len(parsed.parameter) == 2 and parsed.parameter[0] == s7.Function.READ_VAR
    count = s7.peek_read_var_answer(pdu)
    assert (count is not None) == expected
    if count is not None:
        assert count == parsed.parameter[1] and pdu[s7.READ_ANSWER_DATA_OFFSET:] == parsed.data


@given(st.integers(0, 0xFFFF), st.integers(0, 255), st.binary(max_size=40))
def test_build_read_var_answer_is_the_general_build(pdu_ref: int, count: int, data: bytes) -> None:
    general = s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu_ref, bytes([s7.Function.READ_VAR, count]), data))
    assert s7.build_read_var_answer(pdu_ref, count, data) == general


@given(st.dictionaries(st.sampled_from(szl.BLOCK_TYPES), st.integers(0, 0xFFFF)))
def test_block_counts_round_trip(counts: dict[int, int]) -> None:
    """The "list blocks" answer carries all seven block types; a type not given counts 0."""
    parsed = szl.parse_block_counts(szl.build_block_counts(counts))
    assert parsed == {block_type: counts.get(block_type, 0) for block_type in szl.BLOCK_TYPES}


@given(st.binary(max_size=40))
def test_block_counts_from_random_bytes_raise_only_typed_errors(data: bytes) -> None:
    try:
        szl.parse_block_counts(data)
    except NckProtocolError:
        pass
