"""NC program transfer codecs: the fixed frames of ../shared/reference/programs.md §6 (decoded there
by tshark 4.0.17) and round trips of every codec pair."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.protocol import blocks, ncprog, pi, s7
from nckemu.protocol.errors import NckProtocolError
from nckemu.protocol.ncprog import NcData, NcParameter, NcSubfunction, TransferContent

HEADER_UD = "32 07 0000 0001"
CONTENT = (b"00000029" b"240102030405    " b";$PATH=/_N_MPF_DIR\n" b"G0 X0\nM30\n")

# frame number -> S7 PDU (programs.md §6)
FRAMES = {
    1: bytes.fromhex(f"{HEADER_UD} 0008 000F 00011204117F0100 FF09000B") + b"_N_TEST_MPF",
    2: bytes.fromhex(f"{HEADER_UD} 000C 0006 0001120812BF012A00000000 FF0900020800"),
    3: bytes.fromhex(f"{HEADER_UD} 000C 003B 00011208123F022A01000000 FF09003700FB") + CONTENT,
    4: bytes.fromhex(f"{HEADER_UD} 000C 0006 00011208123F032A00000000 FF0900020800"),
    5: bytes.fromhex(f"{HEADER_UD} 0008 0006 00011204117F042A FF0900020000"),
    6: bytes.fromhex(f"{HEADER_UD} 000C 0006 0001120812BF042A00000000 FF0900020000"),
    7: bytes.fromhex(f"{HEADER_UD} 0008 0011 00011204117F0600 FF09000D1400") + b"_N_TEST_MPF",
    9: bytes.fromhex(f"{HEADER_UD} 0008 0006 00011204113F0833 FF0900021400"),
    10: bytes.fromhex(f"{HEADER_UD} 000C 0004 0001120812BF012B0000D401 0A000000"),
}


def _parts(frame: bytes) -> tuple[NcParameter, bytes]:
    pdu = s7.parse_pdu(frame)
    assert s7.build_pdu(pdu) == frame
    parameter = ncprog.parse_nc_parameter(pdu.parameter)
    assert ncprog.build_nc_parameter(parameter) == pdu.parameter
    assert ncprog.is_nc_parameter(pdu.parameter)
    return parameter, pdu.data


def test_request_download_frame_1() -> None:
    parameter, data = _parts(FRAMES[1])
    assert parameter == NcParameter(ncprog.NC_REQUEST, NcSubfunction.REQUEST_DOWNLOAD, 0)
    assert ncprog.parse_name(ncprog.parse_nc_data(data).payload) == "_N_TEST_MPF"
    assert ncprog.build_nc_data(NcData(ncprog.build_name("_N_TEST_MPF"))) == data
    assert ncprog.describe(parameter) == "NC Request -> Request download"


def test_answer_with_window_frame_2_and_continue_download_frame_4() -> None:
    for number, kind, sub in ((2, ncprog.NC_RESPONSE, NcSubfunction.REQUEST_DOWNLOAD),
                              (4, ncprog.NC_PUSH, NcSubfunction.CONTINUE_DOWNLOAD)):
        parameter, data = _parts(FRAMES[number])
        assert parameter == NcParameter(kind, sub, 42, long=True)
        window = ncprog.parse_window(ncprog.parse_nc_data(data).payload)
        assert window == ncprog.Window(8)
        assert ncprog.build_nc_data(NcData(ncprog.build_window(window))) == data


def test_download_block_frame_3_carries_the_content() -> None:
    parameter, data = _parts(FRAMES[3])
    assert parameter == NcParameter(ncprog.NC_PUSH, NcSubfunction.DOWNLOAD_BLOCK, 42, True, 1, 0)
    assert parameter.is_last
    content = ncprog.parse_chunk(ncprog.parse_nc_data(data).payload)
    assert content == CONTENT
    parsed = ncprog.parse_transfer_content(content)
    assert parsed == TransferContent("/_N_MPF_DIR", b"G0 X0\nM30\n", "240102030405    ", 29)
    assert ncprog.build_transfer_content(dataclasses.replace(parsed, length=-1)) == content
    assert ncprog.stamp_of(2024, 1, 2, 3, 4, 5) == "240102030405    "


def test_download_ended_frames_5_and_6() -> None:
    request, data = _parts(FRAMES[5])
    assert request == NcParameter(ncprog.NC_REQUEST, NcSubfunction.DOWNLOAD_ENDED, 42)
    assert ncprog.parse_nc_data(data).payload == b"\x00\x00"
    answer, _ = _parts(FRAMES[6])
    assert answer == NcParameter(ncprog.NC_RESPONSE, NcSubfunction.DOWNLOAD_ENDED, 42, long=True)


def test_start_upload_frame_7_and_continue_upload_frame_9() -> None:
    parameter, data = _parts(FRAMES[7])
    assert parameter == NcParameter(ncprog.NC_REQUEST, NcSubfunction.START_UPLOAD, 0)
    request = ncprog.parse_start_upload(ncprog.parse_nc_data(data).payload)
    assert request == ncprog.StartUpload("_N_TEST_MPF", 20)
    assert ncprog.build_nc_data(NcData(ncprog.build_start_upload(request))) == data
    parameter, data = _parts(FRAMES[9])
    # Continue upload goes out as a push with the short parameter and method 0x11.
    assert parameter == NcParameter(ncprog.NC_PUSH, NcSubfunction.CONTINUE_UPLOAD, 0x33)
    assert ncprog.parse_window(ncprog.parse_nc_data(data).payload) == ncprog.Window(20)


def test_error_answer_frame_10() -> None:
    parameter, data = _parts(FRAMES[10])
    assert parameter.error_code == 0xD401 and parameter.sequence == 0x2B
    assert data == ncprog.ERROR_DATA
    assert ncprog.parse_nc_data(data) == NcData(b"", 0x0A, 0x00)


def test_plc_block_path_frames_11_to_15() -> None:
    start = bytes.fromhex("1D 00 0000 00000000 0B") + b"_N_TEST_MPF"
    control = blocks.parse_block_control(start)
    assert control == blocks.BlockControl(0x1D, 0, 0, 0, "_N_TEST_MPF")
    assert blocks.build_block_control(control) == start
    answer = bytes.fromhex("1D 00 0000 00000007 07") + b"0000042"
    assert blocks.parse_block_control(answer) == blocks.BlockControl(0x1D, 0, 0, 7, "0000042")
    assert blocks.parse_block_control(bytes.fromhex("1E00000000000007")).session == 7
    data = bytes.fromhex("000A00FB") + b"0123456789"
    assert ncprog.parse_upload_data(data) == ncprog.UploadData(b"0123456789")
    assert ncprog.build_upload_data(ncprog.UploadData(b"0123456789")) == data
    assert blocks.parse_block_control(bytes.fromhex("1F00000000000007")).function == 0x1F


def test_pi_xfer_frame_16() -> None:
    parameter = (bytes.fromhex("28 00 00 00 00 00 00 FD 00 1C 03") + b"P01" + b"\x17/_N_MPF_DIR/_N_TEST_MPF"
                 + b"\x09_N_F_XFER")
    request = pi.parse_pi_request(parameter)
    assert request.service == "_N_F_XFER" and request.arguments == ("P01", "/_N_MPF_DIR/_N_TEST_MPF")
    assert pi.build_pi_request(request) == parameter


@pytest.mark.parametrize("content", [
    b"0000002",  # shorter than the header
    b"0000002X" + b" " * 16 + b";$PATH=/A\n",  # length not digits
    b"00000099" + b" " * 16 + b";$PATH=/A\n",  # length not the bytes that follow
    b"00000003" + b" " * 16 + b"abc",  # no $PATH line
    b"00000011" + b" " * 16 + b";$PATH=/A\r\n",  # CR LF ends the path line
])
def test_bad_transfer_content_is_refused(content: bytes) -> None:
    with pytest.raises(NckProtocolError):
        ncprog.parse_transfer_content(content)


@pytest.mark.parametrize("parameter", [b"\x00\x01\x12\x04\x11\x44\x01\x00", b"\x00\x01\x12\x08\x11\x7F\x01\x00",
                                       b"\x00\x01", b"\x00\x01\x13\x04\x11\x7F\x01\x00"])
def test_bad_parameters_are_refused(parameter: bytes) -> None:
    with pytest.raises(NckProtocolError):
        ncprog.parse_nc_parameter(parameter)


BYTE = st.integers(0, 255)


@given(st.sampled_from(sorted(ncprog.NC_TYPES)), BYTE, BYTE, st.booleans(), BYTE, BYTE, st.integers(0, 0xFFFF),
       st.sampled_from([None, 0x11, 0x12]))
def test_parameter_round_trip(kind: int, sub: int, seq: int, long: bool, ref: int, last: int, error: int,
                              method: int | None) -> None:
    parameter = NcParameter(kind, sub, seq, long, ref if long else 0, last if long else 0,
                            error if long else 0, method)
    raw = ncprog.build_nc_parameter(parameter)
    parsed = ncprog.parse_nc_parameter(raw)
    assert parsed.wire_method == parameter.wire_method
    assert parsed == dataclasses.replace(parameter, method=parsed.method)
    assert ncprog.build_nc_parameter(parsed) == raw


@given(st.binary(max_size=600), BYTE, BYTE)
def test_data_round_trip(payload: bytes, return_code: int, transport_size: int) -> None:
    data = NcData(payload, return_code, transport_size)
    assert ncprog.parse_nc_data(ncprog.build_nc_data(data)) == data


PATHS = st.from_regex(r"/_N_[A-Z]{1,8}_DIR(/_N_[A-Z0-9]{1,8}_WPD)?", fullmatch=True)
STAMPS = st.text(st.characters(min_codepoint=32, max_codepoint=126), min_size=16, max_size=16)


@given(PATHS, st.binary(max_size=2000), STAMPS, st.booleans())
def test_content_round_trip(path: str, text: bytes, stamp: str, spaces: bool) -> None:
    content = TransferContent(path, text, stamp, None if spaces else -1)
    raw = ncprog.build_transfer_content(content)
    parsed = ncprog.parse_transfer_content(raw)
    assert parsed == dataclasses.replace(content, length=None if spaces else len(raw) - 24)
    assert ncprog.build_transfer_content(parsed) == raw


@given(st.from_regex(r"_N_[A-Z0-9_]{1,20}", fullmatch=True), BYTE, BYTE)
def test_start_upload_and_window_round_trip(name: str, window: int, extra: int) -> None:
    request = ncprog.StartUpload(name, window, extra)
    assert ncprog.parse_start_upload(ncprog.build_start_upload(request)) == request
    assert ncprog.parse_window(ncprog.build_window(ncprog.Window(window, extra))) == ncprog.Window(window, extra)
    assert ncprog.parse_name(ncprog.build_name(name)) == name


@given(st.binary(max_size=3000), st.integers(1, 1000))
def test_chunks_and_upload_data_round_trip(content: bytes, room: int) -> None:
    pieces = ncprog.split_content(content, room)
    assert b"".join(pieces) == content and all(len(piece) <= room for piece in pieces)
    for piece in pieces:
        assert ncprog.parse_chunk(ncprog.build_chunk(piece)) == piece
        assert ncprog.parse_upload_data(ncprog.build_upload_data(ncprog.UploadData(piece))).content == piece
