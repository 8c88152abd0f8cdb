"""The sans-IO connection state machine of the emulator (no sockets, no clock, no asyncio).

``ServerSession.receive(bytes) -> list[bytes]`` takes whatever arrived on the connection and
returns the frames to send back; ``closed`` tells the transport to drop the connection. The same
session can be driven by the asyncio server, by a test, or by a trace replay.

States: WAIT_CONNECT (expects COTP CR) -> CONNECTED (expects S7 setup communication) -> READY.

Policy for bad input, in order of how much of the frame we could understand:
* not TPKT, a TPKT frame that is not COTP, a COTP TPDU other than CR/DT/DR, or an S7 header that
  does not parse: the connection is closed (the controller cannot even tell whom to answer);
* an S7 job whose header parses but whose parameters do not: ACK_DATA with header error 0x85/0x00
  ("wrong frames"), echoing the PDU reference and function, the connection stays open;
* an S7 function we do not serve: ACK_DATA with 0x81/0x04 (what a real 840D sl answered, GH107);
* a job before setup communication: 0x84/0x01 ("invalid service sequence");
* more jobs outstanding than the granted AMQ: the extras get 0x83/0x02 (no resources).
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Callable
from dataclasses import dataclass, field

from nckemu.emulator.dispatch import Dispatcher
from nckemu.emulator.nck.access import AccessContext
from nckemu.protocol import cotp, s7, tpkt
from nckemu.protocol.errors import NckError, NckProtocolError

log = logging.getLogger(__name__)

# Header errors the session itself answers with (class, code); one place to correct them.
ERROR_WRONG_FRAMES = (0x85, 0x00)
ERROR_NOT_IMPLEMENTED = (0x81, 0x04)
ERROR_INVALID_SEQUENCE = (0x84, 0x01)
ERROR_NO_RESOURCES = (0x83, 0x02)
ERROR_PDU_TOO_LARGE = (0x85, 0x00)

SETUP_PARAMETER_BYTES = 8
_ROSCTR_JOB = int(s7.Rosctr.JOB)
_READ_VAR = int(s7.Function.READ_VAR)


class SessionState(enum.Enum):
    WAIT_CONNECT = "wait_connect"
    CONNECTED = "connected"
    READY = "ready"
    CLOSED = "closed"


@dataclass(frozen=True)
class SessionLimits:
    """What one connection may use; the machine file sets them (see docs/limits.md)."""

    pdu_size_max: int = 960
    max_amq: int = 8
    max_frame_bytes: int = 65535
    # COTP DT fragments of one S7 PDU are reassembled up to this size, then the connection closes.
    max_reassembly_bytes: int = 65535
    # A client's unframed bytes are kept up to this size (a frame's worth), then the connection closes.
    max_buffer_bytes: int = 65535 + 4
    # Jobs beyond the AMQ get the controller's "no resources" answer; a client that sends more than
    # this many times the AMQ at once is flooding and is disconnected.
    flood_factor: int = 4


@dataclass
class SessionInfo:
    """What the session learned about its peer (for logs, recordings and tests)."""

    peer: str = ""
    calling_tsap: bytes | None = None
    called_tsap: bytes | None = None
    tpdu_size: int = 1024
    pdu_size: int = 240
    amq: int = 1
    jobs: int = 0
    errors: int = 0
    close_reason: str = ""
    extra: dict[str, object] = field(default_factory=dict)


def _describe_tsap(tsap: bytes | None) -> str:
    if not tsap or len(tsap) != 2:
        return repr(tsap)
    connection_type, rack_slot = tsap[0], tsap[1]
    return f"{tsap.hex()} (type {connection_type}, rack {rack_slot >> 5}, slot {rack_slot & 0x1F})"


class ServerSession:
    """One client connection, from COTP connect to close."""

    def __init__(self, dispatcher: Dispatcher, *, limits: SessionLimits | None = None,
                 access: AccessContext | None = None, peer: str = "",
                 on_close: Callable[[str], None] | None = None) -> None:
        self.dispatcher = dispatcher
        self.limits = limits or SessionLimits()
        self.access = access if access is not None else dispatcher.new_access_context(peer)
        self.info = SessionInfo(peer=peer)
        self.state = SessionState.WAIT_CONNECT
        self._buffer = b""
        self._fragments: list[bytes] = []
        self._fragment_bytes = 0
        self._src_ref = 0x0001
        self._on_close = on_close

    @property
    def has_partial_frame(self) -> bool:
        """Bytes of an incomplete frame or of an unfinished fragmented PDU are waiting."""
        return bool(self._buffer) or bool(self._fragments)

    @property
    def closed(self) -> bool:
        return self.state is SessionState.CLOSED

    def close(self, reason: str) -> None:
        if self.state is SessionState.CLOSED:
            return
        self.state = SessionState.CLOSED
        self.info.close_reason = reason
        log.info("connection %s closed: %s", self.info.peer, reason)
        if self._on_close is not None:
            self._on_close(reason)

    # ------------------------------------------------------------------ input
    def receive(self, data: bytes) -> list[bytes]:
        """Feed received bytes; return the frames to send, in order."""
        if self.closed:
            return []
        buffer = self._buffer + data if self._buffer else data
        try:
            frames, rest = tpkt.split_frames(buffer, self.limits.max_frame_bytes)
        except NckProtocolError as exc:
            self.close(f"not TPKT: {exc}")
            return []
        if len(rest) > self.limits.max_buffer_bytes:
            self.close("partial frame larger than the buffer limit")
            return []
        self._buffer = rest
        out: list[bytes] = []
        jobs_in_flight = 0
        for frame in frames:
            if self.closed:
                break
            if jobs_in_flight >= self.info.amq * self.limits.flood_factor:
                self.close(f"flooding: more than {jobs_in_flight} jobs at once, AMQ is {self.info.amq}")
                break
            if frame[4:7] == cotp.DT_HEADER_EOT and self.state is SessionState.READY and not self._fragments:
                # The common case, a whole S7 PDU in one DT: skip building a DataTpdu for it.
                jobs_in_flight += 1
                over_amq = jobs_in_flight > self.info.amq
                if not over_amq:
                    read_answer = self._fast_read(frame)
                    if read_answer is not None:
                        out.append(read_answer)
                        continue
                answer = self._handle_pdu(frame[7:], over_amq=over_amq)
                if answer is not None:
                    out.append(cotp.build_data_frame(answer))
                continue
            try:
                payload = tpkt.parse_tpkt(frame)
                tpdu = cotp.parse_cotp(payload)
            except NckProtocolError as exc:
                self.close(f"not COTP: {exc}")
                break
            if isinstance(tpdu, cotp.DataTpdu):
                pdu_bytes = self._reassemble(tpdu)
                if pdu_bytes is None:
                    continue
                jobs_in_flight += 1
                answer = self._handle_pdu(pdu_bytes, over_amq=jobs_in_flight > self.info.amq)
                if answer is not None:
                    out.append(cotp.build_data_frame(answer))
            elif isinstance(tpdu, cotp.ConnectRequest):
                out.extend(self._handle_connect(tpdu))
            elif isinstance(tpdu, cotp.DisconnectRequest):
                out.append(cotp.build_frame(cotp.DisconnectConfirm(tpdu.src_ref, tpdu.dst_ref)))
                self.close("client sent DR")
            else:
                self.close(f"unexpected COTP {type(tpdu).__name__}")
        return out

    def _reassemble(self, tpdu: cotp.DataTpdu) -> bytes | None:
        if self.state is SessionState.WAIT_CONNECT:
            self.close("COTP data before connect")
            return None
        if not tpdu.payload and not tpdu.eot:
            return None  # "fast acknowledge" some peers send; nothing to answer
        self._fragment_bytes += len(tpdu.payload)
        if self._fragment_bytes > self.limits.max_reassembly_bytes:
            self.close("fragmented PDU larger than the reassembly limit")
            return None
        self._fragments.append(tpdu.payload)
        if not tpdu.eot:
            return None
        pdu = self._fragments[0] if len(self._fragments) == 1 else b"".join(self._fragments)
        self._fragments.clear()
        self._fragment_bytes = 0
        return pdu

    def _handle_connect(self, request: cotp.ConnectRequest) -> list[bytes]:
        if self.state is not SessionState.WAIT_CONNECT:
            self.close("second COTP connect request on one connection")
            return []
        self.info.calling_tsap = request.calling_tsap
        self.info.called_tsap = request.called_tsap
        tpdu_size = request.tpdu_size or 1024
        self.info.tpdu_size = min(tpdu_size, 1024) if tpdu_size >= 128 else 128
        log.info("COTP connect from %s: calling TSAP %s, called TSAP %s", self.info.peer,
                 _describe_tsap(request.calling_tsap), _describe_tsap(request.called_tsap))
        confirm = cotp.ConnectConfirm(
            src_ref=self._src_ref, dst_ref=request.src_ref, class_option=0,
            calling_tsap=request.calling_tsap, called_tsap=request.called_tsap,
            tpdu_size=self.info.tpdu_size,
        )
        self.state = SessionState.CONNECTED
        return [cotp.build_frame(confirm)]

    # ------------------------------------------------------------------ S7
    def _fast_read(self, frame: bytes) -> bytes | None:
        """The answer frame to a well-formed read-var job within the limits, straight from the header;
        None leaves the job to ``_handle_pdu``, which also gives every error its answer."""
        if len(frame) < 19 or frame[7] != s7.PROTOCOL_ID or frame[8] != _ROSCTR_JOB or frame[17] != _READ_VAR \
                or frame[15] or frame[16] or (frame[13] << 8 | frame[14]) != len(frame) - 17 \
                or len(frame) - 7 > self.info.pdu_size:
            return None
        try:
            answer = self.dispatcher.read_answer(frame[11] << 8 | frame[12], frame[17:], self.access)
        except Exception:  # noqa: BLE001 - the general path answers (or logs) the same job properly
            return None
        if len(answer) > self.info.pdu_size:
            return None
        self.info.jobs += 1
        return cotp.build_data_frame(answer)

    def _handle_pdu(self, raw: bytes, *, over_amq: bool) -> bytes | None:
        try:
            pdu = s7.parse_pdu(raw)
        except NckProtocolError as exc:
            self.close(f"not an S7 PDU: {exc}")
            return None
        if pdu.rosctr != s7.Rosctr.JOB and pdu.rosctr != s7.Rosctr.USERDATA:
            self.close(f"client sent ROSCTR {pdu.rosctr}")
            return None
        self.info.jobs += 1
        if not pdu.parameter:
            return self._error_answer(pdu, ERROR_WRONG_FRAMES)
        function = pdu.parameter[0]
        if pdu.rosctr == s7.Rosctr.JOB and function == s7.Function.SETUP_COMMUNICATION:
            return self._handle_setup(pdu)
        if self.state is not SessionState.READY:
            return self._error_answer(pdu, ERROR_INVALID_SEQUENCE)
        if over_amq:
            return self._error_answer(pdu, ERROR_NO_RESOURCES)
        if len(raw) > self.info.pdu_size:
            return self._error_answer(pdu, ERROR_PDU_TOO_LARGE)
        try:
            if pdu.rosctr == s7.Rosctr.USERDATA:
                answer = self.dispatcher.userdata(pdu, self.access)
            else:
                answer = self.dispatcher.job(pdu, self.access)
        except NckError as exc:
            self.info.errors += 1
            log.info("job 0x%02X from %s refused: %s", function & 0xFF, self.info.peer, exc)
            return self._error_answer(pdu, (exc.error_class, exc.error_code))
        except Exception:  # a bug in a job must never reach the socket loop
            self.info.errors += 1
            log.exception("job 0x%02X from %s failed inside the emulator", function & 0xFF, self.info.peer)
            return self._error_answer(pdu, ERROR_NOT_IMPLEMENTED)
        if answer is None:
            return self._error_answer(pdu, ERROR_NOT_IMPLEMENTED)
        encoded = s7.build_pdu(answer)
        if len(encoded) > self.info.pdu_size:
            return self._error_answer(pdu, ERROR_PDU_TOO_LARGE)
        return encoded

    def _handle_setup(self, pdu: s7.S7Pdu) -> bytes:
        try:
            request = s7.parse_setup_communication(pdu.parameter)
        except NckProtocolError:
            return self._error_answer(pdu, ERROR_WRONG_FRAMES)
        # The granted AMQ is the server's own (as real CPUs and python-snap7's server answer a
        # fixed value); python-snap7 3.3 asks for 1 and then pipelines up to 8 jobs anyway.
        pdu_size = max(min(request.pdu_length, self.limits.pdu_size_max), 240) \
            if request.pdu_length >= 240 else request.pdu_length
        self.info.pdu_size = pdu_size
        self.info.amq = self.limits.max_amq
        self.state = SessionState.READY
        granted = s7.SetupCommunication(self.limits.max_amq, self.limits.max_amq, pdu_size)
        return s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref,
                                     s7.build_setup_communication(granted)))

    def _error_answer(self, pdu: s7.S7Pdu, error: tuple[int, int]) -> bytes:
        self.info.errors += 1
        function = pdu.parameter[:1]
        if pdu.rosctr == s7.Rosctr.USERDATA:
            return s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref, function,
                                         error_class=error[0], error_code=error[1]))
        parameter = function
        if function and function[0] in (s7.Function.READ_VAR, s7.Function.WRITE_VAR):
            parameter = function + b"\x00"
        return s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref, parameter,
                                     error_class=error[0], error_code=error[1]))
