"""Without the NodeSet files the OPC UA face serves the SINUMERIK namespace alone and says in one line how
to get them."""

from __future__ import annotations

import asyncio
import logging

import pytest
from asyncua import Client

from nckemu.emulator.faces.opcua import OpcUaFace, models, nodesets
from nckemu.emulator.machine.core import Emulator

pytestmark = pytest.mark.timeout(120)


def test_without_nodesets_one_line_and_the_sinumerik_namespace(monkeypatch: pytest.MonkeyPatch,
                                                               caplog: pytest.LogCaptureFixture) -> None:
    monkeypatch.setattr(nodesets, "find", lambda configured=None: None)
    monkeypatch.setattr(models, "_TOLD_MISSING", False)

    async def go() -> tuple[bool, list[str], object]:
        face = await OpcUaFace(Emulator(), "127.0.0.1", 0).start()
        try:
            async with Client(face.url, timeout=10) as client:
                namespaces = await client.get_namespace_array()
                value = await client.get_node("ns=2;s=/Channel/State/progStatus").read_value()
            return face.models.on, namespaces, value
        finally:
            await face.stop()

    with caplog.at_level(logging.WARNING, logger="nckemu.emulator.opcua.models"):
        on, namespaces, value = asyncio.run(go())
    assert not on and nodesets.MACHINE_TOOL not in namespaces and value == 5
    told = [record.getMessage() for record in caplog.records if "make nodesets" in record.getMessage()]
    assert len(told) == 1 and "\n" not in told[0]
