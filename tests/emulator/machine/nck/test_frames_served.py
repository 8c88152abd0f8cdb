"""A program's frames on the faces: after ``TRANS``, ``AROT Z90`` and ``ASCALE`` a served channel reports the work
positions through the frame, the same over S7 (workPosition, /Channel/GeometricAxis) and OPC UA, while
the machine positions are where the axes are; reset deletes the programmable frame; a $P_UIFR write
is the NCK's stored settable frame."""

from __future__ import annotations

import asyncio
import time

import pytest
from asyncua import ua

from nckemu.clients import NckClient
from nckemu.emulator.machine.nck.channel import CHAN_INTERRUPTED
from tests.support.opcua_tools import NS_URI, connect, two_faces

PROGRAM = "/_N_MPF_DIR/_N_FRAMED_MPF"
TEXT = b"$P_UIFR[1,X,TR]=12.5\nG500 G0 X10 Y5 Z0\nTRANS X100 Y100\nAROT Z90\nASCALE X2\nG0 X3 Y4\nM0\nM30\n"


def test_work_positions_follow_the_programmed_frame_on_every_face() -> None:
    with two_faces() as (emulator, face):
        nck = emulator.emulator.nck
        channel = nck.channels[1]
        emulator.call(lambda: nck.programs.write(PROGRAM, TEXT))
        emulator.call(lambda: (channel.select(PROGRAM), channel.start()))
        deadline = time.monotonic() + 30
        while emulator.call(lambda: channel.state.status) != CHAN_INTERRUPTED:   # M0: the frame stays
            assert time.monotonic() < deadline, "the program did not reach M0"
            time.sleep(0.05)

        async def read_ua() -> list[float]:
            client = await connect(face)
            try:
                ns = await client.get_namespace_index(NS_URI)
                return [await client.get_node(ua.NodeId(f"/Channel/GeometricAxis/actToolBasePos[u1,{n}]", ns))
                        .read_value() for n in (1, 2)]
            finally:
                await client.disconnect()

        with NckClient("127.0.0.1", emulator.port) as s7:
            machine = s7.get("/Channel/MachineAxis/actToolBasePos[u1,1]", "/Channel/MachineAxis/actToolBasePos[u1,2]")
            work = s7.get("workPosition[u1,1]", "workPosition[u1,2]")
            wcs = s7.get("/Channel/GeometricAxis/actToolBasePos[u1,1]", "/Channel/GeometricAxis/actToolBasePos[u1,2]")
            over_ua = asyncio.run(read_ua())
            stored = s7.get("linShift[4,C1]")        # settable frame 1 (G54), machine axis 1 (4 axes)
            # the active frames' translations (FA): line = frame index x 4 axes + axis; PFRAME is 2
            programmed, active = s7.get("actFrameLinShift[8,C1]", "actFrameLinShift[0,C1]")
            # X3 Y4 through ASCALE X2 (6, 4), AROT Z90 (-4, 6) and TRANS: the machine; the work system 3, 4
            assert machine == pytest.approx([96.0, 106.0])
            assert work == pytest.approx([3.0, 4.0]) and wcs == pytest.approx([3.0, 4.0])
            assert over_ua == pytest.approx([3.0, 4.0])
            assert stored == [12.5]                   # the program's $P_UIFR write, stored in the NCK
            assert programmed == 100.0 and active == 100.0 + emulator.call(lambda: nck.frames.active_shift_mm(1, 1))
            emulator.call(channel.reset)
            assert s7.get("workPosition[u1,1]", "workPosition[u1,2]") == pytest.approx([96.0, 106.0])
