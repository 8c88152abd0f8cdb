"""The machine's ways in, one sub-package each: ``s7``, ``opcua``, ``web``.

A face imports the machine (``nckemu.emulator.machine``) and never another face; what two faces
share lives in the machine. :class:`Face` is what a composer (``serve``, a fleet) asks of a face.
"""

from __future__ import annotations

from typing import Protocol


class Face(Protocol):
    """Something a served machine starts and stops on the running loop with its S7 face (the live
    machine, the HTTP page, an OPC UA face). ``serve`` also reads, where a face has them: ``ready`` (a
    dict added to the --json ready line), ``ready_line`` (a line after the ready text), and ``what``
    and ``port`` (to name it when its port cannot be bound)."""

    async def start(self) -> object: ...

    async def stop(self) -> None: ...
