"""The standard address space from the on-disk cache: faces after the first start from it, serve the same
standard nodes as a face that built its own, and a damaged or unwritable cache only costs time."""

from __future__ import annotations

import asyncio
import dataclasses
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua

from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.faces.opcua import shelf as address_cache
from nckemu.emulator.faces.opcua.settings import OpcUaSettings
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import load_machine

pytestmark = pytest.mark.timeout(180)


async def _server_view(face: OpcUaFace) -> tuple[list[str], int, str]:
    """What a client sees of the standard nodes: the Server object's children, its state, the namespaces."""
    async with Client(face.url, timeout=10) as client:
        server = client.get_node(ua.NodeId(ua.ObjectIds.Server))
        children = sorted([(await child.read_browse_name()).Name for child in await server.get_children()])
        state = await client.get_node(ua.NodeId(ua.ObjectIds.Server_ServerStatus_State)).read_value()
        namespaces = await client.get_namespace_array()
        ns = namespaces.index("SinumerikVarProvider")
        value = await client.get_node(ua.NodeId("/Channel/State/progStatus", ns)).read_value()
        return children, int(state), f"{namespaces[-1]} {value}"


async def _start_and_view() -> tuple[Any, ...]:
    emulator = Emulator(load_machine(None))
    # the standard address space's cache alone (the models' cache: test_opcua_umati.py)
    settings = dataclasses.replace(OpcUaSettings.from_machine(emulator.machine.opcua), models=())
    face = await OpcUaFace(emulator, "127.0.0.1", 0, settings=settings).start()
    try:
        nodes = len(face.server.iserver.aspace._nodes)
        return (*await _server_view(face), nodes)
    finally:
        await face.stop()


def test_faces_after_the_first_load_the_cache_and_serve_the_same(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("NCKEMU_CACHE", "off")
    own = asyncio.run(_start_and_view())
    monkeypatch.setenv("NCKEMU_CACHE", str(tmp_path))
    building = asyncio.run(_start_and_view())
    assert address_cache.ready_shelf() is not None
    cached = asyncio.run(_start_and_view())
    assert own[:3] == building[:3] == cached[:3]
    assert "ServerStatus" in own[0] and own[1] == 0  # Running
    assert cached[3] < own[3] / 10  # nodes the face touched, not the whole standard address space
    assert not list(tmp_path.glob(".building-*"))


# Slow (make slow): each builds the standard address space again, 15-90 s on two cores; the first test
# above keeps the cache's build-and-load path in the default run.
@pytest.mark.slow
def test_a_damaged_cache_is_built_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                        caplog: pytest.LogCaptureFixture) -> None:
    monkeypatch.setenv("NCKEMU_CACHE", str(tmp_path))
    asyncio.run(_start_and_view())
    shelf = address_cache.ready_shelf()
    assert shelf is not None
    for data in shelf.parent.glob(f"{address_cache.SHELF_NAME}.*"):
        data.write_bytes(b"\x00not a shelf\x00" * 100)
    again = asyncio.run(_start_and_view())
    assert "ServerStatus" in again[0]
    assert "did not load" in caplog.text
    assert address_cache.ready_shelf() is not None  # built again for the next face
    assert "ServerStatus" in asyncio.run(_start_and_view())[0]


@pytest.mark.slow
def test_an_unwritable_cache_only_costs_time(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocked = tmp_path / "file"
    blocked.write_text("not a directory", encoding="utf-8")
    monkeypatch.setenv("NCKEMU_CACHE", str(blocked / "cache"))
    assert "ServerStatus" in asyncio.run(_start_and_view())[0]
    assert address_cache.ready_shelf() is None


@pytest.mark.parametrize("value", ["off", "", "0", "no"])
def test_the_cache_can_be_turned_off(value: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("NCKEMU_CACHE", value)
    assert address_cache.cache_root() is None and address_cache.new_shelf() is None
