"""The asyncio transport: accept, frame, hand bytes to a sans-IO session, write the answers.

Everything protocol-related happens in ``session.py``; this module only moves bytes and enforces
the limits a transport can see (connections, idle time, unread answers).
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from nckemu.capture import CaptureWriter
from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.saves import GroupSaves

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.server")


@dataclass(frozen=True)
class ServerLimits:
    """Transport limits; each has a test that hits it (docs/limits.md)."""

    max_connections: int = 64
    idle_timeout_s: float = 300.0
    # Answers a client does not read pile up in the socket buffer; past this we stop reading it,
    # and if it stays that way for write_stall_timeout_s we close the connection.
    write_buffer_high_bytes: int = 256 * 1024
    write_stall_timeout_s: float = 30.0
    # A frame begun must be complete within this time (a client sending one byte a second).
    partial_frame_timeout_s: float = 10.0


# Bytes taken from one connection per event-loop turn. asyncio would hand over 256 KiB at once: a
# client flooding jobs then holds the loop for hundreds of milliseconds while the others wait.
READ_CHUNK_BYTES = 4 * 1024


class _Connection(asyncio.BufferedProtocol):
    def __init__(self, server: EmulatorServer) -> None:
        self.server = server
        self._read_buffer = bytearray(READ_CHUNK_BYTES)
        self._read_view = memoryview(self._read_buffer)  # slicing a view copies once, a bytearray twice
        self.transport: asyncio.Transport | None = None
        self.session: ServerSession | None = None
        self.peer = ""
        self.last_activity_s = time.monotonic()
        self.paused_since_s: float | None = None
        self.partial_since_s: float | None = None
        self.holding = False  # answers wait for a save of retained data (reading paused meanwhile)

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        # uvloop's TCP transport has asyncio.Transport's methods without being its subclass.
        self.transport = cast(asyncio.Transport, transport)
        transport = self.transport
        peername = transport.get_extra_info("peername")
        self.peer = f"{peername[0]}:{peername[1]}" if peername else "?"
        if len(self.server.connections) >= self.server.limits.max_connections:
            log.warning("refusing %s: %d connections open (limit)", self.peer,
                        len(self.server.connections))
            self.server.refused_connections += 1
            transport.abort()
            return
        transport.set_write_buffer_limits(high=self.server.limits.write_buffer_high_bytes)
        self.session = ServerSession(self.server.dispatcher, limits=self.server.session_limits,
                                     peer=self.peer)
        self.server.connections.add(self)
        log.info("connection from %s", self.peer)

    def get_buffer(self, sizehint: int) -> bytearray:
        return self._read_buffer

    def buffer_updated(self, nbytes: int) -> None:
        data = bytes(self._read_view[:nbytes])
        session, transport = self.session, self.transport
        if session is not None and transport is not None and self.server.recorder is None:
            # A polled read job, alone in its segment: answered without the general bookkeeping
            # below (the session answers only with nothing half-received before or after, so there
            # is no partial frame to watch; the connection stays open).
            answer = session.answer_polled_read(data)
            if answer is not None:
                self.last_activity_s = time.monotonic()
                transport.write(answer)
                return
        self.data_received(data)

    def data_received(self, data: bytes) -> None:
        session, transport = self.session, self.transport
        if session is None or transport is None:
            return
        self.last_activity_s = time.monotonic()
        recorder = self.server.recorder
        if recorder is not None:
            recorder.segment(self, True, data, client=self._peer_tuple())
        saves = self.server.saves
        requested = saves.requested if saves is not None else 0
        answers = session.receive(data)
        if session.has_partial_frame:
            if self.partial_since_s is None:
                self.partial_since_s = self.last_activity_s
                self.server.watched.add(self)
        elif self.partial_since_s is not None:
            self.partial_since_s = None
            self.server.watched.discard(self)
        out = (answers[0] if len(answers) == 1 else b"".join(answers)) if answers else b""
        if saves is not None and saves.requested != requested:
            # A write of retained data: its acknowledgement (and what follows it on this connection)
            # leaves once a save holding it has ended; the other connections are served meanwhile.
            self.holding = True
            transport.pause_reading()
            saves.after_requests().add_done_callback(lambda _saved: self._release(out))
            return
        self._send(out)

    def _send(self, out: bytes) -> None:
        session, transport = self.session, self.transport
        assert session is not None and transport is not None
        if out:
            transport.write(out)
            if self.server.recorder is not None:
                self.server.recorder.segment(self, False, out, client=self._peer_tuple())
        if session.closed:
            transport.close()

    def _release(self, out: bytes) -> None:
        self.holding = False
        transport = self.transport
        if transport is None or transport.is_closing():
            return
        self._send(out)
        if not transport.is_closing() and self.paused_since_s is None:
            transport.resume_reading()

    def _peer_tuple(self) -> tuple[str, int] | None:
        assert self.transport is not None
        peername = self.transport.get_extra_info("peername")
        return (peername[0], peername[1]) if peername else None

    def pause_writing(self) -> None:
        # The client does not read its answers: stop reading its jobs until it does.
        if self.transport is not None:
            self.transport.pause_reading()
            self.paused_since_s = time.monotonic()
            self.server.watched.add(self)

    def resume_writing(self) -> None:
        if self.transport is not None:
            if not self.holding:
                self.transport.resume_reading()
            self.paused_since_s = None
            if self.partial_since_s is None:
                self.server.watched.discard(self)

    def connection_lost(self, exc: Exception | None) -> None:
        self.server.connections.discard(self)
        self.server.watched.discard(self)
        if self.server.recorder is not None and self.session is not None:
            self.server.recorder.close_connection(self)
        if self.session is not None and not self.session.closed:
            self.session.close("peer closed" if exc is None else f"connection lost: {exc}")

    def check_timeouts(self, now_s: float) -> None:
        if self.transport is None or self.transport.is_closing():
            return
        limits = self.server.limits
        if self.paused_since_s is not None and now_s - self.paused_since_s > limits.write_stall_timeout_s:
            log.warning("closing %s: it has not read its answers for %.0f s", self.peer,
                        limits.write_stall_timeout_s)
            self.transport.abort()
        elif self.partial_since_s is not None and now_s - self.partial_since_s > limits.partial_frame_timeout_s:
            log.warning("closing %s: a frame begun %.0f s ago is still incomplete", self.peer,
                        limits.partial_frame_timeout_s)
            if self.session is not None:
                self.session.close("partial frame timeout")
            self.transport.abort()
        elif now_s - self.last_activity_s > limits.idle_timeout_s:
            log.info("closing %s: idle for %.0f s", self.peer, limits.idle_timeout_s)
            if self.session is not None:
                self.session.close("idle timeout")
            self.transport.close()


class EmulatorServer:
    """An emulator listening on ISO-on-TCP. Use ``await start()`` / ``await stop()``."""

    def __init__(self, emulator: Emulator, *, host: str = "127.0.0.1", port: int = 102,
                 limits: ServerLimits | None = None, session_limits: SessionLimits | None = None,
                 record_path: str | Path | None = None, record_port: int = 102) -> None:
        self.emulator = emulator
        self.dispatcher = Dispatcher.for_machine(emulator)
        self.host = host
        self.requested_port = port
        self.limits = limits or ServerLimits()
        machine = emulator.machine
        self.session_limits = session_limits or SessionLimits(
            pdu_size_max=int(getattr(machine, "pdu_size_max", 960)),
            max_amq=int(getattr(machine, "max_amq", 8)),
        )
        self.record_path = Path(record_path) if record_path is not None else None
        self.record_port = record_port
        self.recorder: CaptureWriter | None = None
        self.connections: set[_Connection] = set()
        # Connections with a frame begun or answers unread: the only ones the watchdog looks at on
        # every turn. Idle ones are looked at once per idle scan: the watchdog's cost per second does
        # not grow with connections that do nothing.
        self.watched: set[_Connection] = set()
        self.refused_connections = 0
        self._server: asyncio.AbstractServer | None = None
        self._watchdog: asyncio.Task[None] | None = None
        # With retained state on disk, writes are saved off the event loop (machine/saves.py).
        self.saves: GroupSaves | None = None

    @property
    def port(self) -> int:
        if self._server is None or not self._server.sockets:
            return self.requested_port
        return int(self._server.sockets[0].getsockname()[1])

    def clients(self) -> list[dict[str, object]]:
        """The connected S7 clients with the jobs each has sent (``machine.status.ClientList``)."""
        return [{"peer": connection.peer, "jobs": connection.session.info.jobs}
                for connection in self.connections if connection.session is not None]

    async def start(self) -> EmulatorServer:
        loop = asyncio.get_running_loop()
        if self.record_path is not None:
            self.recorder = CaptureWriter.open(self.record_path, server_port=self.record_port)
        self._server = await loop.create_server(lambda: _Connection(self), self.host,
                                                self.requested_port, reuse_address=True)
        self._watchdog = asyncio.create_task(self._watch_timeouts())
        if self.emulator.saves.enabled:
            self.saves = self.emulator.saves
            self.dispatcher.persist_later = self.saves.request
        if not self.emulator.cycle_deferred:  # the channels run programs on every served machine
            await self.emulator.start_cycle()
        log.info("nckemu listening on %s:%d", self.host, self.port)
        return self

    async def _watch_timeouts(self) -> None:
        period_s = max(0.05, min(1.0, self.limits.write_stall_timeout_s / 4, self.limits.partial_frame_timeout_s / 4))
        # Idle connections are closed within an eighth of the idle timeout after it (at most 10 s).
        idle_period_s = max(0.05, min(10.0, self.limits.idle_timeout_s / 8))
        period_s = min(period_s, idle_period_s)
        next_idle_scan_s = time.monotonic() + idle_period_s
        while True:
            await asyncio.sleep(period_s)
            now_s = time.monotonic()
            if now_s >= next_idle_scan_s:
                next_idle_scan_s = now_s + idle_period_s
                watched: Iterable[_Connection] = list(self.connections)
            else:
                watched = list(self.watched)
            for connection in watched:
                connection.check_timeouts(now_s)

    async def stop(self) -> None:
        await self.emulator.stop_cycle()
        if self._watchdog is not None:
            self._watchdog.cancel()
            self._watchdog = None
        if self._server is not None:
            self._server.close()
            for connection in list(self.connections):
                if connection.transport is not None:
                    connection.transport.abort()
            await self._server.wait_closed()
            self._server = None
        if self.saves is not None and self.dispatcher.persist_later == self.saves.request:
            self.dispatcher.persist_later = None
        self.saves = None
        self.emulator.persist()
        if self.recorder is not None:
            self.recorder.close()
            self.recorder = None

    async def __aenter__(self) -> EmulatorServer:
        return await self.start()

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    async def serve_forever(self) -> None:
        assert self._server is not None
        await self._server.serve_forever()
