"""Retained data saved off the event loop, many writes to one save (a group commit).

A face acknowledges a write of retained data only once a save holding it has ended. Saving on the
event loop (``Emulator.persist``) made every client of every face wait for each fsync; here a face
asks for a save (``request``) and holds that answer until the save is done (the S7 face: that
connection's answers until ``after_requests`` is done; the OPC UA face's handlers ``await
durable()``), and everyone else is served meanwhile. One save runs at a time: the snapshot is taken and encoded
on the loop (the machine does not change under it), the file is written and synced in a thread, and
every write asked for before the snapshot was taken is then acknowledged together.
"""

from __future__ import annotations

import asyncio
from typing import Protocol

from nckemu.emulator.machine.state import RetainedStore


class RetainedSource(Protocol):
    """What a group save needs of the machine (the Emulator is one): no import of the machine's core, so
    the two modules are no circle."""

    @property
    def store(self) -> RetainedStore | None: ...

    def encode_retained(self) -> tuple[bytes, int]: ...

    def saved(self, exc: Exception | None) -> None: ...


class GroupSaves:
    def __init__(self, emulator: RetainedSource) -> None:
        self._emulator = emulator
        self.requested = 0  # saves asked for so far: a caller compares it before and after its work
        self._waiting: list[tuple[int, asyncio.Future[None]]] = []
        self._saver: asyncio.Task[None] | None = None
        self.saves = 0  # saves done, for the benches (how many writes one save carried)

    @property
    def enabled(self) -> bool:
        return self._emulator.store is not None

    def request(self) -> None:
        """Retained data changed: a save is due (``after_requests`` waits for it)."""
        self.requested += 1

    async def durable(self) -> None:
        """Return once every change asked for so far is on disk (at once without a state file): for
        handlers that answer after awaiting, as the OPC UA face's."""
        if self.enabled:
            await self.after_requests()

    def after_requests(self) -> asyncio.Future[None]:
        """Done when a save that holds every change requested so far has ended (written, or failed
        with the alarm raised: as ``persist``, a failed save does not hold the answer back forever)."""
        loop = asyncio.get_running_loop()
        future: asyncio.Future[None] = loop.create_future()
        self._waiting.append((self.requested, future))
        if self._saver is None:
            self._saver = loop.create_task(self._save_while_asked())
        return future

    async def _save_while_asked(self) -> None:
        emulator, store = self._emulator, self._emulator.store
        assert store is not None, "saves are asked for only with a state file (enabled)"
        try:
            while self._waiting:
                covered = self.requested
                error: Exception | None = None
                try:
                    data, sequence = emulator.encode_retained()
                    await asyncio.to_thread(store.write, data, sequence)
                except Exception as exc:  # noqa: BLE001 - any failure is an alarm, never a lost answer
                    error = exc
                emulator.saved(error)
                self.saves += 1
                still = []
                for wanted, future in self._waiting:
                    if wanted > covered:
                        still.append((wanted, future))
                    elif not future.done():
                        future.set_result(None)
                self._waiting = still
        finally:
            self._saver = None
            for _wanted, future in self._waiting:  # cancelled (the loop is closing): nobody waits on
                if not future.done():
                    future.cancel()
            self._waiting = []
