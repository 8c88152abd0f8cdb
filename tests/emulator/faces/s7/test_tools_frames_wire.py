"""Tool offsets, work offsets and NCK counts over the real server: our client by name (and a write
through PUT), python-snap7 with the raw items a collector sends (LSC reads a tool's edge with one line
count; IOT reads three lines of FU column 1 as three items). Values agree with the related variables
(actTNumber/actDNumber/actToolLength1/actToolRadius, actToolBasePos/workPosition)."""

from __future__ import annotations

import struct
from collections.abc import Iterator

import pytest
import snap7

from nckemu.clients import NckClient
from nckemu.emulator.runner import EmulatorThread
from tests.emulator.faces.s7.test_field_catalogue_snap7 import item, read

PARAMS, AXES = 35, 4    # the default machine: numCuttEdgeParams, machine axes X1 Y1 SP1 Z1


@pytest.fixture
def nck(emulator: EmulatorThread) -> Iterator[NckClient]:
    with NckClient("127.0.0.1", emulator.port, timeout_s=3.0) as client:
        yield client


def test_client_reads_the_active_tool_s_edge_by_t_and_d(nck: NckClient) -> None:
    t, d, length1, radius, params = nck.get("actTNumber", "actDNumber", "actToolLength1", "actToolRadius",
                                            "numCuttEdgeParams")
    first = (d - 1) * params                        # 0-based index of P1 of edge D
    edge = nck.get(f"cuttEdgeParam[{first},T1,col{t},x{params}]")[0]
    assert len(edge) == params
    assert length1 == edge[2] + edge[11] and radius == edge[5] + edge[14]


def test_client_writes_a_tool_length_and_a_work_offset(emulator: EmulatorThread, nck: NckClient) -> None:
    t, d = nck.get("actTNumber", "actDNumber")
    nck.put({f"cuttEdgeParam[{(d - 1) * PARAMS + 2},T1,col{t}]": 130.0})
    assert nck.get("actToolLength1") == [130.0 + nck.get(f"cuttEdgeParam[{(d - 1) * PARAMS + 11},T1,col{t}]")[0]]
    frame = nck.get("actFrameIndex")[0]
    nck.put({f"linShift[{frame * AXES},C1]": 123.0})          # the active frame, machine axis 1
    machine_x, work_x, active_x = nck.get("actToolBasePos[0,C1]", "workPosition[0,C1]", "actFrameLinShift[0,C1]")
    assert active_x == 123.0 and work_x == machine_x - 123.0
    assert emulator.call(lambda: emulator.nck.frames.settable_shift_mm(1, frame * AXES + 1)) == 123.0


def test_client_reads_the_nck_counts(nck: NckClient) -> None:
    assert nck.get("numChannels", "maxnumChannels", "numGlobMachAxes", "maxnumGlobMachAxes",
                   "numMachAxes", "numUserFrames") == [1, 1, AXES, AXES, AXES, 5]


def test_snap7_reads_an_edge_in_one_item_and_three_frame_lines_as_three_items(collector: snap7.Client) -> None:
    (t,), (d,), (length1,) = (struct.unpack("<H", data) if len(data) == 2 else struct.unpack("<d", data)
                              for _rc, data in read(collector, item(0x41, 23, 1, 0x7F), item(0x41, 24, 1, 0x7F),
                                                    item(0x41, 28, 1, 0x7F)))
    ((rc, edge),) = read(collector, item(0x81, t, (d - 1) * PARAMS + 1, 0x14, PARAMS))
    assert rc == 0xFF and len(edge) == 8 * PARAMS
    values = struct.unpack(f"<{PARAMS}d", edge)
    assert length1 == values[2] + values[11]
    # IOT's read of FU column 1: three single-line items (here G54 of X1, Y1, SP1), 8 bytes each
    answers = read(collector, *(item(0x41, 1, AXES + axis, 0x12) for axis in (1, 2, 3)))
    assert [struct.unpack("<d", data)[0] for _rc, data in answers] == [400.0, 250.0, 0.0]
    ((rc, counts),) = read(collector, item(0x01, 5, 1, 0x10))
    assert (rc, counts) == (0xFF, b"\x01\x00")
