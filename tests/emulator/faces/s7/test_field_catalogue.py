"""What field tools read, with hand-built request bytes: a collector's connect sequence and the
catalogue's groups answered with the type and length a real NCK gives.

The facts behind the bytes (our own frames; the sources are named, no code taken from them):
  IOT   xingshuangs/iot-communication S7PLC.java Javadoc: requests and answers captured from an 828D
  LSC   libsiemenscnc (828D collector) siemens_828d_new.c: connect handshake and request tables
  NCVS2 NC-Var-Selector export MDClite_signallist_840D_SL_4_5.awl (in Vunnupyx/clight)
  DNTEX DotNetSiemensPLCToolBoxLibrary ReadTools example
An NCK item is 12 08 82 <area<<5|unit> <column BE16> <line BE16> <module> <line count>; every answer
item of the NCK is FF 09 <length in bytes BE16> + values, little-endian (IOT, LSC).
"""

from __future__ import annotations

import struct

import pytest

from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.nck.alarms import ALARM_RETAINED_STATE

# LSC's connect: CR with src-ref 0x0048, calling TSAP 0x0400, called TSAP 0x0D04, TPDU size 1024; it
# drops the connection unless the CC is exactly 22 bytes.
CR_LSC = bytes.fromhex("03 00 00 16 11 E0 00 00 00 48 00 C1 02 04 00 C2 02 0D 04 C0 01 0A")
# LSC's setup communication: PDU ref 1, AMQ 100/100, PDU 960; the answer frame must be 27 bytes.
SETUP_LSC = bytes.fromhex("03 00 00 19 02 F0 80 32 01 00 00 00 01 00 08 00 00 F0 00 00 64 00 64 03 C0")
# LSC's third handshake: read N / DIAGN (0x3B) / column 0x14 / line 1 / count 1; the answer frame must
# be 27 bytes, i.e. one item of exactly 2 data bytes. The job is 29 bytes.
DIAGN_LSC = bytes.fromhex("03 00 00 1D 02 F0 80 32 01 00 00 00 01 00 0C 00 00 04 01"
                          " 12 08 82 01 00 14 00 01 3B 01")


def item(au: int, column: int, line: int, module: int, count: int = 1) -> bytes:
    return bytes([0x12, 0x08, 0x82, au]) + struct.pack(">HHBB", column, line, module, count)


def read_frame(*items: bytes, ref: int = 5) -> bytes:
    parameter = bytes([0x04, len(items)]) + b"".join(items)
    s7 = struct.pack(">BBHHHH", 0x32, 1, 0, ref, len(parameter), 0) + parameter
    return struct.pack(">BBH", 3, 0, 7 + len(s7)) + b"\x02\xF0\x80" + s7


def answer_items(frame: bytes) -> list[tuple[int, int, bytes]]:
    """(return code, transport size, data) of each item in a read-var answer frame."""
    assert frame[8] == 3 and frame[17:19] == b"\x00\x00", frame.hex()
    count = frame[20]
    offset, items = 21, []
    for _ in range(count):
        rc, ts, length = frame[offset], frame[offset + 1], struct.unpack(">H", frame[offset + 2:offset + 4])[0]
        size = length if rc != 0xFF or ts in (0x09, 0x07) else length // 8
        items.append((rc, ts, frame[offset + 4:offset + 4 + size]))
        offset += 4 + size + (size % 2 if _ < count - 1 else 0)
    assert offset == len(frame)
    return items


@pytest.fixture
def clock() -> SimulatedClock:
    return SimulatedClock()


@pytest.fixture
def emulator(clock: SimulatedClock) -> Emulator:
    return Emulator(clock=clock)


@pytest.fixture
def session(emulator: Emulator) -> ServerSession:
    session = ServerSession(Dispatcher.for_machine(emulator), limits=SessionLimits(pdu_size_max=960, max_amq=8), peer="t")
    (cc,) = session.receive(CR_LSC)
    (setup,) = session.receive(SETUP_LSC)
    assert len(cc) == 22 and len(setup) == 27
    return session


def read(session: ServerSession, *items: bytes) -> list[tuple[int, int, bytes]]:
    (answer,) = session.receive(read_frame(*items))
    return answer_items(answer)


def test_collector_connect_sequence_gets_the_lengths_it_insists_on(emulator: Emulator) -> None:
    session = ServerSession(Dispatcher.for_machine(emulator), limits=SessionLimits(pdu_size_max=960, max_amq=8))
    (cc,) = session.receive(CR_LSC)
    assert len(cc) == 22 and cc[5] == 0xD0
    (setup,) = session.receive(SETUP_LSC)
    assert len(setup) == 27 and setup[-2:] == b"\x03\xC0"
    (diagn,) = session.receive(DIAGN_LSC)
    assert len(diagn) == 27
    assert diagn[19:21] == b"\x04\x01" and diagn[21:25] == bytes.fromhex("FF090002")


def test_machine_data_strings_have_their_field_length(session: ServerSession) -> None:
    # IOT: MD18030 answers 32 bytes (text, then NUL); MD18040 lines answer 20 bytes each.
    ((rc, ts, serial),) = read(session, item(0x01, 18030, 1, 0x1A))
    assert (rc, ts, len(serial)) == (0xFF, 0x09, 32) and serial.rstrip(b"\x00").isascii()
    ((rc, ts, version),) = read(session, item(0x01, 18040, 1, 0x1A))
    assert (rc, ts, len(version)) == (0xFF, 0x09, 20) and version.endswith(b"\x00")
    # A line count of 4 is one item of 4 x 20 bytes.
    ((rc, _ts, lines),) = read(session, item(0x01, 18040, 1, 0x1A, 4))
    assert rc == 0xFF and len(lines) == 80 and lines[:20] == version


def test_axis_names_follow_the_machine(session: ServerSession) -> None:
    # MD10000 by the rule column = MD number, line = index + 1 (unconfirmed address); default machine
    # axis 4 is Z1; MD20080 (LSC "axis name") names channel axis 4 Z.
    ((_rc, _ts, name),) = read(session, item(0x01, 10000, 4, 0x1A))
    assert name == b"Z1".ljust(32, b"\x00")
    ((_rc, _ts, names),) = read(session, item(0x41, 20080, 1, 0x1A, 4))
    assert [names[i:i + 32].rstrip(b"\x00") for i in range(0, 128, 32)] == [b"X", b"Y", b"SP", b"Z"]
    (axes, spindles) = read(session, item(0x41, 3, 1, 0x10), item(0x41, 4, 1, 0x10))
    assert axes[2] == struct.pack("<H", 4) and spindles[2] == struct.pack("<H", 1)


def test_machine_position_line_count_3_is_one_item_of_three_real8(session: ServerSession) -> None:
    # IOT: 12 08 82 41 00 02 00 01 74 03 -> FF 09 00 18 + 3 LE doubles.
    ((rc, ts, data),) = read(session, item(0x41, 2, 1, 0x74, 3))
    assert (rc, ts, len(data)) == (0xFF, 0x09, 24)
    assert len(struct.unpack("<3d", data)) == 3


def test_four_remaining_distance_items_come_back_to_back(session: ServerSession) -> None:
    # IOT: four items 12 08 82 41 00 03 00 0n 74 01 -> parameter 04 04, four FF 09 00 08 items.
    (answer,) = session.receive(read_frame(*(item(0x41, 3, n, 0x74) for n in range(1, 5))))
    assert answer[19:21] == b"\x04\x04"
    assert answer[21:] == (bytes.fromhex("FF090008") + bytes(8)) * 4


def test_two_word_items_for_lsc_fixed_offsets(session: ServerSession) -> None:
    # LSC decodes opMode (B, S col 3) and channel S col 12 at fixed offsets: item 2 header at 27.
    (answer,) = session.receive(read_frame(item(0x21, 3, 1, 0x7F), item(0x41, 12, 1, 0x7F)))
    assert answer[21:25] == bytes.fromhex("FF090002") and answer[27:31] == bytes.fromhex("FF090002")
    assert len(answer) == 33
    # LSC "status": chanStatus (col 11) + progStatus (col 13): reset is 0 + 5.
    (chan, prog) = read(session, item(0x41, 11, 1, 0x7F), item(0x41, 13, 1, 0x7F))
    assert (chan[2], prog[2]) == (b"\x00\x00", b"\x05\x00")


def test_same_column_different_areas(session: ServerSession) -> None:
    # S column 3: opMode in area B (WORD, NCVS/IOT), feedRateIpoOvr in area C (REAL8, NCVS2/IOT/LSC).
    (mode, override) = read(session, item(0x21, 3, 1, 0x7F), item(0x41, 3, 1, 0x7F))
    assert len(mode[2]) == 2 and struct.unpack("<d", override[2]) == (100.0,)
    # ... and not in area N: object does not exist, as before.
    ((rc, _ts, data),) = read(session, item(0x01, 3, 1, 0x7F))
    assert (rc, data) == (0x0A, b"")


def test_unknown_addresses_stay_object_does_not_exist(session: ServerSession) -> None:
    assert [rc for rc, _, _ in read(session, item(0x41, 500, 1, 0x7F), item(0x01, 0x15, 1, 0x3B),
                                    item(0x41, 1, 1, 0x6F))] == [0x0A, 0x0A, 0x0A]


def test_channel_group_types_and_lengths(session: ServerSession) -> None:
    # column, module, bytes: the sources' types (see variables.toml)
    expected = {
        (0x01, 0x7F): 8, (0x02, 0x7F): 8, (0x04, 0x7F): 8, (0x17, 0x7F): 2, (0x18, 0x7F): 2,
        (0x1B, 0x7F): 8, (0x1C, 0x7F): 8, (0x21, 0x7F): 32, (0x23, 0x7F): 32, (0x77, 0x7F): 8,
        (0x78, 0x7F): 8, (0x79, 0x7F): 8, (0x7A, 0x7F): 8, (0x129, 0x7F): 8, (0x12A, 0x7F): 8,
        (0x09, 0x7E): 2, (0x0A, 0x7E): 2, (0x0C, 0x7E): 2, (0x10, 0x7E): 2,
        (0x01, 0x7D): 128, (0x03, 0x7D): 32, (0x0C, 0x7D): 128, (0x10, 0x7D): 160, (0x23, 0x7D): 160,
        (0x05, 0x7A): 32, (0x0C, 0x7A): 160,
        (0x02, 0x72): 8, (0x04, 0x72): 8, (0x09, 0x72): 2, (0x0D, 0x72): 2,
        (0x19, 0x70): 8, (0x01, 0x71): 8, (0x09, 0x3B): 8, (0x0A, 0x3B): 8, (20000, 0x1A): 32,
        (27880, 0x1A): 4,
    }
    for (column, module), size in expected.items():
        ((rc, ts, data),) = read(session, item(0x41, column, 1, module))
        assert (rc, ts, len(data)) == (0xFF, 0x09, size), (hex(column), hex(module))


def test_nck_group_types_and_lengths(session: ServerSession) -> None:
    expected = {(0x01, 0x10): 4, (0x02, 0x10): 2, (0x13, 0x10): 2, (0x1F, 0x10): 2, (0x20, 0x10): 8,
                (0x4E, 0x10): 2, (0x07, 0x7F): 2, (0x121, 0x7F): 4, (0x14, 0x3B): 2,
                (0x01, 0x77): 4, (0x02, 0x77): 4, (0x02, 0x75): 4, (0x02, 0x76): 4, (0x02, 0x54): 4}
    for (column, module), size in expected.items():
        ((rc, ts, data),) = read(session, item(0x01, column, 1, module))
        assert (rc, ts, len(data)) == (0xFF, 0x09, size), (hex(column), hex(module))


def test_program_names_follow_the_selection(emulator: Emulator, session: ServerSession) -> None:
    emulator.nck.programs.select("/_N_MPF_DIR/_N_TEST_MPF")
    (path, name) = read(session, item(0x41, 0x0C, 1, 0x7A), item(0x41, 0x03, 1, 0x7D))
    assert path[2] == b"/_N_MPF_DIR/_N_TEST_MPF".ljust(160, b"\x00")
    assert name[2] == b"_N_TEST_MPF".ljust(32, b"\x00")


def test_channel_run_times_parts_and_spindle(emulator: Emulator, clock: SimulatedClock,
                                             session: ServerSession) -> None:
    channel = emulator.nck.channels[1]
    channel.state.spindles[1].commanded_rpm = 1000.0
    channel.state.spindles[1].direction = 1
    channel.run_without_program()  # a run the recording says is on (NC start needs a selected program)
    clock.advance(12.5)
    (status, net, speed) = read(session, item(0x41, 11, 1, 0x7F), item(0x41, 0x129, 1, 0x7F),
                                item(0x41, 2, 1, 0x72))
    assert status[2] == b"\x01\x00" and struct.unpack("<d", net[2]) == (12.5,)
    assert struct.unpack("<d", speed[2]) == (1000.0,)
    channel.end_program()
    (parts, old, total) = read(session, item(0x41, 0x79, 1, 0x7F), item(0x41, 0x12A, 1, 0x7F),
                               item(0x41, 0x78, 1, 0x7F))
    assert struct.unpack("<d", parts[2]) == (1.0,) and struct.unpack("<d", old[2]) == (12.5,)
    assert struct.unpack("<d", total[2]) == (1.0,)
    # spindle 2 does not exist on the default machine
    ((rc, _ts, _data),) = read(session, item(0x41, 2, 2, 0x72))
    assert rc == 0x05


def test_alarm_list_shows_the_retained_state_alarm(emulator: Emulator, clock: SimulatedClock,
                                                   session: ServerSession) -> None:
    clock.advance(3.0)
    emulator.nck.alarm_list.raise_alarm("retained state not saved: disk full", ALARM_RETAINED_STATE, ("disk full",))
    (count, first, last, event) = read(session, item(0x01, 7, 1, 0x7F), item(0x01, 2, 1, 0x77),
                                       item(0x01, 2, 1, 0x75), item(0x01, 2, 1, 0x54))
    assert count[2] == b"\x01\x00"
    assert {first[2], last[2], event[2]} == {struct.pack("<i", ALARM_RETAINED_STATE)}
    assert emulator.nck.alarm_list.pending[0].time_s == 3.0
    assert emulator.nck.alarm_list.pending[0].parameters == ("disk full",)
    ((_rc, _ts, two),) = read(session, item(0x01, 2, 1, 0x77, 2))
    assert two == struct.pack("<ii", ALARM_RETAINED_STATE, 0)
    emulator.nck.alarm_list.clear("retained state not saved: disk full")
    (count, event) = read(session, item(0x01, 7, 1, 0x7F), item(0x01, 2, 1, 0x54, 2))
    assert count[2] == b"\x00\x00" and event[2] == struct.pack("<ii", ALARM_RETAINED_STATE, ALARM_RETAINED_STATE)


def test_channel_command_over_the_wire(session: ServerSession) -> None:
    # nckemu extension NCKEMU_CHAN_COMMAND (module 0x60, column 10, area C): write 1 = start.
    parameter = b"\x05\x01" + item(0x41, 10, 1, 0x60)
    data = bytes.fromhex("00090002") + struct.pack("<H", 1)
    s7 = struct.pack(">BBHHHH", 0x32, 1, 0, 9, len(parameter), len(data)) + parameter + data
    (answer,) = session.receive(struct.pack(">BBH", 3, 0, 7 + len(s7)) + b"\x02\xF0\x80" + s7)
    assert answer[-1] == 0xFF
    ((_rc, _ts, status),) = read(session, item(0x41, 11, 1, 0x7F))
    assert status == b"\x01\x00"
