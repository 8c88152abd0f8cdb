"""Issue 14 part 2, "wire details an audit found": each fixed with a test that would have caught it.

Frames are written out byte by byte here (not built by our encoders); where a byte comes from a
public source, the source is named (notes/catalogue.md keys: SNAP7, PYSNAP7, LSC, WS).
"""

from __future__ import annotations

import struct
from datetime import datetime, timedelta
from pathlib import Path

import pytest

import nckemu.emulator.machine
from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import load_machine, parse_machine
from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.errors import NckConfigError
from nckemu.protocol import c840, db41, pi
from nckemu.protocol.addresses import NckAddress
from tests.emulator.faces.s7.test_session import CR_NCK, SD43900_AX4, SETUP_960, connected, dt, job, s7_of

EMPTY_DT = bytes.fromhex("0300000702f000")       # LSC: sent after every job, same TCP write
EMPTY_DT_EOT = bytes.fromhex("0300000702f080")


def userdata(pdu_ref: int, parameter: bytes, data: bytes) -> bytes:
    return struct.pack(">BBHHHH", 0x32, 7, 0, pdu_ref, len(parameter), len(data)) + parameter + data


def szl_read(szl_id: int, index: int, pdu_ref: int = 0x20) -> bytes:
    # PYSNAP7 read_szl: param 00 01 12 04 11 44 01 00, data FF 09 00 04 + ID + index
    return userdata(pdu_ref, bytes.fromhex("0001120411440100"), struct.pack(">BBHHH", 0xFF, 9, 4, szl_id, index))


def split_userdata_answer(frame: bytes) -> tuple[bytes, bytes]:
    pdu = s7_of(frame)
    assert pdu[0] == 0x32 and pdu[1] == 7
    parameter_length, data_length = struct.unpack_from(">HH", pdu, 6)
    assert len(pdu) == 10 + parameter_length + data_length
    return pdu[10:10 + parameter_length], pdu[10 + parameter_length:]


@pytest.fixture
def session() -> ServerSession:
    return connected(ServerSession(Dispatcher.for_machine(Emulator()), limits=SessionLimits(pdu_size_max=960, max_amq=8)))


# ---------------------------------------------------------------- 1. userdata groups
def test_read_clock_answers_the_plc_clock_in_userdata() -> None:
    clock = SimulatedClock()
    emulator = Emulator(clock=clock)
    session = connected(ServerSession(Dispatcher.for_machine(emulator)))
    clock.advance(3600.0)
    expected = emulator.plc.now()
    # PYSNAP7 get_plc_datetime: group 7 ("time functions"), subfunction 1 ("read clock")
    (answer,) = session.receive(dt(userdata(0x31, bytes.fromhex("0001120411470100"), bytes.fromhex("0A000000"))))
    parameter, data = split_userdata_answer(answer)
    assert parameter == bytes.fromhex("000112081287010000000000")
    assert data[:4] == bytes.fromhex("FF09000A") and len(data) == 14
    year = expected.year
    assert data[5:7] == bytes([int(str(year)[:2], 16), int(str(year)[2:], 16)])  # century, year in BCD
    assert data[7] == int(f"{expected.month:02d}", 16) and data[8] == int(f"{expected.day:02d}", 16)
    assert data[13] & 0x0F == expected.isoweekday() % 7 + 1  # 1 = Sunday
    assert s7_of(answer)[4:6] == b"\x00\x31"


def test_the_plc_clock_follows_the_emulator_clock() -> None:
    clock = SimulatedClock()
    emulator = Emulator(clock=clock)
    before = emulator.plc.now()
    clock.advance(90.0)
    assert emulator.plc.now() - before == timedelta(seconds=90)


def test_list_blocks_counts_the_plcs_data_blocks(session: ServerSession) -> None:
    # PYSNAP7 list_blocks: group 3 ("block functions"), subfunction 1 ("list blocks"); exactly 28 bytes back
    (answer,) = session.receive(dt(userdata(0x32, bytes.fromhex("0001120411430100"), bytes.fromhex("0A000000"))))
    parameter, data = split_userdata_answer(answer)
    assert parameter == bytes.fromhex("000112081283010000000000")
    blocks = len(load_machine().data_blocks)
    assert data == bytes.fromhex("FF09001C" "30380000" "3041") + struct.pack(">H", blocks) \
        + bytes.fromhex("30420000" "30430000" "30440000" "30450000" "30460000")


@pytest.mark.parametrize("parameter_hex", [
    "0001120411470200",  # time functions / set clock
    "0001120411430200",  # block functions / list blocks of type
    "0001120411430300",  # block functions / block info
    "0001120411410100",  # programmer commands
    "0001120411420100",  # cyclic data
    "0001120411440200",  # CPU functions, subfunction 2 (message service)
])
def test_unserved_userdata_gets_a_userdata_answer_with_the_error_in_its_parameter(
        session: ServerSession, parameter_hex: str) -> None:
    request = bytes.fromhex(parameter_hex)
    (answer,) = session.receive(dt(userdata(0x33, request, bytes.fromhex("0A000000"))))
    parameter, data = split_userdata_answer(answer)
    # 12 8<group> <subfunction> <seq> 00 00 81 04, data 0A 00 00 00 (the SNAP7 SZLNotAvailable form)
    assert parameter == bytes.fromhex("0001120812") + bytes([0x80 | request[5] & 0x0F, request[6], 0]) \
        + bytes.fromhex("00008104")
    assert data == bytes.fromhex("0A000000")
    assert not session.closed


def test_unserved_userdata_error_is_a_setting() -> None:
    machine = parse_machine("[settings]\nuserdata_not_served_error = 0xD405\n")
    session = connected(ServerSession(Dispatcher.for_machine(Emulator(machine))))
    (answer,) = session.receive(dt(userdata(1, bytes.fromhex("0001120411470200"), bytes.fromhex("0A000000"))))
    assert split_userdata_answer(answer)[0][-2:] == b"\xD4\x05"


def test_userdata_that_is_not_a_request_is_refused_as_today(session: ServerSession) -> None:
    (answer,) = session.receive(dt(userdata(2, bytes.fromhex("0001120412870100"), bytes.fromhex("0A000000"))))
    pdu = s7_of(answer)
    assert pdu[1] == 3 and pdu[10:12] == b"\x85\x00"


# ---------------------------------------------------------------- 2. unsupported job functions
@pytest.mark.parametrize("parameter_hex", [
    "1A00000000000000",                       # request download
    "1D0000000000000009" + "5F3041303030303150",  # start upload (ROSCTR 3 + 1D alone is "malformed")
    "1E000000000000001",                      # upload
    "1F0000000000000000",                     # end upload
    "00",                                     # CPU services
    "FF",
])
def test_unsupported_functions_get_an_ack_with_the_error_and_no_parameter(
        session: ServerSession, parameter_hex: str) -> None:
    parameter = bytes.fromhex(parameter_hex if len(parameter_hex) % 2 == 0 else parameter_hex + "0")
    (answer,) = session.receive(dt(job(4, parameter)))
    # SNAP7 / PYSNAP7 form: ROSCTR 2, parameter and data length 0, header error 81 04
    assert s7_of(answer) == bytes.fromhex("32020000000400000000" "8104")
    assert not session.closed


def test_unsupported_function_error_is_a_setting() -> None:
    machine = parse_machine("[settings]\nunsupported_function_error = 0xD241\n")
    session = connected(ServerSession(Dispatcher.for_machine(Emulator(machine))))
    (answer,) = session.receive(dt(job(4, bytes.fromhex("1D00000000000000"))))
    assert s7_of(answer) == bytes.fromhex("32020000000400000000" "D241")


def test_unsupported_function_before_setup_is_an_ack_too() -> None:
    session = ServerSession(Dispatcher.for_machine(Emulator()))
    session.receive(CR_NCK)
    (answer,) = session.receive(dt(job(4, bytes.fromhex("1D00000000000000"))))
    assert s7_of(answer) == bytes.fromhex("32020000000400000000" "8401")


# ---------------------------------------------------------------- 4. PDU size clamp
@pytest.mark.parametrize(("asked", "granted"), [(0, 240), (1, 240), (100, 240), (239, 240), (240, 240),
                                                 (480, 480), (960, 960), (0xFFFF, 960)])
def test_setup_pdu_size_is_clamped_to_240_and_the_maximum(asked: int, granted: int) -> None:
    session = ServerSession(Dispatcher.for_machine(Emulator()), limits=SessionLimits(pdu_size_max=960))
    session.receive(CR_NCK)
    (answer,) = session.receive(dt(job(1, bytes.fromhex("F0000008000 8".replace(" ", "")) + struct.pack(">H", asked))))
    assert s7_of(answer)[-2:] == struct.pack(">H", granted)
    (read,) = session.receive(dt(job(2, b"\x04\x01" + SD43900_AX4)))
    assert s7_of(read)[10:12] == b"\x00\x00" and s7_of(read)[14] == 0xFF


# ---------------------------------------------------------------- 5. SZL
def _szl_answer(session: ServerSession, szl_id: int, index: int) -> tuple[bytes, bytes]:
    (answer,) = session.receive(dt(szl_read(szl_id, index)))
    return split_userdata_answer(answer)


def test_szl_unknown_id_and_unknown_index_codes(session: ServerSession) -> None:
    parameter, data = _szl_answer(session, 0x0999, 0)
    assert parameter[-2:] == b"\xD4\x01" and data == bytes.fromhex("0A000000")
    parameter, data = _szl_answer(session, 0x0131, 0x0007)
    assert parameter[-2:] == b"\xD4\x02" and data == bytes.fromhex("0A000000")


def test_szl_not_available_codes_are_settings() -> None:
    # C snap7 answers 0xD402 for every SZL it lacks (SNAP7 PerformGroupSZL)
    machine = parse_machine("[settings]\nszl_unknown_id_error = 0xD402\n")
    session = connected(ServerSession(Dispatcher.for_machine(Emulator(machine))))
    assert _szl_answer(session, 0x0999, 0)[0][-2:] == b"\xD4\x02"
    with pytest.raises(NckConfigError, match="szl_unknown_id_error"):
        parse_machine("[settings]\nszl_unknown_id_error = 0x10000\n")


def test_szl_0424_record_has_a_cpus_event_id(session: ServerSession) -> None:
    _, data = _szl_answer(session, 0x0424, 0)
    # SNAP7 s7_firmware.h SZL_ID_0424_IDX_XXXX ("from a physical CPU"): LENTHDR 20, one record
    # 51 44 FF <mode 08 = RUN> ..., bytes 12..19 a DATE_AND_TIME
    assert data[:4] == bytes.fromhex("FF09001C") and data[4:12] == bytes.fromhex("0424000000140001")
    assert data[12:16] == bytes.fromhex("5144FF08") and data[16:24] == bytes(8)
    assert len(data) == 32


def test_szl_0131_index_1_is_a_cpus_communication_record(session: ServerSession) -> None:
    _, data = _szl_answer(session, 0x0131, 1)
    # SNAP7 SZL_ID_0131_IDX_0001: FF 09 00 30, 01 31 00 01 00 28 00 01, record index 1, max PDU,
    # max connections, MPI rate 12 Mbit/s (00 B7 1B 00), K-bus rate 187.5 kbit/s (00 02 DC 6C)
    assert data[:16] == bytes.fromhex("FF090030" "01310001" "00280001" "0001") + struct.pack(">H", 960)
    assert data[16:26] == bytes.fromhex("0010" "00B71B00" "0002DC6C")
    assert len(data) == 52


def test_szl_0232_index_4_is_a_cpus_protection_record(session: ServerSession) -> None:
    _, data = _szl_answer(session, 0x0232, 4)
    # SNAP7 SZL_ID_0232_IDX_0004: sch_schal 1, sch_par 0, sch_rel 1, bart_sch 2, anl_sch 0
    assert data[:24] == bytes.fromhex("FF090030" "02320004" "00280001" "0004" "0001" "0000" "0001" "0002" "0000")
    assert len(data) == 52


def test_szl_index_0_in_python_snap7s_layout(session: ServerSession) -> None:
    # PYSNAP7 parse_cp_info_szl / get_protection: four / five words right after ID and index
    _, data = _szl_answer(session, 0x0131, 0)
    assert data == bytes.fromhex("FF09000C" "01310000") + struct.pack(">HHHH", 960, 16, 12, 12)
    _, data = _szl_answer(session, 0x0232, 0)
    assert data == bytes.fromhex("FF09000E" "02320000" "0001" "0000" "0001" "0002" "0000")


def test_szl_index_0_layout_can_be_switched_off() -> None:
    machine = parse_machine("[settings]\nszl_index0_python_snap7 = false\n")
    session = connected(ServerSession(Dispatcher.for_machine(Emulator(machine))))
    assert _szl_answer(session, 0x0131, 0)[0][-2:] == b"\xD4\x02"


# ---------------------------------------------------------------- 7. S7ANY transport sizes
def test_char_and_dint_answer_with_snap7s_transport_sizes(session: ServerSession) -> None:
    # S7ANY items on DB100.DBB0: CHAR x4 (0x03), DINT x1 (0x07), INT x1 (0x05), BYTE x2 (0x02)
    items = [bytes.fromhex(f"120A10{ts:02X}{count:04X}006484000000") for ts, count in
             ((0x03, 4), (0x07, 1), (0x05, 1), (0x02, 2))]
    (answer,) = session.receive(dt(job(9, b"\x04\x04" + b"".join(items))))
    data = s7_of(answer)[14:]
    # SNAP7 PerformFunctionRead: CHAR 0x09 (length in bytes), DINT and INT 0x05 (bits), BYTE 0x04 (bits)
    assert data == bytes.fromhex("FF090004" "00000000" "FF050020" "00000000" "FF050010" "0000" "FF040010" "0000")


# ---------------------------------------------------------------- 8. empty DTs
def test_empty_dt_after_each_job_in_the_same_write_is_ignored(session: ServerSession) -> None:
    answers = session.receive(dt(job(5, b"\x04\x01" + SD43900_AX4)) + EMPTY_DT
                              + dt(job(6, b"\x04\x01" + SD43900_AX4)) + EMPTY_DT)
    assert len(answers) == 2 and [s7_of(a)[4:6] for a in answers] == [b"\x00\x05", b"\x00\x06"]
    assert not session.closed


def test_empty_dt_with_eot_is_ignored(session: ServerSession) -> None:
    assert session.receive(EMPTY_DT_EOT) == []
    assert not session.closed
    (answer,) = session.receive(dt(job(7, b"\x04\x01" + SD43900_AX4)))
    assert s7_of(answer)[14] == 0xFF


def test_empty_dts_before_setup_are_ignored_too() -> None:
    session = ServerSession(Dispatcher.for_machine(Emulator()))
    session.receive(CR_NCK)
    assert session.receive(EMPTY_DT_EOT + EMPTY_DT) == []
    (answer,) = session.receive(dt(SETUP_960) + EMPTY_DT)
    assert s7_of(answer)[12] == 0xF0 and not session.closed


def test_empty_dt_with_eot_ends_a_fragmented_pdu() -> None:
    session = connected(ServerSession(Dispatcher.for_machine(Emulator())))
    pdu = job(8, b"\x04\x01" + SD43900_AX4)
    assert session.receive(dt(pdu, eot=False)) == []
    (answer,) = session.receive(EMPTY_DT_EOT)
    assert s7_of(answer)[14] == 0xFF


# ---------------------------------------------------------------- 9. COTP segmentation
def test_answers_longer_than_the_tpdu_are_split_into_several_dts() -> None:
    session = ServerSession(Dispatcher.for_machine(Emulator()), limits=SessionLimits(pdu_size_max=960))
    session.receive(bytes.fromhex("0300001611E00000000100C00107C1020100C2020104"))
    session.receive(dt(job(1, bytes.fromhex("F0000008000803C0"))))
    frames = session.receive(dt(job(2, bytes.fromhex("0401120A100200C8006484000000"))))
    assert len(frames) == 2  # 14 + 4 + 200 = 218 bytes of S7 PDU in DTs of at most 125
    payload = b""
    for index, frame in enumerate(frames):
        assert frame[:2] == b"\x03\x00" and struct.unpack(">H", frame[2:4])[0] == len(frame)
        assert len(frame) - 4 <= 128 and frame[4:6] == b"\x02\xF0"
        assert frame[6] == (0x80 if index == len(frames) - 1 else 0x00)
        payload += frame[7:]
    assert len(payload) == 14 + 4 + 200 and payload[14:18] == bytes.fromhex("FF040640")


# ---------------------------------------------------------------- 3. _N_CONFIG
def test_n_config_activates_new_conf_machine_data(session: ServerSession) -> None:
    emulator = Emulator()
    session = connected(ServerSession(Dispatcher.for_machine(emulator)))
    md32760 = NckAddress(3, 4, 32760, 1, 0x1A)
    emulator.nck.write(md32760, [0.05], AccessContext(level=0))
    assert emulator.nck.store.active_value("COMP_ADD_VELO_FACTOR", 4) == 0.01
    # PI job: 28, 7 header bytes, block length 6, "201" and "1" (odd lengths: no fill), name length 9
    block = b"\x03201\x011"
    parameter = bytes.fromhex("28000000000000FD") + struct.pack(">H", len(block)) + block + b"\x09_N_CONFIG"
    (answer,) = session.receive(dt(job(3, parameter)))
    assert s7_of(answer)[10:13] == bytes.fromhex("000028")
    assert emulator.nck.store.active_value("COMP_ADD_VELO_FACTOR", 4) == 0.05


def test_n_config_with_wrong_arguments_is_refused(session: ServerSession) -> None:
    block = b"\x03201"
    parameter = bytes.fromhex("28000000000000FD") + struct.pack(">H", len(block)) + block + b"\x09_N_CONFIG"
    (answer,) = session.receive(dt(job(3, parameter)))
    assert s7_of(answer)[10:12] == b"\xD4\x05"


# ---------------------------------------------------------------- 6. PI table
@pytest.mark.parametrize(("name", "arguments"), [("_N_TMFPBP", 13), ("_N_TMPOSM", 8), ("_N_TSEARC", 9)])
def test_wiresharks_tool_management_services_are_in_the_pi_table(name: str, arguments: int) -> None:
    spec = pi.PI_SERVICES[name]
    assert len(spec.argument_names) == arguments and spec.argument_names[0] == "addressident"
    assert spec.description


# ---------------------------------------------------------------- 10. 840C channel
def _user_db(flags_axis: int, tan_beta_raw: int, p0_units: int) -> bytes:
    return struct.pack(">HHiii", 7, flags_axis, 300, tan_beta_raw, p0_units)


def test_840c_tan_beta_0x80000000_is_exactly_minus_one() -> None:
    db = c840.parse_user_db(_user_db(0xC004, -(2**31), 1000))
    assert db.tan_beta == -1.0
    assert c840.build_user_db(db) == _user_db(0xC004, -(2**31), 1000)


def _run_channel(emulator: Emulator, user_db: bytes) -> int:
    plc = emulator.plc
    plc.write(0x84, 100, 0, user_db)
    plc.write(0x84, db41.CHANNEL_DB, 0, db41.build_request(100, 0))
    status = db41.parse_status(plc.read(0x84, db41.CHANNEL_DB, 0, db41.CHANNEL_BYTES))
    return status.error_number


def test_840c_p0_zero_with_a_flag_is_accepted_by_default_and_refused_by_setting() -> None:
    user_db = _user_db(0xC004, 0x40000000, 0)  # U and A set, axis 4, P0 = 0
    assert _run_channel(Emulator(), user_db) == db41.ChannelError.NONE
    default_text = (Path(nckemu.emulator.machine.__file__).parent / "machines" / "default.toml").read_text()
    strict = parse_machine(default_text.replace("c840_refuse_p0_at_zero = false", "c840_refuse_p0_at_zero = true"))
    assert _run_channel(Emulator(strict), user_db) == db41.ChannelError.P0_AT_AXIS_ZERO


def test_840c_tan_beta_minus_one_runs_through_the_channel() -> None:
    assert _run_channel(Emulator(), _user_db(0xC004, -(2**31), 1000)) == db41.ChannelError.NONE


def test_clock_bcd_round_trip() -> None:
    from nckemu.protocol import szl

    moment = datetime(2026, 11, 22, 23, 59, 58, 987000)  # a Sunday
    data = szl.build_clock(moment)
    assert data == bytes.fromhex("FF09000A" "0020261122235958" "98" "71")
    assert szl.parse_clock(data) == moment


# ---------------------------------------------------------------- 8. the 828D collector's connect (LSC)
def test_828d_collector_handshake_and_extra_empty_dt() -> None:
    """LSC `_siemenscnc_828d_connect` (notes/catalogue.md 2.1): CC exactly 22 bytes, setup answer
    exactly 27 bytes, then every job followed by 03 00 00 07 02 F0 00 in the same send buffer."""
    session = ServerSession(Dispatcher.for_machine(Emulator()))
    (cc,) = session.receive(bytes.fromhex("0300001611E00000004800C1020400C2020D04C0010A"))
    assert len(cc) == 22 and cc[5] == 0xD0
    (setup,) = session.receive(bytes.fromhex("0300001902F08032010000000100080000F0000064006403C0"))
    assert len(setup) == 27 and s7_of(setup)[-2:] == struct.pack(">H", 960)
    for ref in range(2, 6):
        answers = session.receive(dt(job(ref, b"\x04\x01" + SD43900_AX4)) + EMPTY_DT)
        assert len(answers) == 1 and s7_of(answers[0])[4:6] == struct.pack(">H", ref)
        assert s7_of(answers[0])[14:18] == bytes.fromhex("FF090008")
    assert not session.closed and session.info.errors == 0


# ---------------------------------------------------------------- 4./5. a long SZL at PDU 240
def test_long_szl_at_pdu_240_comes_in_parts() -> None:
    """After the clamp to 240 an SZL longer than the PDU is sent in parts (last data unit 1, then 0);
    the client asks for each next part with method 0x12, type request and the answer's sequence number
    (python-snap7 3.3 build_userdata_followup_request; snap7.pcap in icsnpp-s7comm)."""
    whole_session = connected(ServerSession(Dispatcher.for_machine(Emulator())))
    (whole,) = whole_session.receive(dt(szl_read(0x001C, 0)))
    expected = split_userdata_answer(whole)[1][4:]
    assert len(expected) > 240
    session = ServerSession(Dispatcher.for_machine(Emulator()))
    session.receive(CR_NCK)
    session.receive(dt(job(1, bytes.fromhex("F000000800080000"))))  # PDU 0 -> 240
    (first,) = session.receive(dt(szl_read(0x001C, 0, pdu_ref=0x40)))
    assert len(s7_of(first)) <= 240
    parameter, data = split_userdata_answer(first)
    sequence = parameter[7]
    assert parameter[4:7] == bytes.fromhex("128401") and parameter[9] == 1 and sequence != 0
    assert data[:2] == b"\xFF\x09" and struct.unpack(">H", data[2:4])[0] == len(data) - 4
    collected = data[4:]
    for ref in range(0x41, 0x50):
        # 00 01 12 08, method 12, type 4 / group 4, subfunction 01, the sequence, 00 00 00 00
        follow = bytes.fromhex("00011208124401") + bytes([sequence]) + bytes(4)
        (part,) = session.receive(dt(userdata(ref, follow, bytes.fromhex("0A000000"))))
        assert len(s7_of(part)) <= 240 and s7_of(part)[4:6] == struct.pack(">H", ref)
        parameter, data = split_userdata_answer(part)
        collected += data[4:]
        if parameter[9] == 0:
            break
    assert collected == expected
    # a next-part request when nothing is pending is refused as any malformed userdata is
    (refused,) = session.receive(dt(userdata(0x60, bytes.fromhex("000112081244010100000000"),
                                             bytes.fromhex("0A000000"))))
    assert s7_of(refused)[1] == 3 and s7_of(refused)[10:12] == b"\x85\x00"
