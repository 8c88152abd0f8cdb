"""Tool offsets, work offsets and the NCK counts, read and written with hand-built request bytes against
the default machine (T1 D1 active, G54 active; see machines/default.toml).

Addresses (rows of variables.toml name their sources): module TO 0x14 in area T unit 1 (AU 0x81),
column = T number, line = (D - 1) * numCuttEdgeParams + P; modules FU 0x12 / FA 0x13 column 1 (linShift)
in area C, line = frame index * numMachAxes + axis; S columns 16, 23, 24, 27..30; Y columns 4, 5, 11,
15, 16 (N) and 8 (C); SEGA column 25 is the work position.
"""

from __future__ import annotations

import struct

import pytest

from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import parse_machine
from tests.emulator.faces.s7.test_field_catalogue import CR_LSC, SETUP_LSC, answer_items, item, read_frame

TO, FU, FA, S, Y, SEGA, SMA = 0x14, 0x12, 0x13, 0x7F, 0x10, 0x70, 0x74
AU_TOOL, AU_CHAN, AU_NCK = 0x81, 0x41, 0x01
PARAMS = 35        # the default machine's numCuttEdgeParams
AXES = 4           # X1, Y1, SP1, Z1


def line_of(d_number: int, parameter: int) -> int:
    return (d_number - 1) * PARAMS + parameter


def connect(emulator: Emulator) -> ServerSession:
    session = ServerSession(Dispatcher.for_machine(emulator))
    session.receive(CR_LSC)
    session.receive(SETUP_LSC)
    return session


def read(session: ServerSession, *items: bytes) -> list[tuple[int, int, bytes]]:
    (answer,) = session.receive(read_frame(*items))
    return answer_items(answer)


def write_real8(session: ServerSession, address: bytes, *values: float) -> int:
    """One write item of REAL8 values (octet string, length in bytes); the item's return code."""
    parameter = b"\x05\x01" + address
    payload = struct.pack(f"<{len(values)}d", *values)
    data = bytes([0x00, 0x09]) + struct.pack(">H", len(payload)) + payload
    s7 = struct.pack(">BBHHHH", 0x32, 1, 0, 7, len(parameter), len(data)) + parameter + data
    (answer,) = session.receive(struct.pack(">BBH", 3, 0, 7 + len(s7)) + b"\x02\xF0\x80" + s7)
    return answer[-1]


def real8(data: bytes) -> list[float]:
    return list(struct.unpack(f"<{len(data) // 8}d", data))


def word(data: bytes) -> int:
    return int(struct.unpack("<H", data)[0])


@pytest.fixture
def emulator() -> Emulator:
    return Emulator()


@pytest.fixture
def session(emulator: Emulator) -> ServerSession:
    return connect(emulator)


def test_active_tool_values_are_those_of_its_edge(session: ServerSession) -> None:
    t, d, radius, length1, length2, ident = read(
        session, item(AU_CHAN, 23, 1, S), item(AU_CHAN, 24, 1, S), item(AU_CHAN, 27, 1, S),
        item(AU_CHAN, 28, 1, S), item(AU_CHAN, 29, 1, S), item(AU_CHAN, 33, 1, S))
    t_number, d_number = word(t[2]), word(d[2])
    assert (t_number, d_number) == (1, 1) and ident[2].rstrip(b"\x00") == b"END_MILL_D10"
    # the whole edge in one item, as LSC reads a tool's parameters with one line count
    ((rc, ts, edge),) = read(session, item(AU_TOOL, t_number, line_of(d_number, 1), TO, PARAMS))
    assert (rc, ts, len(edge)) == (0xFF, 0x09, 8 * PARAMS)
    p = real8(edge)
    assert p[0] == 120.0 and (p[2], p[5]) == (125.0, 5.0)
    assert real8(length1[2]) == [p[2] + p[11]] and real8(radius[2]) == [p[5] + p[14]]
    assert real8(length2[2]) == [p[3] + p[12]] == [0.0]
    ((_rc, _ts, count),) = read(session, item(AU_NCK, 11, 1, Y))
    assert word(count) == PARAMS


def test_tool_change_and_an_edge_write_follow_through(emulator: Emulator, session: ServerSession) -> None:
    emulator.nck.select_tool(2, 2)
    t, d, length1 = read(session, item(AU_CHAN, 23, 1, S), item(AU_CHAN, 24, 1, S), item(AU_CHAN, 28, 1, S))
    assert (word(t[2]), word(d[2]), real8(length1[2])) == (2, 2, [141.5])
    # the operator corrects D2's length 1 and its wear: the active length follows at once
    assert write_real8(session, item(AU_TOOL, 2, line_of(2, 3), TO), 150.0) == 0xFF
    assert write_real8(session, item(AU_TOOL, 2, line_of(2, 12), TO), -0.25) == 0xFF
    ((_rc, _ts, length1),) = read(session, item(AU_CHAN, 28, 1, S))
    assert real8(length1) == [149.75]
    ((_rc, _ts, geometry),) = read(session, item(AU_TOOL, 2, line_of(2, 3), TO))
    assert real8(geometry) == [150.0]
    # D1 of T2 is untouched; T0 D0 means no offset
    ((_rc, _ts, other),) = read(session, item(AU_TOOL, 2, line_of(1, 3), TO))
    assert real8(other) == [140.0]
    emulator.nck.select_tool(0, 0)
    t, length1, ident = read(session, item(AU_CHAN, 23, 1, S), item(AU_CHAN, 28, 1, S), item(AU_CHAN, 33, 1, S))
    assert (word(t[2]), real8(length1[2]), ident[2]) == (0, [0.0], bytes(32))


def test_tools_and_edges_that_do_not_exist(session: ServerSession) -> None:
    # T3 is not in the table: object does not exist; T1 has one edge, so D2 P1 is out of range, and so
    # is a span of 10 lines from P(PARAMS - 5) of D1 that runs into D2
    no_tool, no_edge, spans = read(session, item(AU_TOOL, 3, 1, TO), item(AU_TOOL, 1, line_of(2, 1), TO),
                                   item(AU_TOOL, 1, PARAMS - 5, TO, 10))
    assert [no_tool[0], no_edge[0], spans[0]] == [0x0A, 0x05, 0x05]
    # the TO module is not served in the channel area (the sources read it in area T)
    ((rc, _ts, _data),) = read(session, item(AU_CHAN, 1, 1, TO))
    assert rc == 0x0A


def test_work_offsets_and_the_work_position(emulator: Emulator, session: ServerSession) -> None:
    emulator.nck.set_axis_position(1, 600.0)
    emulator.nck.set_axis_position(4, -500.0)
    index, frames, work, machine = read(
        session, item(AU_CHAN, 16, 1, S), item(AU_CHAN, 1, 1, FU, 3 * AXES), item(AU_CHAN, 25, 1, SEGA, AXES),
        item(AU_CHAN, 2, 1, SMA, AXES))
    assert word(index[2]) == 1                     # G54
    g500, g54, g55 = (real8(frames[2])[i * AXES:(i + 1) * AXES] for i in range(3))
    assert g500 == [0.0] * AXES and g54 == [400.0, 250.0, 0.0, -350.0] and g55[0] == 900.0
    assert real8(work[2]) == [m - s for m, s in zip(real8(machine[2]), g54, strict=True)]
    # active frames: ACTFRAME, IFRAME and TOTFRAME carry G54; PFRAME (2) is zero
    ((_rc, _ts, active),) = read(session, item(AU_CHAN, 1, 1, FA, 5 * AXES))
    actframe, iframe, pframe, _ext, totframe = (real8(active)[i * AXES:(i + 1) * AXES] for i in range(5))
    assert actframe == iframe == totframe == g54 and pframe == [0.0] * AXES
    # G55 selected: the work position and the active frame follow
    emulator.nck.select_frame(2)
    index, work_x, act_x = read(session, item(AU_CHAN, 16, 1, S), item(AU_CHAN, 25, 1, SEGA),
                                item(AU_CHAN, 1, 1, FA))
    assert word(index[2]) == 2 and real8(work_x[2]) == [600.0 - 900.0] and real8(act_x[2]) == [900.0]


def test_a_work_offset_written_over_the_wire_moves_the_work_position(emulator: Emulator,
                                                                     session: ServerSession) -> None:
    g54_z = 1 * AXES + 4
    assert write_real8(session, item(AU_CHAN, 1, g54_z, FU), -420.5) == 0xFF
    frame, work_z = read(session, item(AU_CHAN, 1, g54_z, FU), item(AU_CHAN, 25, 4, SEGA))
    assert real8(frame[2]) == [-420.5]
    assert real8(work_z[2]) == [emulator.nck.actual_position_mm(4) + 420.5]
    # the active frames are read only; frames past G57 do not exist on the default machine
    assert write_real8(session, item(AU_CHAN, 1, 1, FA), 1.0) == 0x03
    ((rc, _ts, _data),) = read(session, item(AU_CHAN, 1, 5 * AXES + 1, FU))
    assert rc == 0x05


def test_write_levels_of_the_offsets_are_the_catalogue_s() -> None:
    """A machine that protects the work offsets (write_level 3) refuses a level-7 connection."""
    text = """
[[axis]]
number = 1
name = "X1"

[[var]]
name = "linShift"
number = "FU1"
module = 0x12
column = 1
areas = ["C"]
type = "REAL8"
lines = 3100
write_level = 3
source = "frames.settable_shift"
"""
    session = connect(Emulator(parse_machine(text, "m.toml")))
    assert write_real8(session, item(AU_CHAN, 1, 2, FU), 5.0) == 0x03


def test_nck_counts_follow_the_machine() -> None:
    text = """
channels = 2
[[axis]]
number = 1
name = "X1"
[[axis]]
number = 2
name = "Z1"
[[axis]]
number = 5
name = "C1"
rotary = true
"""
    session = connect(Emulator(parse_machine(text, "m.toml")))
    values = read(session, *(item(AU_NCK, column, 1, Y) for column in (4, 5, 11, 15, 16)),
                  item(AU_CHAN, 8, 1, Y), item(AU_CHAN, 3, 1, Y))
    assert [word(data) for _rc, _ts, data in values] == [2, 2, 25, 5, 3, 5, 3]
