"""An emulator with its S7 face and its OPC UA face on one background loop, for the OPC UA tests."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from asyncua import Client, ua
from asyncua.ua.uaerrors import UaStatusCodeError

from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.runner import EmulatorThread


@contextmanager
def two_faces(machine: str | Path | None = None, state_path: str | Path | None = None
              ) -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    """S7 on a free port and OPC UA on another, both over one Emulator (as ``serve --opcua``)."""
    with EmulatorThread(machine, state_path=state_path) as emulator:
        face = OpcUaFace(emulator.emulator, "127.0.0.1", 0)
        loop = emulator._loop  # the server's loop: the face attaches to it as serve does
        asyncio.run_coroutine_threadsafe(face.start(), loop).result(timeout=60)
        try:
            yield emulator, face
        finally:
            asyncio.run_coroutine_threadsafe(face.stop(), loop).result(timeout=30)


NS_URI = "SinumerikVarProvider"


async def connect(face: OpcUaFace, user: str | None = None, password: str | None = None) -> Client:
    """asyncua's client on the face, as ``user`` (anonymous without one)."""
    client = Client(face.url, timeout=10)
    if user:
        client.set_user(user)
        client.set_password(password or "")
    await client.connect()
    return client


async def write_status(face: OpcUaFace, node_id: str, variant: ua.Variant, user: str | None = "nckemu",
                       password: str = "SUNRISE") -> str:
    """Write one SINUMERIK node in a session of its own; the status name (Good, BadUserAccessDenied ...)."""
    client = await connect(face, user, password)
    try:
        ns = await client.get_namespace_index(NS_URI)
        try:
            await client.get_node(ua.NodeId(node_id, ns)).write_value(variant)
        except UaStatusCodeError as exc:
            return type(exc).__name__
        return "Good"
    finally:
        await client.disconnect()
