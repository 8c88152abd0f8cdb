"""Drive parameters and 828D tool data on the OPC UA face (issue 32), with asyncua's client: the node ids
public collectors read (/DriveVsa/Drive/r0035[uN], /DriveVsa/DC/R0026[uN], /Channel/State/...) give
what the S7 face gives, in the Drive realm."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest
from asyncua import ua
from asyncua.ua.uaerrors import UaStatusCodeError

from tests.support.opcua_tools import NS_URI, connect, two_faces, write_status

pytestmark = pytest.mark.timeout(120)
LATHE = Path(__file__).resolve().parents[4] / "fixtures" / "machines" / "lathe_828d.toml"


async def _read(face: Any, *ids: str) -> list[Any]:
    client = await connect(face)
    try:
        ns = await client.get_namespace_index(NS_URI)
        values = []
        for node_id in ids:
            try:
                values.append(await client.get_node(ua.NodeId(node_id, ns)).read_value())
            except UaStatusCodeError as exc:
                values.append(type(exc).__name__)
        return values
    finally:
        await client.disconnect()


def test_drive_and_tool_nodes_read_the_model() -> None:
    with two_faces(LATHE) as (emulator, face):
        emulator.call(lambda: emulator.nck.set_sensor_temperature("spindle_motor", 47.5))
        temperature, dc_link, inverter, h_number, tool_x, missing = asyncio.run(_read(
            face, "/DriveVsa/Drive/r0035[u1]", "/DriveVsa/DC/R0026[u1]", "/DriveVsa/Drive/r0037[u1, 1]",
            "/Channel/State/actHNumberFanuc32", "/Channel/State/actOriToolLength1", "/DriveVsa/Drive/r0035[u9]"))
        assert temperature == 47.5 and dc_link == 540.0
        assert inverter == pytest.approx(24.0 + 30.0 * 9.0 / 26.0)   # standing: the magnetizing current only
        assert h_number == 1 and tool_x == pytest.approx(32.51)
        assert missing == "BadAttributeIdInvalid"
        # an r-parameter is not writable; a p-parameter is, with the Drive realm's write right
        assert asyncio.run(write_status(face, "/DriveVsa/Drive/r0035[u1]", ua.Variant(1.0, ua.VariantType.Float))) \
            == "BadNotWritable"
        assert asyncio.run(write_status(face, "/DriveVsa/Drive/p0604[u1]", ua.Variant(100.0, ua.VariantType.Float))) \
            == "Good"
        assert asyncio.run(_read(face, "/DriveVsa/Drive/p0604[u1]")) == [100.0]
