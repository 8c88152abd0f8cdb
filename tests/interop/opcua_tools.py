"""An emulator with its S7 face and its OPC UA face on one background loop, for the OPC UA tests."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from nckemu.emulator.opcua import OpcUaFace
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
