"""The OPC UA face's connections: asyncua's own protocol and processor, with the faults that hostile
input found in them answered the way OPC UA says (docs/asyncua-hostile-input.md has each with its
steps):

- a message that cannot be decoded, a wrong sequence number, channel or token id, a bad certificate:
  asyncua logs a traceback and leaves the connection open and silent; here the client gets an
  OPC UA ``ERR`` message with the status (BadDecodingError, BadSequenceNumberInvalid, ...) and the
  connection is closed (Part 6, 7.1.5: the server closes after an Error message);
- a size field that promises more than the receive buffer: asyncua buffers until it has it all (a
  header of 4 GiB and a stream of zeros grow the server without bound); here ``BadTcpMessageTooLarge``
  as soon as the header is read, and close;
- a chunk type other than final on Hello, OpenSecureChannel or CloseSecureChannel (or anything but
  F, C, A on a message): asyncua waits in silence; here ``BadTcpMessageTypeInvalid`` and close;
- a message begun and never finished, a connection that never says Hello: asyncua waits forever
  (each holds a descriptor and, after CreateSession, one of the ten sessions); here closed after
  ``partial_timeout_s``, and a connection whose first message is no Hello is closed at once;
- a second CreateSession on one channel: asyncua forgets the first session, which then lives on
  (a flood grows the server); here the first one is closed. A connection lost closes every session
  it created;
- more whole messages on one connection than asyncua 2.x queues (its
  ``max_pending_messages_per_connection``, 500: a client sending requests faster than they are served):
  asyncua 2.x closes the connection in silence; here the rest waits with reading paused and is served
  in turn (the S7 face pauses its reading the same way).
- a request body that cannot be decoded: asyncua answers BadInternalError with a traceback in the
  log; here BadDecodingError and one line at debug level (a client cannot fill the disk with logs).

Two faults of asyncua 1.1 that the face worked around are mended in asyncua 2.x, which the face now
needs: Publish requests queued without a bound (2.x keeps the channel's subscriptions + 10 and answers
the oldest past that ``BadTooManyPublishRequests``, Part 4, 5.13.5), and a session that timed out
closed by a watchdog awaiting itself (a traceback, then a second one when the connection closed).

Installed by ``install(server, limits)`` before ``server.start()``: a face's server makes these
connections; any other asyncua server in the process keeps asyncua's own.
"""

from __future__ import annotations

import asyncio
import logging
import struct
from dataclasses import dataclass
from typing import Any

from asyncua import ua
from asyncua.common.utils import NotEnoughData, ServiceError
from asyncua.server.binary_server_asyncio import OPCUAProtocol
from asyncua.ua.ua_binary import nodeid_from_binary, struct_from_binary, uatcp_to_binary
from asyncua.ua.uaerrors import UaError, UaStatusCodeError

from nckemu.emulator.faces.opcua.asyncua_internals import (
    Processor,
    Protocol,
    SocketServer,
    serve_connections_with,
)

log = logging.getLogger("nckemu.emulator.opcua.transport")

_KNOWN_TYPES = (b"HEL", b"OPN", b"MSG", b"CLO")
# Only a secure message may come in chunks or be aborted (Part 6, 6.7.2 and 7.1.2); asyncua waited in
# silence on an OpenSecureChannel marked as an abort chunk.
_CHUNK_TYPES = {b"HEL": (b"F",), b"OPN": (b"F",), b"CLO": (b"F",), b"MSG": (b"F", b"C", b"A")}
_CREATE_SESSION = ua.NodeId(ua.ObjectIds.CreateSessionRequest_Encoding_DefaultBinary)
# What asyncua's decoders raise on bytes that are no valid encoding (a truncated field, an unknown
# encoding byte or enum value, a string that is not UTF-8, an array length past the data).
_DECODING = (NotEnoughData, struct.error, UnicodeDecodeError, ValueError, IndexError, KeyError, TypeError,
             OverflowError, MemoryError, AttributeError)


@dataclass(frozen=True)
class Limits:
    """What one OPC UA connection may do before it is answered with an error and closed."""

    partial_timeout_s: float = 10.0  # a begun message, or the Hello after connecting, must come by then
    max_message_bytes: int = 20 * 1024 * 1024  # a whole request, all chunks (CopyFileToServer: 16 MiB)
    # Operations in one request (Part 4's operation limits): asyncua decodes a request whole before it
    # answers, about 0.3 ms an item here, so 5000 monitored items in one call held every client of
    # both faces for 2 s; more than this many get BadTooManyOperations before they are decoded.
    max_operations: int = 1000


# Where the top-level array of each request starts after its RequestHeader (bytes of fixed fields
# before it): Read (MaxAge, TimestampsToReturn), Write, Call, CreateMonitoredItems (SubscriptionId,
# TimestampsToReturn), ModifyMonitoredItems (the same), DeleteMonitoredItems (SubscriptionId),
# TranslateBrowsePathsToNodeIds, RegisterNodes, UnregisterNodes, Publish (acknowledgements),
# DeleteSubscriptions, BrowseNext (ReleaseContinuationPoints).
_ARRAY_AFTER = {ua.NodeId(getattr(ua.ObjectIds, f"{name}Request_Encoding_DefaultBinary")): skip for name, skip in (
    ("Read", 12), ("Write", 0), ("Call", 0), ("CreateMonitoredItems", 8), ("ModifyMonitoredItems", 8),
    ("DeleteMonitoredItems", 4), ("TranslateBrowsePathsToNodeIds", 0), ("RegisterNodes", 0),
    ("UnregisterNodes", 0), ("Publish", 0), ("DeleteSubscriptions", 0), ("BrowseNext", 1))}


def install(server: Any, limits: Limits | None = None) -> None:
    """Make ``server`` (an asyncua Server not yet started) serve its connections as this module says."""
    limits = limits or Limits()
    server.iserver.nckemu_transport_limits = limits
    processor_log = logging.getLogger("asyncua.server.uaprocessor")
    if _FAULTS not in processor_log.filters:
        processor_log.addFilter(_FAULTS)
    transport_limits = server.limits
    transport_limits.max_message_size = limits.max_message_bytes
    transport_limits.max_chunk_count = -(-limits.max_message_bytes // transport_limits.max_recv_buffer)


class _FaultLines(logging.Filter):
    """asyncua logs every refused request at ERROR ("sending service fault response: ..."); the client
    has the status, so the line is debug: a hostile client cannot fill the log with them."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno >= logging.ERROR and str(record.msg).startswith("sending service fault response"):
            record.levelno, record.levelname = logging.DEBUG, "DEBUG"
            return logging.getLogger(record.name).isEnabledFor(logging.DEBUG)
        return True


_FAULTS = _FaultLines()


def _status_of(exc: BaseException) -> int:
    if isinstance(exc, UaStatusCodeError | ServiceError):
        return int(exc.code)
    if isinstance(exc, _DECODING):
        return ua.StatusCodes.BadDecodingError
    text = str(exc).lower()
    if "sequence" in text:
        return ua.StatusCodes.BadSequenceNumberInvalid
    if "channel id" in text:
        return ua.StatusCodes.BadSecureChannelIdInvalid
    if "token id" in text:
        return ua.StatusCodes.BadSecureChannelTokenUnknown
    if "unsupported message type" in text:
        return ua.StatusCodes.BadTcpMessageTypeInvalid
    if isinstance(exc, UaError):
        return ua.StatusCodes.BadSecurityChecksFailed  # a policy or certificate asyncua refused
    return ua.StatusCodes.BadInternalError


class _Processor(Processor):
    """asyncua's processor; a second CreateSession closes the first, a request with too many operations
    gets BadTooManyOperations before it is decoded, one that does not decode BadDecodingError."""

    def __init__(self, *args: Any, limits: Limits, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.guard = limits
        self.created: list[Any] = []

    async def process_message(self, seqhdr: Any, body: Any) -> Any:
        operations = _operations(body)
        if operations is not None and operations[1] > self.guard.max_operations:
            response = ua.ServiceFault()
            response.ResponseHeader.ServiceResult = ua.StatusCode(ua.StatusCodes.BadTooManyOperations)
            self.send_response(operations[0], seqhdr, response)
            return True
        return await super().process_message(seqhdr, body)

    async def serve(self, typeid: Any, requesthdr: Any, seqhdr: Any, body: Any) -> Any:
        if typeid == _CREATE_SESSION and self.session is not None:
            await self._end_session()
        try:
            result = await super().serve(typeid, requesthdr, seqhdr, body)
        except (ServiceError, UaStatusCodeError):
            raise
        except (*_DECODING, UaError) as exc:
            log.debug("OPC UA %s: a request that does not decode (%s: %s)", self.name, type(exc).__name__, exc)
            raise ServiceError(ua.StatusCodes.BadDecodingError) from exc
        except Exception as exc:  # one line, not asyncua's traceback per request; the client gets the status
            log.warning("OPC UA %s: internal error serving a request (%s: %s)", self.name, type(exc).__name__, exc)
            raise ServiceError(ua.StatusCodes.BadInternalError) from exc
        if typeid == _CREATE_SESSION and self.session is not None:
            self.created.append(self.session)
        return result

    async def _end_session(self) -> None:
        """Close this channel's session and stop its watchdog (asyncua would leave both running)."""
        watchdog = self.take_session_watchdog()
        if watchdog is not None:
            watchdog.cancel()
        session, self.session = self.session, None
        if session is not None and session.state.name != "Closed":
            await session.close_session(True)

    async def close(self) -> None:
        # asyncua 2.x keeps an activated session with subscriptions when its connection goes (for a
        # client to take it up on a new channel, Part 4, 6.7); the controller's sessions end with their
        # connection, so that a client that drops its connections cannot hold the ten sessions.
        try:
            await super().close()
        finally:
            for session in self.created:
                if session.state.name != "Closed":
                    await session.close_session(True)
            self.created.clear()


def _operations(body: Any) -> tuple[int, int] | None:
    """The request handle and the length of a request's top-level array, read without decoding the
    rest; None for other requests or bytes that do not decode (asyncua answers those)."""
    try:
        peek = body.copy()
        skip = _ARRAY_AFTER.get(nodeid_from_binary(peek))
        if skip is None:
            return None
        header = struct_from_binary(ua.RequestHeader, peek)
        peek.skip(skip)
        return header.RequestHandle, struct.unpack("<i", peek.read(4))[0]
    except Exception:
        return None


class _Protocol(Protocol):
    """asyncua's protocol with the checks on framing it lacks (see the module's docstring)."""

    def __init__(self, *args: Any, guard: Limits, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.guard = guard
        self._hello_seen = False
        self._timer: asyncio.TimerHandle | None = None
        self._failed = False
        self._held = b""  # whole messages past asyncua's queue (and what follows them), reading paused

    def connection_made(self, transport: Any) -> None:
        super().connection_made(transport)
        if self.transport is None:  # asyncua 2.x refused it (its max_connections) and closed it
            return
        processor = _Processor(self.iserver, self.transport, self.limits, limits=self.guard)
        processor.set_policies(self.policies)
        self.processor = processor
        self._arm()  # the Hello must come within the partial timeout

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def _arm(self) -> None:
        if self._timer is None:
            self._timer = asyncio.get_running_loop().call_later(self.guard.partial_timeout_s, self._timed_out)

    def _disarm(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _timed_out(self) -> None:
        self._timer = None
        log.debug("OPC UA %s: %s", self.peer_name,
                  "a message begun and not finished" if self._hello_seen else "no Hello")
        self.fail(ua.StatusCodes.BadTimeout)

    def fail(self, status: int, reason: str = "") -> None:
        """An OPC UA Error message with ``status``, then close (Part 6, 7.1.5)."""
        if self._failed:
            return
        self._failed = True
        self._disarm()
        self.buffered = b""
        try:
            self.transport.write(uatcp_to_binary(ua.MessageType.Error, ua.ErrorMessage(ua.StatusCode(status), reason)))
        except Exception:  # the transport is gone already
            pass
        self.transport.close()

    def data_received(self, data: bytes) -> None:
        if self._failed:
            return
        buffered, self._held = self.buffered + self._held + data, b""
        offset = 0
        ends: list[int] = []
        # Check every complete header in what has arrived before asyncua parses it.
        while len(buffered) - offset >= 8:
            kind, chunk = buffered[offset:offset + 3], buffered[offset + 3:offset + 4]
            size = struct.unpack_from("<I", buffered, offset + 4)[0]
            if kind not in _KNOWN_TYPES or (kind == b"HEL") == self._hello_seen or chunk not in _CHUNK_TYPES[kind]:
                return self.fail(ua.StatusCodes.BadTcpMessageTypeInvalid)
            if size < (12 if kind != b"HEL" else 8) + 8 or size > self.limits.max_recv_buffer:
                return self.fail(ua.StatusCodes.BadTcpMessageTooLarge if size > 8 else
                                 ua.StatusCodes.BadDecodingError)
            if len(buffered) - offset < size:
                break
            self._hello_seen = True
            offset += size
            ends.append(offset)
        # asyncua 2.x queues at most max_pending_messages_per_connection whole messages a connection and
        # closes it in silence past that (1.1 queued without a bound): the rest waits here with reading
        # paused (the client's sending waits on TCP) until asyncua has served half its queue.
        room = self.messages.maxsize - self.messages.qsize() if self.messages.maxsize else len(ends)
        if len(ends) > room:
            cut = ends[room - 1] if room > 0 else 0
            buffered, self._held = buffered[:cut], buffered[cut:]
            self.transport.pause_reading()
        self.buffered = b""
        super().data_received(buffered)
        self._rearm()

    def _rearm(self) -> None:
        """The timer runs while part of a message is here: bytes of a chunk, or chunks of a message (not
        while the face holds messages back: then the client waits for the face)."""
        if self._held:
            self._disarm()
        elif self.buffered or not self._hello_seen or self.processor.chunks_waiting:
            self._arm()  # the rest must come within the partial timeout
        else:
            self._disarm()

    async def process_one_message(self, header: Any, buf: Any) -> bool:
        if self._failed:
            return False
        try:
            going_on = await super().process_one_message(header, buf)
        except Exception as exc:  # asyncua would log a traceback and leave the connection open
            status = _status_of(exc)
            log.debug("OPC UA %s: %s (%s: %s)", self.peer_name, ua.StatusCode(status).name, type(exc).__name__, exc)
            self.fail(status)
            return False
        if not self._failed:
            self._rearm()
            if self._held and self.messages.qsize() <= self.messages.maxsize // 2:
                self.transport.resume_reading()
                self.data_received(b"")
        return going_on and not self._failed


class _BinaryServer(SocketServer):
    """asyncua's socket server; a face's server (``install``) makes guarded connections."""

    def make_protocol(self) -> OPCUAProtocol:
        guard = getattr(self.iserver, "nckemu_transport_limits", None)
        if guard is None:
            return super().make_protocol()
        return _Protocol(iserver=self.iserver, policies=self.security_policies, clients=self.clients,
                         closing_tasks=self.closing_tasks, limits=self.limits, guard=guard)


# asyncua's Server makes its BinaryServer by this module-level name when it starts; servers without
# ``install`` get asyncua's own protocol from it.
serve_connections_with(_BinaryServer)
