"""The OPC UA face as an MES/dashboard integrator reads it (issue 43): units a client can look up,
identities that tell machines apart, rights shown before a write fails, and values equal across faces.
"""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from typing import Any

import pytest
from asyncua import Client, ua

from nckemu.emulator.faces.opcua import OpcUaFace, nodesets
from nckemu.emulator.runner import EmulatorThread

from .opcua_tools import connect, two_faces

pytestmark = [pytest.mark.timeout(300)]
needs_models = pytest.mark.skipif(nodesets.find() is None, reason=nodesets.how_to_get())

UNECE = "http://www.opcfoundation.org/UA/units/un/cefact"
# UNECE Recommendation 20 common codes the instances may use: code -> (symbol, name)
RECOMMENDATION_20 = {
    "MMT": ("mm", "millimetre"), "DD": ("°", "degree [unit of angle]"), "H81": ("mm/min", "millimetre per minute"),
    "P1": ("%", "percent"), "RPM": ("r/min", "revolutions per minute"), "KWT": ("kW", "kilowatt"),
    "NU": ("N·m", "newton metre"),
}


def code_of(unit_id: int) -> str:
    """The letters a UnitId was made of (OPC 10000-8: one byte a letter, the first the highest)."""
    letters = []
    while unit_id:
        letters.append(chr(unit_id & 0xFF))
        unit_id >>= 8
    return "".join(reversed(letters))


def unit_id_of(code: str) -> int:
    return sum(ord(letter) << (8 * position) for position, letter in enumerate(reversed(code)))


def test_unit_ids_are_the_letters_of_their_code() -> None:
    assert unit_id_of("KWT") == 4937556 and unit_id_of("NU") == 20053
    assert unit_id_of("H81") == 4732977 and unit_id_of("RPM") == 5394509 and unit_id_of("P1") == 20529
    assert code_of(unit_id_of("MMT")) == "MMT"


@pytest.fixture(scope="module")
def faces() -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    with two_faces() as pair:
        yield pair


def run(coroutine: Any) -> Any:
    return asyncio.run(coroutine)


async def _variables(client: Client, root: Any) -> list[tuple[str, Any]]:
    """Every variable below ``root`` (browse path, node), depth first."""
    found: list[tuple[str, Any]] = []

    async def walk(node: Any, path: str, depth: int) -> None:
        if depth > 10:
            return
        for description in await node.get_children_descriptions():
            child = client.get_node(description.NodeId)
            where = f"{path}/{description.BrowseName.Name}"
            if description.NodeClass == ua.NodeClass.Variable:
                found.append((where, child))
            if description.NodeClass in (ua.NodeClass.Object, ua.NodeClass.Variable):
                await walk(child, where, depth + 1)

    await walk(root, "", 0)
    return found


async def _instance_roots(client: Client) -> list[tuple[str, Any]]:
    namespaces = await client.get_namespace_array()
    machines = await client.nodes.objects.get_child(f"{namespaces.index(nodesets.MACHINERY)}:Machines")
    cnc = await client.nodes.objects.get_child(f"{namespaces.index(nodesets.CNC)}:CncInterface")
    return [("Machines", machines), ("CncInterface", cnc)]


@needs_models
def test_every_engineering_unit_is_a_unece_common_code_with_its_unit_id(faces: tuple[EmulatorThread, OpcUaFace]
                                                                        ) -> None:
    async def go() -> dict[str, tuple[str, str, str]]:
        client = await connect(faces[1])
        try:
            units: dict[str, tuple[str, str, str]] = {}
            for name, root in await _instance_roots(client):
                for path, node in await _variables(client, root):
                    if path.endswith("/EngineeringUnits"):
                        unit = await node.read_value()
                        assert isinstance(unit, ua.EUInformation), path
                        assert unit.NamespaceUri == UNECE, path
                        code = code_of(unit.UnitId)
                        assert unit.UnitId == unit_id_of(code), path
                        units[name + path] = (code, unit.DisplayName.Text, unit.Description.Text)
            return units
        finally:
            await client.disconnect()

    units = run(go())
    assert len(units) > 20
    for path, (code, symbol, name) in units.items():
        assert code in RECOMMENDATION_20, f"{path}: UnitId of {code!r}, no common code"
        assert (symbol, name) == RECOMMENDATION_20[code], path
    by_name = {path.rsplit("/", 2)[-2]: code for path, (code, _s, _n) in units.items()}
    assert by_name["ActPower"] == "KWT" and by_name["ActTorque"] == "NU" and by_name["ActSpeed"] == "RPM"
    assert by_name["ActFeedrate"] == "H81" and by_name["DryRunFeed"] == "H81" and by_name["ActLoad"] == "P1"
