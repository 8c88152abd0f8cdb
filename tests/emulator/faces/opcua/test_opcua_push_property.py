"""Property: whatever sequence of S7 writes lands on PLC memory, each monitored item receives exactly the
values its bytes took, in order, once each (no loss, no repeats), however the writes straddle items."""

from __future__ import annotations

import asyncio
import struct
import time
from collections.abc import Iterator
from typing import Any

import pytest
import snap7
from asyncua import Client, ua
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.runner import EmulatorThread
from tests.support.opcua_tools import two_faces

pytestmark = pytest.mark.timeout(300)
DB = 130
AREA_BYTES = 24  # DBB 200..223 of DB130
BASE = 200
ITEMS = [("DBW", 0, 2), ("DBW", 2, 2), ("DBD", 4, 4), ("DBB", 8, 1), ("DBW", 10, 2), ("DBD", 12, 4),
         ("DBW", 20, 2)]


@pytest.fixture(scope="module")
def faces() -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    with two_faces() as pair:
        yield pair


def _node_id(kind: str, offset: int) -> str:
    return f"/Plc/DB{DB}.{kind}{BASE + offset}"


def _value(memory: bytes, kind: str, offset: int, size: int) -> int:
    return int.from_bytes(memory[offset:offset + size], "big")


writes = st.lists(st.tuples(st.integers(0, AREA_BYTES - 1), st.binary(min_size=1, max_size=8)),
                  min_size=1, max_size=12)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(writes=writes, watched=st.sets(st.sampled_from(range(len(ITEMS))), min_size=1))
def test_each_item_sees_every_value_its_bytes_took(faces: tuple[EmulatorThread, OpcUaFace],
                                                   writes: list[tuple[int, bytes]], watched: set[int]) -> None:
    emulator, face = faces
    start = bytes(AREA_BYTES)
    emulator.emulator.plc.write(0x84, DB, BASE, start)
    memory = bytearray(start)
    expected: dict[str, list[int]] = {_node_id(kind, off): [] for i, (kind, off, _) in enumerate(ITEMS) if i in watched}
    for offset, data in writes:
        data = data[:AREA_BYTES - offset]
        before = bytes(memory)
        memory[offset:offset + len(data)] = data
        for index in watched:
            kind, off, size = ITEMS[index]
            if _value(before, kind, off, size) != _value(bytes(memory), kind, off, size):
                expected[_node_id(kind, off)].append(_value(bytes(memory), kind, off, size))
    seen: dict[str, list[int]] = {name: [] for name in expected}

    class Handler:
        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            seen[str(node.nodeid.Identifier)].append(int(value))

    def write_all() -> None:
        plc = snap7.Client()
        plc.connect("127.0.0.1", 0, 2, emulator.port)
        try:
            for offset, data in writes:
                plc.db_write(DB, BASE + offset, bytearray(data[:AREA_BYTES - offset]))
        finally:
            plc.disconnect()

    async def go() -> None:
        async with Client(face.url, timeout=10) as client:
            ns = await client.get_namespace_index("SinumerikVarProvider")
            subscription = await client.create_subscription(100, Handler())
            await subscription.subscribe_data_change([client.get_node(ua.NodeId(name, ns)) for name in expected],
                                                     queuesize=100)
            await asyncio.sleep(0.25)
            for name in seen:
                assert seen[name] == [0], (name, seen[name])  # the first notification: the value now
                seen[name].clear()
            await asyncio.to_thread(write_all)
            deadline = time.monotonic() + 2.0
            while time.monotonic() < deadline and any(len(seen[n]) < len(expected[n]) for n in expected):
                await asyncio.sleep(0.05)
            await asyncio.sleep(0.25)  # and nothing more arrives

    asyncio.run(go())
    assert seen == expected


def test_the_items_read_what_they_name() -> None:
    memory = struct.pack(">HHIB", 1, 2, 3, 4)
    assert [_value(memory, k, o, s) for k, o, s in ITEMS[:4]] == [1, 2, 3, 4]
