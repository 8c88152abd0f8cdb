"""The sans-IO session driven with hand-built frames (bytes from the reference sheets, not our encoder)."""

from __future__ import annotations

import struct

import pytest

from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits
from nckemu.emulator.machine.core import Emulator

CR_NCK = bytes.fromhex("0300001611E00000000100C0010AC1020100C2020104")
CR_828D = bytes.fromhex("0300001611E00000004800C1020400C2020D04C0010A")


def dt(s7_pdu: bytes, eot: bool = True) -> bytes:
    cotp = bytes([0x02, 0xF0, 0x80 if eot else 0x00])
    return struct.pack(">BBH", 3, 0, 4 + len(cotp) + len(s7_pdu)) + cotp + s7_pdu


def job(pdu_ref: int, parameter: bytes, data: bytes = b"") -> bytes:
    return struct.pack(">BBHHHH", 0x32, 1, 0, pdu_ref, len(parameter), len(data)) + parameter + data


SETUP_960 = job(1, bytes.fromhex("F000000800080 3C0".replace(" ", "")))
SD43900_AX4 = bytes.fromhex("12088264AB7C00011601")


def s7_of(frame: bytes) -> bytes:
    assert frame[:2] == b"\x03\x00" and frame[5] == 0xF0
    return frame[7:]


def header_error(answer: bytes) -> tuple[int, int]:
    assert answer[1] == 3
    return answer[10], answer[11]


@pytest.fixture
def session() -> ServerSession:
    emulator = Emulator()
    return ServerSession(Dispatcher.for_machine(emulator), limits=SessionLimits(pdu_size_max=960, max_amq=8),
                         peer="test")


def connected(session: ServerSession) -> ServerSession:
    (cc,) = session.receive(CR_NCK)
    assert cc[5] == 0xD0
    (setup,) = session.receive(dt(SETUP_960))
    assert s7_of(setup)[12:] == bytes.fromhex("F00000080008 03C0".replace(" ", ""))
    return session


def test_connect_confirm_echoes_tsaps_and_reference(session: ServerSession) -> None:
    (cc,) = session.receive(CR_NCK)
    assert cc[:4] == bytes.fromhex("03000016") and cc[5] == 0xD0
    assert cc[6:8] == b"\x00\x01"  # destination reference = the client's source reference
    assert bytes.fromhex("C1020100") in cc and bytes.fromhex("C2020104") in cc
    assert session.info.called_tsap == b"\x01\x04"


def test_828d_tsaps_are_accepted(session: ServerSession) -> None:
    (cc,) = session.receive(CR_828D)
    assert cc[5] == 0xD0 and bytes.fromhex("C2020D04") in cc


def test_setup_negotiates_pdu_down_to_the_server_maximum() -> None:
    session = ServerSession(Dispatcher.for_machine(Emulator()), limits=SessionLimits(pdu_size_max=480))
    session.receive(CR_NCK)
    (answer,) = session.receive(dt(SETUP_960))
    assert s7_of(answer)[-2:] == struct.pack(">H", 480)


def test_nck_read_of_sd43900_answers_one_real8(session: ServerSession) -> None:
    connected(session)
    (answer,) = session.receive(dt(job(7, b"\x04\x01" + SD43900_AX4)))
    pdu = s7_of(answer)
    assert pdu[1] == 3 and pdu[4:6] == b"\x00\x07" and header_error(pdu) == (0, 0)
    assert pdu[12:14] == b"\x04\x01"
    assert pdu[14:18] == bytes.fromhex("FF090008")
    assert struct.unpack("<d", pdu[18:26])[0] == 0.0


def test_seed000_three_variable_write_then_read_back(session: ServerSession) -> None:
    connected(session)
    items = [bytes.fromhex(f"12088264{col}00011601") for col in ("AB7C", "AB86", "AB90")]
    values = (0.3, 0.000012, 0.0)
    parameter = b"\x05\x03" + b"".join(items)
    data = b"".join(b"\x00\x09\x00\x08" + struct.pack("<d", v) for v in values)
    (answer,) = session.receive(dt(job(8, parameter, data)))
    pdu = s7_of(answer)
    assert pdu[12:14] == b"\x05\x03" and pdu[14:17] == b"\xFF\xFF\xFF"
    (answer,) = session.receive(dt(job(9, b"\x04\x03" + b"".join(items))))
    pdu = s7_of(answer)
    got = [struct.unpack("<d", pdu[18 + 12 * i:26 + 12 * i])[0] for i in range(3)]
    assert got == list(values)


def test_unknown_syntax_id_gets_object_does_not_exist_never_other_data(session: ServerSession) -> None:
    connected(session)
    dbread = bytes.fromhex("1207B001040001000000")  # DBREAD syntax (9 bytes, then a fill byte)
    (answer,) = session.receive(dt(job(3, b"\x04\x02" + dbread + SD43900_AX4)))
    pdu = s7_of(answer)
    assert pdu[14:18] == bytes.fromhex("0A000000")
    assert pdu[18:22] == bytes.fromhex("FF090008")


@pytest.mark.parametrize(("item_hex", "code"), [
    ("12088264AB7C00015501", 0x0A),  # module 0x55 (AUXFU) not served
    ("12088264FFFF00011601", 0x0A),  # no such setting datum
    ("12088264AB7C00091601", 0x05),  # line beyond the array
    ("12088264AB7C00001601", 0x05),  # line 0
])
def test_item_errors(session: ServerSession, item_hex: str, code: int) -> None:
    connected(session)
    (answer,) = session.receive(dt(job(3, b"\x04\x01" + bytes.fromhex(item_hex))))
    assert s7_of(answer)[14] == code


def test_job_before_setup_is_refused_with_a_sequence_error(session: ServerSession) -> None:
    session.receive(CR_NCK)
    (answer,) = session.receive(dt(job(2, b"\x04\x01" + SD43900_AX4)))
    assert header_error(s7_of(answer)) == (0x84, 0x01)
    assert not session.closed


def test_unsupported_function_gets_a_header_error(session: ServerSession) -> None:
    connected(session)
    (answer,) = session.receive(dt(job(4, bytes.fromhex("1A00000000000000"))))
    assert s7_of(answer)[1] == 2 and s7_of(answer)[10:12] == b"\x81\x04"  # ACK, no parameter


def test_garbage_closes_the_connection(session: ServerSession) -> None:
    assert session.receive(b"GET / HTTP/1.0\r\n\r\n") == []
    assert session.closed


def test_frames_split_at_every_byte_are_reassembled(session: ServerSession) -> None:
    stream = CR_NCK + dt(SETUP_960) + dt(job(5, b"\x04\x01" + SD43900_AX4))
    answers: list[bytes] = []
    for index in range(len(stream)):
        answers.extend(session.receive(stream[index:index + 1]))
    assert len(answers) == 3 and s7_of(answers[2])[14] == 0xFF


def test_cotp_fragments_are_reassembled(session: ServerSession) -> None:
    connected(session)
    pdu = job(6, b"\x04\x01" + SD43900_AX4)
    assert session.receive(dt(pdu[:5], eot=False)) == []
    (answer,) = session.receive(dt(pdu[5:]))
    assert s7_of(answer)[14] == 0xFF


def test_more_jobs_than_the_granted_amq_get_no_resources() -> None:
    session = ServerSession(Dispatcher.for_machine(Emulator()), limits=SessionLimits(max_amq=2))
    session.receive(CR_NCK)
    session.receive(dt(SETUP_960))
    burst = b"".join(dt(job(10 + i, b"\x04\x01" + SD43900_AX4)) for i in range(3))
    answers = session.receive(burst)
    assert [s7_of(a)[14] if header_error(s7_of(a)) == (0, 0) else header_error(s7_of(a))
            for a in answers] == [0xFF, 0xFF, (0x83, 0x02)]


def test_disconnect_request_is_confirmed_and_closes(session: ServerSession) -> None:
    session.receive(CR_NCK)
    (dc,) = session.receive(bytes.fromhex("0300000B068000010001" + "00")[:11])
    assert dc[5] == 0xC0 and session.closed


def _nc_userdata(pdu_ref: int, parameter: object, payload: bytes) -> bytes:
    from nckemu.protocol import ncprog, s7

    assert isinstance(parameter, ncprog.NcParameter)
    return s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, pdu_ref, ncprog.build_nc_parameter(parameter),
                                 ncprog.build_nc_data(ncprog.NcData(payload))))


def test_a_download_block_split_over_dts_behind_a_full_amq_is_no_job() -> None:
    """An NC push is a telegram of a transfer, not a job: reassembled from several DTs behind more jobs
    than the AMQ, it gets no 'no resources' answer (as it gets none in one DT) and its block counts."""
    from nckemu.protocol import ncprog
    from nckemu.protocol.ncprog import NcParameter, NcSubfunction

    emulator = Emulator()
    session = ServerSession(Dispatcher.for_machine(emulator), limits=SessionLimits(max_amq=2))
    session.receive(CR_NCK)
    session.receive(dt(SETUP_960))
    (started,) = session.receive(dt(_nc_userdata(
        5, NcParameter(ncprog.NC_REQUEST, NcSubfunction.REQUEST_DOWNLOAD), ncprog.build_name("_N_AMQ_MPF"))))
    sequence = ncprog.parse_nc_parameter(s7_of(started)[10:10 + int.from_bytes(s7_of(started)[6:8], "big")]).sequence
    text = b"G1 X10 F100\nM30\n"
    content = ncprog.build_transfer_content(ncprog.TransferContent("/_N_MPF_DIR", text))
    block = _nc_userdata(6, NcParameter(ncprog.NC_PUSH, NcSubfunction.DOWNLOAD_BLOCK, sequence, True, 1,
                                        ncprog.LAST_DATA_UNIT), ncprog.build_chunk(content))
    jobs = b"".join(dt(job(10 + i, b"\x04\x01" + SD43900_AX4)) for i in range(3))
    answers = session.receive(jobs + dt(block[:20], eot=False) + dt(block[20:]))
    assert [header_error(s7_of(a)) for a in answers] == [(0, 0), (0, 0), (0x83, 0x02)]
    (ended,) = session.receive(dt(_nc_userdata(
        7, NcParameter(ncprog.NC_REQUEST, NcSubfunction.DOWNLOAD_ENDED, sequence), b"\x00\x00")))
    ended_parameter = s7_of(ended)[10:10 + int.from_bytes(s7_of(ended)[6:8], "big")]
    assert ncprog.parse_nc_parameter(ended_parameter).error_code == 0
    assert emulator.nck.programs.read("/_N_MPF_DIR/_N_AMQ_MPF") == text
