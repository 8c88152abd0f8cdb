"""The NC transfer state machine without sockets: a download is stored whole at "download ended" or
not at all, windows come where libnodave waits for them, uploads give back what was stored."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.emulator.faces.s7.nc_transfer import DOWNLOAD_WINDOW, NcTransfers
from nckemu.emulator.machine.nck.programs import Programs
from nckemu.protocol import ncprog, s7
from nckemu.protocol.ncprog import NcData, NcParameter, NcSubfunction

PATH = "/_N_MPF_DIR/_N_TEST_MPF"


def _pdu(parameter: NcParameter, payload: bytes) -> s7.S7Pdu:
    return s7.S7Pdu(s7.Rosctr.USERDATA, 1, ncprog.build_nc_parameter(parameter), ncprog.build_nc_data(NcData(payload)))


def _request_download(nc: NcTransfers, name: str = "_N_TEST_MPF") -> int:
    (answer,) = nc.userdata(_pdu(NcParameter(ncprog.NC_REQUEST, NcSubfunction.REQUEST_DOWNLOAD), name.encode()), 240)
    parameter = ncprog.parse_nc_parameter(answer.parameter)
    assert parameter.error_code == 0
    assert ncprog.parse_window(ncprog.parse_nc_data(answer.data).payload).count == DOWNLOAD_WINDOW
    return parameter.sequence


def _blocks(nc: NcTransfers, sequence: int, pieces: list[bytes], upto: int) -> int:
    """Send the first ``upto`` blocks; the number of continue-download pushes the NC answered."""
    pushes = 0
    for index, piece in enumerate(pieces[:upto]):
        last = index == len(pieces) - 1
        answers = nc.userdata(_pdu(NcParameter(
            ncprog.NC_PUSH, NcSubfunction.DOWNLOAD_BLOCK, sequence, True, index + 1,
            ncprog.LAST_DATA_UNIT if last else ncprog.MORE_DATA_UNITS), ncprog.build_chunk(piece)), 240)
        expected = not last and (index + 1) % DOWNLOAD_WINDOW == 0
        assert len(answers) == int(expected)
        for answer in answers:
            parameter = ncprog.parse_nc_parameter(answer.parameter)
            assert (parameter.type, parameter.subfunction) == (ncprog.NC_PUSH, NcSubfunction.CONTINUE_DOWNLOAD)
            assert len(answer.data) == 6  # libnodave requires exactly this
        pushes += len(answers)
    return pushes


def _ended(nc: NcTransfers, sequence: int) -> int:
    (answer,) = nc.userdata(_pdu(NcParameter(ncprog.NC_REQUEST, NcSubfunction.DOWNLOAD_ENDED, sequence), b"\0\0"), 240)
    return ncprog.parse_nc_parameter(answer.parameter).error_code


def _upload(nc: NcTransfers, name: str, pdu_size: int, window: int) -> bytes:
    request = ncprog.build_start_upload(ncprog.StartUpload(name, window))
    answers = nc.userdata(_pdu(NcParameter(ncprog.NC_REQUEST, NcSubfunction.START_UPLOAD), request), pdu_size)
    pieces, last = [], False
    while True:
        assert 1 <= len(answers) <= window + 1
        for answer in answers:
            assert len(s7.build_pdu(answer)) <= pdu_size
            parameter = ncprog.parse_nc_parameter(answer.parameter)
            assert parameter.error_code == 0
            pieces.append(ncprog.parse_chunk(ncprog.parse_nc_data(answer.data).payload))
            last = parameter.is_last
        if last:
            break
        answers = nc.userdata(_pdu(NcParameter(ncprog.NC_PUSH, NcSubfunction.CONTINUE_UPLOAD, parameter.sequence),
                                   ncprog.build_window(ncprog.Window(window))), pdu_size)
    return b"".join(pieces)


@settings(max_examples=60, deadline=None)
@given(text=st.binary(max_size=6000), old=st.binary(max_size=200), cut=st.none() | st.integers(0, 40),
       new_request=st.booleans())
def test_a_download_is_stored_whole_at_its_end_or_not_at_all(text: bytes, old: bytes, cut: int | None,
                                                            new_request: bool) -> None:
    programs = Programs()
    programs.write(PATH, old)
    nc = NcTransfers(programs)
    sequence = _request_download(nc)
    content = ncprog.build_transfer_content(ncprog.TransferContent("/_N_MPF_DIR", text, "240102030405    "))
    pieces = ncprog.split_content(content, 240 - ncprog.BLOCK_OVERHEAD)
    upto = len(pieces) if cut is None else min(cut, len(pieces))
    pushes = _blocks(nc, sequence, pieces, upto)
    assert pushes == sum(1 for i in range(1, upto + 1) if i % DOWNLOAD_WINDOW == 0 and i < len(pieces))
    if upto == len(pieces) and cut is None:
        assert _ended(nc, sequence) == 0
        assert programs.read(PATH) == text and programs.stamps[PATH] == "240102030405    "
    else:
        if new_request:  # the client starts again: the half transfer is dropped
            _request_download(nc)
            assert _ended(nc, sequence) == ncprog.ERROR_SEQUENCE
        assert programs.read(PATH) == old  # a connection lost now leaves it so too


@settings(max_examples=60, deadline=None)
@given(text=st.binary(max_size=20000), pdu_size=st.integers(240, 960), window=st.integers(1, 30))
def test_an_upload_gives_back_what_was_stored(text: bytes, pdu_size: int, window: int) -> None:
    programs = Programs()
    programs.write(PATH, text)
    nc = NcTransfers(programs)
    content = ncprog.parse_transfer_content(_upload(nc, "_N_TEST_MPF", pdu_size, window))
    assert content.text == text and content.path == "/_N_MPF_DIR"


def test_refusals_carry_their_codes() -> None:
    programs = Programs()
    nc = NcTransfers(programs, store_bytes=100)
    (answer,) = nc.userdata(_pdu(NcParameter(ncprog.NC_REQUEST, NcSubfunction.REQUEST_DOWNLOAD), b"../x"), 240)
    assert ncprog.parse_nc_parameter(answer.parameter).error_code == ncprog.ERROR_NOT_A_FILE_NAME
    assert answer.data == ncprog.ERROR_DATA
    sequence = _request_download(nc)
    content = ncprog.build_transfer_content(ncprog.TransferContent("/_N_MPF_DIR", b"x" * 500))
    _blocks(nc, sequence, ncprog.split_content(content, 212), 99)
    assert _ended(nc, sequence) == ncprog.ERROR_STORE_FULL
    assert not programs.texts
    sequence = _request_download(nc)
    _blocks(nc, sequence, [b"not a transfer header"], 1)
    assert _ended(nc, sequence) == ncprog.ERROR_BAD_CONTENT
    programs.running = PATH
    sequence = _request_download(nc)
    _blocks(nc, sequence, [ncprog.build_transfer_content(ncprog.TransferContent("/_N_MPF_DIR", b"M30\n"))], 1)
    assert _ended(nc, sequence) == ncprog.ERROR_IN_USE
    request = ncprog.build_start_upload(ncprog.StartUpload("_N_NONE_MPF"))
    (answer,) = nc.userdata(_pdu(NcParameter(ncprog.NC_REQUEST, NcSubfunction.START_UPLOAD), request), 240)
    assert ncprog.parse_nc_parameter(answer.parameter).error_code == ncprog.ERROR_NO_SUCH_FILE


def test_directory_listing_and_marks() -> None:
    programs = Programs()
    programs.write("/_N_WKS_DIR/_N_PART_WPD/_N_PART_MPF", b"M30\n")
    nc = NcTransfers(programs)
    listing = ncprog.parse_transfer_content(_upload(nc, "_n_wks_dir", 240, 20))
    assert listing.length is None and listing.path == "/_N_WKS_DIR" and listing.text == b"_N_PART_WPD 0\n"
    listing = ncprog.parse_transfer_content(_upload(nc, "_N_PART_WPD", 240, 20))
    assert listing.text == b"_N_PART_MPF 4\n"
    programs.mark_for_transfer("/_N_WKS_DIR/_N_PART_WPD/_N_PART_MPF")
    assert ncprog.parse_transfer_content(_upload(nc, "_N_PART_MPF", 240, 20)).text == b"M30\n"
