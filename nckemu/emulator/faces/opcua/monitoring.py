"""Monitored items of the OPC UA face: asyncua's value callbacks do not feed monitored items, so the
face pushes their values itself.

A write to the model captures, there and then, the new raw value of every monitored item it touched; one
pusher task hands the captured values to the monitored items in the order they were written. Capturing
at the write (not reading at the push) keeps each value even when the next write lands before the
pusher runs, so every change a writer makes reaches the item's queue. The sampler reads only the
monitored nodes every ``sample_interval_ms`` and captures what changes without a write (the machine's
own dynamics, sensors, PI services, the PLC program's memory).
"""

from __future__ import annotations

import asyncio
import bisect
import logging
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from asyncua import Server, ua
from asyncua.server.address_space import NodeData

from nckemu.catalogue.node_ids import NcNodeName, NodeName, PlcNodeName
from nckemu.emulator.faces.opcua import asyncua_internals
from nckemu.emulator.faces.opcua.values import PLC_AREAS, UaStatus, raw_reader, variant_from_raw
from nckemu.errors import NckNodeIdError
from nckemu.protocol.addresses import S7Area

if TYPE_CHECKING:
    from nckemu.emulator.faces.opcua.parts import MonitoringHost

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.opcua.face")


class Monitoring:
    """The monitored items of one face: which nodes are monitored, what was captured, the pusher and the
    sampler. ``install`` before the server starts, ``start`` on the face's loop, ``stop`` at the end."""

    def __init__(self, face: MonitoringHost) -> None:
        self.face = face
        self._monitored: dict[ua.NodeId, _Monitored] = {}
        self._plc_index: _PlcIndex | None = None  # rebuilt after the monitored set changed
        self._pending: list[tuple[_Monitored, object]] = []  # captured at the write, pushed in order
        self._push_scheduled = False
        self._pusher: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._loop_thread = 0
        self._sampler: asyncio.Task[None] | None = None
        self.updates_pushed = 0

    def install(self, server: Server) -> None:
        aspace = server.iserver.aspace
        face, monitored = self.face, self._monitored

        def added(nodeid: ua.NodeId, attr: ua.AttributeIds, result: tuple[Any, int]) -> None:
            if attr != ua.AttributeIds.Value or nodeid in monitored or not result[0].is_good():
                return
            if nodeid.NamespaceIndex == face.namespace:
                try:  # parsed again if the name cache was full when the node was made
                    name: NodeName | None = face.node_name(str(nodeid.Identifier))
                except NckNodeIdError:
                    name = None  # a folder
                if name is not None:
                    # The baseline is the value the monitored item has just read itself.
                    monitored[nodeid] = _Monitored(aspace[nodeid], name, raw_reader(face.emulator, name))
                    self._plc_index = None
                return
            fed = face.models.monitor(nodeid)  # a companion model's variable fed from the machine
            if fed is not None:
                monitored[nodeid] = fed
                self._plc_index = None

        def deleted(nodeid: ua.NodeId | None) -> None:
            if nodeid is not None and nodeid in monitored:
                node = aspace.get(nodeid)
                if node is None or not node.attributes[ua.AttributeIds.Value].datachange_callbacks:
                    del monitored[nodeid]
                    self._plc_index = None

        asyncua_internals.intercept_datachange(
            aspace, added, lambda handle: asyncua_internals.node_of_handle(aspace, handle), deleted)

    def start(self) -> None:
        self._listen()
        self._sampler = asyncio.get_running_loop().create_task(self._sample_forever())

    async def stop(self) -> None:
        self._unlisten()
        if self._pusher is not None:
            self._pusher.cancel()
        if self._sampler is not None:
            self._sampler.cancel()
            try:
                await self._sampler
            except asyncio.CancelledError:
                pass
            self._sampler = None

    def _listen(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._loop_thread = threading.get_ident()
        self.face.emulator.plc.write_listeners.append(self._plc_written)
        self.face.emulator.nck.write_listeners.append(self._nc_written)

    def _unlisten(self) -> None:
        for listeners, listener in ((self.face.emulator.plc.write_listeners, self._plc_written),
                                    (self.face.emulator.nck.write_listeners, self._nc_written)):
            if listener in listeners:
                listeners.remove(listener)

    def _plc_written(self, area: int, db_number: int, start_byte: int, size_bytes: int) -> None:
        if self._plc_index is None:
            self._plc_index = _PlcIndex(self._monitored.values())
        touched = self._plc_index.touched(area, db_number, start_byte, start_byte + size_bytes)
        if touched:
            self._capture(touched)

    def _nc_written(self, _address: Any) -> None:
        # One NC write can move other NC values (a compensation value moves positions): all NC items.
        self._capture([entry for entry in self._monitored.values() if entry.nc])

    def _capture(self, entries: Any) -> int:
        """Queue the raw value of each entry that differs from the one queued last; how many."""
        captured = 0
        for entry in entries:
            try:
                raw = entry.reader()
            except Exception:  # the variable went away (a DB shrank): the client keeps its last value
                continue
            if raw != entry.raw:
                entry.raw = raw
                self._pending.append((entry, raw))
                captured += 1
        if captured:
            self._schedule_push()
        return captured

    def _schedule_push(self) -> None:
        if self._push_scheduled or self._pusher is not None or self._loop is None:
            return  # a pusher running takes what was queued meanwhile before it ends
        self._push_scheduled = True
        if threading.get_ident() == self._loop_thread:
            self._loop.call_soon(self._start_push)
        else:  # a writer on another thread (a test driving the model directly)
            self._loop.call_soon_threadsafe(self._start_push)

    def _start_push(self) -> None:
        self._push_scheduled = False
        if self._pusher is None and self._loop is not None:
            self._pusher = self._loop.create_task(self._drain())

    async def _drain(self) -> None:
        try:
            while self._pending:
                batch, self._pending = self._pending, []
                await self._push(batch)
        except Exception:  # a pusher must not die silently; what it could not push is dropped, logged
            log.exception("OPC UA pusher")
        finally:
            self._pusher = None

    async def _sample_forever(self) -> None:
        interval_s = self.face.settings.sample_interval_ms / 1000.0
        next_s = time.monotonic()
        while True:
            next_s += interval_s
            try:
                self.sample()
            except Exception:  # a sampler must keep sampling; the fault is logged
                log.exception("OPC UA sampler")
            delay = next_s - time.monotonic()
            if delay < 0:
                next_s = time.monotonic()
                delay = 0
            await asyncio.sleep(delay)

    def sample(self) -> int:
        """Queue the monitored values that changed since they were last queued; how many."""
        return self._capture(list(self._monitored.values()))

    async def _push(self, batch: list[tuple[_Monitored, object]]) -> None:
        now = datetime.now(UTC)
        value_attribute = ua.AttributeIds.Value
        pushed = 0
        for entry, raw in batch:
            try:
                variant = entry.to_variant(raw)
            except (UaStatus, ValueError, TypeError, IndexError):
                continue
            value = _PushedValue(variant, SourceTimestamp=now, ServerTimestamp=now)
            for handle, callback in list(entry.node.attributes[value_attribute].datachange_callbacks.items()):
                await callback(handle, value)
            pushed += 1
        self.updates_pushed += pushed


class _PushedValue(ua.DataValue):
    """A value pushed to monitored items. asyncua deep-copies every value it is handed, once per
    monitored item, so that the writer cannot change it afterwards; the face builds a new one for each
    push and never changes it, so the copy may be the value itself (the copy cost more than the rest
    of a push together)."""

    def __deepcopy__(self, memo: dict[int, Any]) -> _PushedValue:
        return self


class _Monitored:
    """A monitored SINUMERIK variable: its node, parsed name, a raw reader and the raw value last pushed."""

    __slots__ = ("node", "name", "reader", "raw", "nc", "block", "first_byte", "end_byte")

    def __init__(self, node: NodeData, name: NodeName, reader: Callable[[], object]) -> None:
        self.node, self.name, self.reader = node, name, reader
        self.raw = _raw_now(reader)
        self.nc = isinstance(name, NcNodeName)
        self.block: tuple[int, int] | None = None
        self.first_byte = self.end_byte = 0
        if isinstance(name, PlcNodeName):
            area = PLC_AREAS[name.area]
            self.block = (area, name.db if area == S7Area.DB else 0)
            self.first_byte = name.byte
            self.end_byte = name.byte + (_STRING_BYTES if name.kind == "STRING" else max(1, name.size_bytes))

    def to_variant(self, raw: object) -> ua.Variant:
        return variant_from_raw(self.name, raw)


_STRING_BYTES = 256  # an S7 string: maximum length, length, up to 254 characters


class _PlcIndex:
    """Monitored PLC items by memory block and byte range, to find what a write touched."""

    def __init__(self, entries: Any) -> None:
        by_block: dict[tuple[int, int], list[_Monitored]] = {}
        for entry in entries:
            if entry.block is not None:
                by_block.setdefault(entry.block, []).append(entry)
        self._blocks: dict[tuple[int, int], tuple[list[int], list[_Monitored], int]] = {}
        for block, items in by_block.items():
            items.sort(key=lambda item: item.first_byte)
            longest = max(item.end_byte - item.first_byte for item in items)
            self._blocks[block] = ([item.first_byte for item in items], items, longest)

    def touched(self, area: int, db_number: int, first_byte: int, end_byte: int) -> list[_Monitored]:
        found = self._blocks.get((area, db_number if area == S7Area.DB else 0))
        if found is None:
            return []
        starts, items, longest = found
        low = bisect.bisect_left(starts, first_byte - longest + 1)
        high = bisect.bisect_left(starts, end_byte)
        return [item for item in items[low:high] if item.end_byte > first_byte]


def _raw_now(reader: Callable[[], object]) -> object:
    try:
        return reader()
    except Exception:  # read errors are the client's to see on its own reads; None: compare afresh
        return None
