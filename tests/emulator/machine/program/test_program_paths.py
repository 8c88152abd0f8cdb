"""Positions on the path while a served program runs (issue 49): during a G3 full circle the axes are on
the circle at every instant a client reads them, over S7 (python-snap7 through our client) and over OPC
UA (asyncua), as on the control; before, every face showed them on the chord (a full circle never moved
X or Y). The offline recording's samples (``program run --out``) lie on the circle too."""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Iterator

import pytest
from asyncua import ua

from nckemu.clients.sync import NckClient
from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.machine.clock import LiveClock, SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.offline import recording_columns, run_offline
from nckemu.emulator.runner import EmulatorThread
from tests.support.opcua_tools import NS_URI, connect

PATH = "/_N_MPF_DIR/_N_CIRCLE_MPF"
# A full circle about (50, 100) of radius 50 from (100, 100): 314.16 mm at 25 mm/s, 12.6 s simulated.
CIRCLE = "G17 G90 G3 X100 Y100 I-50 J0 F1500\nM30\n"
CENTRE, RADIUS = (50.0, 100.0), 50.0
X_AXIS, Y_AXIS = 1, 2          # the default machine: X1, Y1, SP1, Z1
POSITIONS = [f"/Channel/MachineAxis/actToolBasePos[u1,{n}]" for n in (X_AXIS, Y_AXIS)]


def _off_circle_mm(x: float, y: float) -> float:
    return abs(math.hypot(x - CENTRE[0], y - CENTRE[1]) - RADIUS)


def _assert_went_round(points: list[tuple[float, float]]) -> None:
    """Every point on the circle, and the points reach its far side, its top and its bottom."""
    assert points and max(_off_circle_mm(x, y) for x, y in points) < 1e-6
    xs, ys = [x for x, _ in points], [y for _, y in points]
    assert min(xs) < 20.0 and max(ys) > 130.0 and min(ys) < 70.0, points


@pytest.fixture
def served() -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    emulator = Emulator(clock=LiveClock(speed=4.0))
    emulator.nck.programs.write(PATH, CIRCLE.encode())
    emulator.nck.axes.set_position(X_AXIS, 100.0)
    emulator.nck.axes.set_position(Y_AXIS, 100.0)
    with EmulatorThread(emulator=emulator) as emu:
        face = OpcUaFace(emulator, "127.0.0.1", 0)  # the SINUMERIK namespace: no companion model needed
        asyncio.run_coroutine_threadsafe(face.start(), emu._loop).result(timeout=60)
        try:
            yield emu, face
        finally:
            asyncio.run_coroutine_threadsafe(face.stop(), emu._loop).result(timeout=30)


def _start(emu: EmulatorThread) -> None:
    channel = emu.emulator.nck.channels[1]
    emu.call(lambda: (channel.select(PATH), channel.start()))


def _running(emu: EmulatorThread) -> bool:
    return emu.emulator.nck.channels[1].run is not None


def test_s7_reads_positions_on_the_arc(served: tuple[EmulatorThread, OpcUaFace]) -> None:
    emu, _ = served
    points: list[tuple[float, float]] = []
    with NckClient("127.0.0.1", emu.port) as s7:
        _start(emu)
        deadline = time.monotonic() + 30.0
        while _running(emu) and time.monotonic() < deadline:
            x, y = s7.get(*POSITIONS)
            points.append((x, y))
            time.sleep(0.05)
    _assert_went_round(points)


def test_opcua_reads_positions_on_the_arc(served: tuple[EmulatorThread, OpcUaFace]) -> None:
    emu, face = served

    async def watch() -> list[tuple[float, float]]:
        client = await connect(face)
        try:
            ns = await client.get_namespace_index(NS_URI)
            nodes = [client.get_node(ua.NodeId(path, ns)) for path in POSITIONS]
            points = []
            _start(emu)
            deadline = time.monotonic() + 30.0
            while _running(emu) and time.monotonic() < deadline:
                values = await client.read_values(nodes)
                points.append((values[0], values[1]))
                await asyncio.sleep(0.05)
            return points
        finally:
            await client.disconnect()

    _assert_went_round(asyncio.run(watch()))


def test_the_offline_recording_samples_lie_on_the_arc() -> None:
    emulator = Emulator(clock=SimulatedClock())
    emulator.nck.programs.write(PATH, CIRCLE.encode())
    emulator.nck.axes.set_position(X_AXIS, 100.0)
    emulator.nck.axes.set_position(Y_AXIS, 100.0)
    rows: list[list[float]] = []
    result = run_offline(emulator, PATH, on_sample=rows.append, sample_s=0.5, cycle_s=0.25)
    assert result.outcome == "ended"
    columns = recording_columns(emulator)
    x, y = columns.index("pos_X_mm"), columns.index("pos_Y_mm")
    _assert_went_round([(row[x], row[y]) for row in rows])
    # at constant speed (its ramps take 0.025 s) the angle grows with time: at 6 s of 12.59 s the tool has
    # turned 171.6° counter-clockwise from (100, 100), near the far side (0, 100)
    total_s = result.net_time_s
    assert total_s == pytest.approx(2 * math.pi * RADIUS / 25.0 + 25.0 / 1000.0)
    middle = next(row for row in rows if row[0] == pytest.approx(6.0))
    angle = 2 * math.pi * 6.0 / total_s
    assert (middle[x], middle[y]) == pytest.approx((CENTRE[0] + RADIUS * math.cos(angle),
                                                    CENTRE[1] + RADIUS * math.sin(angle)), abs=0.05)


def test_the_block_table_names_the_point_half_way_along_each_arc() -> None:
    """A row shows where its block ends; an arc's row also names the point half-way along it, on the
    arc (G2 and G3 from the same points go opposite ways round), and a helix's middle its height too."""
    emulator = Emulator(clock=SimulatedClock())
    program = "G17 G90 G0 X0 Y0\nG2 X20 Y0 I10 J0 F600\nG3 X40 Y0 Z-5 CR=10 F600\nG1 X50\nM30\n"
    emulator.nck.programs.write(PATH, program.encode())
    rows = []
    emulator.nck.channels[1].block_listeners.append(rows.append)
    assert run_offline(emulator, PATH).outcome == "ended"
    notes = {row.text: row.note for row in rows}
    assert notes["G2 X20 Y0 I10 J0 F600"] == "through X10.0000 Y10.0000 at its middle"
    assert notes["G3 X40 Y0 Z-5 CR=10 F600"] == "through X30.0000 Y-10.0000 Z-2.5000 at its middle"
    assert notes["G1 X50"] == ""
