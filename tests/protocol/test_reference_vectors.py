"""Fixed byte vectors from ../shared/reference/protocol.md §9 (checked there against tshark 4.0.17)."""

from __future__ import annotations

import struct

import pytest

from nckemu.errors import NckTypeInconsistent
from nckemu.protocol import cotp, pi, s7, tpkt
from nckemu.protocol.addresses import NckAddress, NckType, S7AnyAddress
from nckemu.protocol.errors import NckProtocolError
from nckemu.protocol.values import decode_nck_values, encode_nck_values

CR = bytes.fromhex("0300001611E00000000100C0010AC1020100C2020103")
SETUP_JOB = bytes.fromhex("0300001902F08032010000000100080000F0000001000101E0")
NCK_READ_2 = bytes.fromhex("32010000000200160000040212088241000100011501120882014" "66E00011A01")
MIXED = bytes.fromhex("12088264AB7C00011601" "120883614E7000011A01" "12088 4A100250001 8201".replace(" ", ""))


def test_connect_request_round_trip() -> None:
    request = cotp.parse_cotp(tpkt.parse_tpkt(CR))
    assert request == cotp.ConnectRequest(src_ref=1, calling_tsap=b"\x01\x00", called_tsap=b"\x01\x03",
                                           tpdu_size=1024)
    assert cotp.build_frame(request) == CR


def test_setup_job_round_trip() -> None:
    payload = cotp.parse_cotp(tpkt.parse_tpkt(SETUP_JOB))
    assert isinstance(payload, cotp.DataTpdu) and payload.eot
    pdu = s7.parse_pdu(payload.payload)
    assert s7.parse_setup_communication(pdu.parameter) == s7.SetupCommunication(1, 1, 480)
    assert tpkt.build_tpkt(cotp.build_cotp(payload)) == SETUP_JOB


def test_nck_read_job_with_two_items() -> None:
    pdu = s7.parse_pdu(NCK_READ_2)
    request = s7.parse_read_var_request(pdu.parameter)
    assert request.items == (NckAddress(2, 1, 1, 1, 0x15, 1), NckAddress(0, 1, 18030, 1, 0x1A, 1))
    assert s7.build_pdu(s7.S7Pdu(1, 2, s7.build_read_var_request(request))) == NCK_READ_2


def test_seed000_sd43900_item_and_real8_answer() -> None:
    item = s7.build_item(NckAddress(3, 4, 0xAB7C, 1, 0x16, 1))
    assert item == bytes.fromhex("12088264AB7C00011601")
    parameter, data = s7.build_read_var_response(s7.ReadVarResponse((
        s7.DataItem(0xFF, 0x09, encode_nck_values(NckType.REAL8, [0.3], area=3)),)))
    assert parameter == b"\x04\x01" and data == bytes.fromhex("FF090008") + struct.pack("<d", 0.3)


def test_mixed_syntax_items_parse() -> None:
    request = s7.parse_read_var_request(b"\x04\x03" + MIXED)
    assert request.items[1] == NckAddress(3, 1, 0x4E70, 1, 0x1A, 1, syntax_id=0x83)
    assert request.items[2] == NckAddress(5, 1, 0x25, 1, 0x82, 1, syntax_id=0x84)


def test_s7any_item_round_trip() -> None:
    address = S7AnyAddress(transport_size=2, count=4, db_number=130, area=0x84, byte_address=10, bit_address=0)
    encoded = s7.build_item(address)
    assert encoded == bytes.fromhex("120A10020004008284000050")
    assert s7.parse_read_var_request(b"\x04\x01" + encoded).items == (address,)


def test_error_item_and_multi_line_answer() -> None:
    answer = s7.parse_read_var_response(b"\x04\x02", bytes.fromhex("0A000000") + bytes.fromhex("FF090018") + bytes(24))
    assert answer.items[0] == s7.DataItem(0x0A, 0, b"")
    assert len(answer.items[1].data) == 24


def test_ack_data_header_error() -> None:
    raw = bytes.fromhex("320300000005000100008500") + b"\x28"
    pdu = s7.parse_pdu(raw)
    assert (pdu.error_class, pdu.error_code, pdu.parameter) == (0x85, 0x00, b"\x28")
    assert s7.build_pdu(pdu) == raw


def test_pi_select_matches_the_reference_frame() -> None:
    request = pi.PiServiceRequest("_N_SELECT", ("201", "/_N_MPF_DIR/_N_TEST_MPF"))
    encoded = pi.build_pi_request(request)
    assert encoded[:12] == bytes.fromhex("28000000000000FD001C0332")
    assert encoded.endswith(b"\x09_N_SELECT")
    assert pi.parse_pi_request(encoded) == request


def test_values_little_endian_except_drive_areas() -> None:
    assert encode_nck_values(NckType.REAL8, [139.4], area=2) == bytes.fromhex("CDCCCCCCCC6C6140")
    assert encode_nck_values(NckType.WORD, [2], area=2) == b"\x02\x00"
    assert encode_nck_values(NckType.WORD, [2], area=5) == b"\x00\x02"
    assert decode_nck_values(NckType.STRING, b"/_N_MPF0" + bytes(24), area=2, string_length=32) == ["/_N_MPF0"]
    with pytest.raises(NckTypeInconsistent):
        decode_nck_values(NckType.REAL8, bytes(7), area=3)


def test_truncated_pdu_is_a_protocol_error() -> None:
    with pytest.raises(NckProtocolError):
        s7.parse_pdu(NCK_READ_2[:-1])
    with pytest.raises(NckProtocolError):
        tpkt.split_frames(b"\x04\x00\x00\x10" + bytes(12))
