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
* an S7 function we do not serve (upload, download, ...): ACK (ROSCTR 2) with the header error and
  no parameter, the form C snap7 and python-snap7 answer and tshark decodes for every function
  (ROSCTR 3 with the function byte alone is "malformed" for 0x1D start upload: notes/catalogue.md
  5 (c)); the error is the machine's settings.unsupported_function_error, by default 0x81/0x04, what
  a real 840D sl answered (GH107);
* a userdata group we do not serve: a userdata answer with the error in its parameter (dispatch.py);
* an empty COTP DT (with or without EOT, e.g. the 7-byte DT some collectors send after every job in
  the same TCP write) is ignored, as C snap7 does: no answer, the connection stays open;
* an answer longer than the negotiated TPDU size goes out in several DTs (COTP segmentation);
* a job before setup communication: 0x84/0x01 ("invalid service sequence");
* more jobs outstanding than the granted AMQ: the extras get 0x83/0x02 (no resources);
* NC program transfers (userdata group "NC programming", and 0x1D..0x1F naming an NC file) are the
  connection's ``NcTransfers`` (nc_transfer.py): a download block or continue upload is a telegram,
  not a job (no answer, not counted against the AMQ); an upload's pushes follow its answer.
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Callable
from dataclasses import dataclass, field

from nckemu.emulator.faces.s7.dispatch import FRAME_PDU_REF_END, Dispatcher
from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.errors import HeaderError, NckError
from nckemu.protocol import cotp, ncprog, s7, szl, tpkt, userdata
from nckemu.protocol.errors import NckProtocolError

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.session")

SETUP_PARAMETER_BYTES = 8
MIN_PDU_SIZE = 240
# Job functions answered in ACK_DATA with the function byte in the parameter; any other function is
# answered with an ACK (ROSCTR 2) that carries only the header error.
_ACK_DATA_FUNCTIONS = frozenset({s7.Function.READ_VAR, s7.Function.WRITE_VAR, s7.Function.PI_SERVICE,
                                 s7.Function.PLC_STOP, s7.Function.SETUP_COMMUNICATION})
# The PLC-block upload jobs, which carry an NC file name when a client uploads a program through them.
_BLOCK_UPLOAD_FUNCTIONS = frozenset({s7.Function.START_UPLOAD, s7.Function.UPLOAD, s7.Function.END_UPLOAD})
# Where the S7 PDU starts in a frame with one whole PDU in one DT: TPKT (4) + COTP DT (3).
_PDU_OFFSET = cotp.DATA_FRAME_PDU_OFFSET


def _is_nc_push(frame: bytes, offset: int) -> bool:
    """An NC push (download block, continue upload) at ``offset``: a telegram of a transfer, not a
    job. It waits for no answer, and the window of them the transfer announced is not the AMQ's."""
    return len(frame) >= offset + 18 and frame[offset + 1] == s7.Rosctr.USERDATA \
        and frame[offset + 10:offset + 13] == ncprog.PARAMETER_HEAD and frame[offset + 15] == ncprog.NC_PUSH


class SessionState(enum.Enum):
    WAIT_CONNECT = "wait_connect"
    CONNECTED = "connected"
    READY = "ready"
    CLOSED = "closed"


class Event(enum.Enum):
    """What the peer did, as far as the session's state is concerned."""

    CONNECT_REQUEST = "COTP CR"
    DATA = "COTP DT"
    SETUP = "S7 setup communication"
    JOB = "S7 job or userdata"
    DISCONNECT_REQUEST = "COTP DR"


# Rule 1 (after h11's _state.py): every change of ``ServerSession.state`` is decided by this table,
# through ``_advance``. A pair maps to the next state, or to the header error the job is answered
# with while the state stays; a pair that is absent closes the connection. (CLOSED takes nothing.)
_TRANSITIONS: dict[tuple[SessionState, Event], SessionState | HeaderError] = {
    (SessionState.WAIT_CONNECT, Event.CONNECT_REQUEST): SessionState.CONNECTED,
    (SessionState.CONNECTED, Event.DATA): SessionState.CONNECTED,
    (SessionState.CONNECTED, Event.SETUP): SessionState.READY,
    (SessionState.CONNECTED, Event.JOB): HeaderError.INVALID_SEQUENCE,
    (SessionState.READY, Event.DATA): SessionState.READY,
    # A second setup communication renegotiates the PDU size, as real CPUs and snap7 allow.
    (SessionState.READY, Event.SETUP): SessionState.READY,
    (SessionState.READY, Event.JOB): SessionState.READY,
}

_CLOSE_REASONS: dict[tuple[SessionState, Event], str] = {
    (SessionState.WAIT_CONNECT, Event.DATA): "COTP data before connect",
    (SessionState.CONNECTED, Event.CONNECT_REQUEST): "second COTP connect request on one connection",
    (SessionState.READY, Event.CONNECT_REQUEST): "second COTP connect request on one connection",
}


_READY = SessionState.READY


def next_state(state: SessionState, event: Event) -> SessionState | HeaderError:
    """The table's answer for ``event`` in ``state`` (CLOSED where the table has none)."""
    return _TRANSITIONS.get((state, event), SessionState.CLOSED)


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
        self._framed_reads = dispatcher.framed_reads
        self.limits = limits or SessionLimits()
        self.access = access if access is not None else dispatcher.new_access_context(peer)
        self.info = SessionInfo(peer=peer)
        self.state = SessionState.WAIT_CONNECT
        self._buffer = b""
        self._fragments: list[bytes] = []
        self._fragment_bytes = 0
        self._src_ref = 0x0001
        self._on_close = on_close
        # The parts still to send of one userdata answer longer than the PDU: sequence number and the
        # (parameter, data) pairs; one long answer at a time, as a client reads them one by one.
        self._userdata_parts: tuple[int, list[tuple[bytes, bytes]]] | None = None
        self._userdata_sequence = 0
        # NC program transfers of this connection, and the pushes that follow an answer (upload pieces).
        self._nc = dispatcher.new_nc_transfers(peer)
        self._pushes: list[bytes] = []

    @property
    def has_partial_frame(self) -> bool:
        """Bytes of an incomplete frame or of an unfinished fragmented PDU are waiting."""
        return bool(self._buffer) or bool(self._fragments)

    @property
    def closed(self) -> bool:
        return self.state is SessionState.CLOSED

    def close(self, reason: str) -> None:
        """End the connection from any state: the table's closing pairs, and faults it does not name
        (bytes that are not TPKT/COTP/S7, limits, floods)."""
        if self.state is SessionState.CLOSED:
            return
        self.state = SessionState.CLOSED
        self.info.close_reason = reason
        log.info("connection %s closed: %s", self.info.peer, reason)
        if self._on_close is not None:
            self._on_close(reason)

    def _advance(self, event: Event, reason: str = "") -> HeaderError | None:
        """Move as ``_TRANSITIONS`` says; the header error to answer with where it names one."""
        outcome = next_state(self.state, event)
        if isinstance(outcome, HeaderError):
            return outcome
        if outcome is SessionState.CLOSED:
            self.close(reason or _CLOSE_REASONS.get((self.state, event),
                                                    f"{event.value} in state {self.state.value}"))
        else:
            self.state = outcome
        return None

    # ------------------------------------------------------------------ input
    def receive(self, data: bytes) -> list[bytes]:
        """Feed received bytes; return the frames to send, in order."""
        frame = self.answer_polled_read(data)
        if frame is not None:
            return [frame]
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
            if frame[4:7] == cotp.DT_HEADER_EOT and len(frame) > _PDU_OFFSET and self.state is SessionState.READY \
                    and not self._fragments:
                # The common case, a whole S7 PDU in one DT: skip building a DataTpdu for it.
                if _is_nc_push(frame, _PDU_OFFSET):
                    out.extend(self._answer_frames(self._handle_pdu(frame[_PDU_OFFSET:], over_amq=False)))
                    continue
                jobs_in_flight += 1
                over_amq = jobs_in_flight > self.info.amq
                if not over_amq:
                    answer_frame = self._framed_answer(frame)
                    if answer_frame is not None:
                        out.append(answer_frame)
                        continue
                out.extend(self._answer_frames(self._handle_pdu(frame[_PDU_OFFSET:], over_amq=over_amq)))
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
                push = _is_nc_push(pdu_bytes, 0)  # a telegram of a transfer, not a job (as in one DT above)
                if not push:
                    jobs_in_flight += 1
                out.extend(self._answer_frames(self._handle_pdu(
                    pdu_bytes, over_amq=not push and jobs_in_flight > self.info.amq)))
            elif isinstance(tpdu, cotp.ConnectRequest):
                out.extend(self._handle_connect(tpdu))
            elif isinstance(tpdu, cotp.DisconnectRequest):
                out.append(cotp.build_frame(cotp.DisconnectConfirm(tpdu.src_ref, tpdu.dst_ref)))
                self._advance(Event.DISCONNECT_REQUEST, "client sent DR")
            else:
                self.close(f"unexpected COTP {type(tpdu).__name__}")
        return out

    def answer_polled_read(self, data: bytes) -> bytes | None:
        """The answer frame when ``data`` is exactly one read job in one DT on a ready connection
        with nothing half-received, within the limits; None: ``receive`` it. The common case (clients
        poll), answered from the dispatcher's plan for the frame, without the framing loop and
        without parsing: what ``receive`` would answer, byte for byte (tests/emulator/faces/s7/test_fast_read.py)."""
        if self.state is not _READY or self._buffer or self._fragments:
            return None
        return self._framed_answer(data)

    def _framed_answer(self, data: bytes) -> bytes | None:
        """The answer frame to ``data`` when it is one read job in one DT whose answer fits one DT,
        from the dispatcher's plan for the frame; None leaves it to ``_handle_pdu``, which also gives
        every error its answer."""
        entry = self._framed_reads.get(data[FRAME_PDU_REF_END:])
        if entry is None:
            entry = self.dispatcher.framed_read(data)
            if entry is None:
                return None
        info = self.info
        if not data.startswith(entry[0]) or len(data) - _PDU_OFFSET > info.pdu_size \
                or len(data) > self.limits.max_frame_bytes or info.amq < 1 or self.limits.flood_factor < 1:
            return None
        try:
            frame = entry[1](data[_PDU_OFFSET + 4:FRAME_PDU_REF_END], self.access)
        except Exception:  # noqa: BLE001 - the general path answers (or logs) the same job properly
            return None
        if len(frame) - _PDU_OFFSET > info.pdu_size or len(frame) - 4 > info.tpdu_size:
            return None  # the general path refuses it, or sends it in several DTs
        info.jobs += 1
        return frame

    def _data_frames(self, pdu: bytes) -> list[bytes]:
        """The frames carrying one answer PDU: one DT, or several where it exceeds the TPDU size."""
        if len(pdu) + len(cotp.DT_HEADER_EOT) <= self.info.tpdu_size:
            return [cotp.build_data_frame(pdu)]
        return cotp.build_data_frames(pdu, self.info.tpdu_size)

    def _reassemble(self, tpdu: cotp.DataTpdu) -> bytes | None:
        self._advance(Event.DATA)
        if self.closed:
            return None
        if not tpdu.payload and (not tpdu.eot or not self._fragments):
            # An empty DT: the "fast acknowledge" some peers send, or the 7-byte DT LSC (828D
            # collector) sends after every job (notes/catalogue.md 2.1); with EOT and no PDU begun it
            # ends nothing. C snap7 ignores both; nothing to answer, the connection stays open.
            return None
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
        self._advance(Event.CONNECT_REQUEST)
        if self.closed:
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
        return [cotp.build_frame(confirm)]

    # ------------------------------------------------------------------ S7
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
            return self._error_answer(pdu, HeaderError.WRONG_FRAMES)
        function = pdu.parameter[0]
        if pdu.rosctr == s7.Rosctr.JOB and function == s7.Function.SETUP_COMMUNICATION:
            return self._handle_setup(pdu)
        refused = self._advance(Event.JOB)
        if refused is not None:
            return self._error_answer(pdu, refused)
        nc_userdata = pdu.rosctr == s7.Rosctr.USERDATA and self._nc is not None \
            and ncprog.is_nc_parameter(pdu.parameter)
        if over_amq:
            return self._error_answer(pdu, HeaderError.NO_RESOURCES)
        if len(raw) > self.info.pdu_size:
            return self._error_answer(pdu, HeaderError.WRONG_FRAMES)
        if pdu.rosctr == s7.Rosctr.USERDATA and self._userdata_parts is not None:
            next_part = self._next_userdata_part(pdu)
            if next_part is not None:
                return next_part
        try:
            if nc_userdata or (pdu.rosctr == s7.Rosctr.JOB and function in _BLOCK_UPLOAD_FUNCTIONS
                               and self._nc is not None):
                handled, nc_answer = self._nc_transfer(pdu)
                if handled:
                    return nc_answer
            if pdu.rosctr == s7.Rosctr.USERDATA:
                answer = self.dispatcher.userdata(pdu, self.access)
            else:
                answer = self.dispatcher.job(pdu, self.access)
        except NckError as exc:
            self.info.errors += 1
            log.info("job 0x%02X from %s refused: %s", function & 0xFF, self.info.peer, exc)
            return self._error_answer(pdu, exc.header_error)
        except Exception:  # a bug in a job must never reach the socket loop
            self.info.errors += 1
            log.exception("job 0x%02X from %s failed inside the emulator", function & 0xFF, self.info.peer)
            return self._error_answer(pdu, HeaderError.NOT_IMPLEMENTED)
        if answer is None:
            return self._error_answer(pdu, self.dispatcher.unsupported_function_error)
        encoded = s7.build_pdu(answer)
        if len(encoded) > self.info.pdu_size:
            if answer.rosctr == s7.Rosctr.USERDATA:
                return self._userdata_in_parts(answer)
            return self._error_answer(pdu, HeaderError.WRONG_FRAMES)
        return encoded

    def _nc_transfer(self, pdu: s7.S7Pdu) -> tuple[bool, bytes | None]:
        """Whether ``pdu`` was an NC transfer's, and its answer (None: none, as to a download block;
        the pushes that follow go to ``_pushes``). A block job about a PLC block is not. Raises as a
        job does."""
        assert self._nc is not None
        if pdu.rosctr == s7.Rosctr.JOB:
            block_answer = self._nc.block_job(pdu, self.info.pdu_size)
            return block_answer is not None, None if block_answer is None else s7.build_pdu(block_answer)
        answers = [s7.build_pdu(answer) for answer in self._nc.userdata(pdu, self.info.pdu_size)]
        if not answers:
            return True, None
        self._pushes.extend(answers[1:])
        return True, answers[0]

    def _answer_frames(self, answer: bytes | None) -> list[bytes]:
        """The DT frames of ``answer`` (none for a telegram that gets none), then of the pushes that
        follow it (an upload's pieces)."""
        frames = [] if answer is None else self._data_frames(answer)
        for push in self._pushes:
            frames.extend(self._data_frames(push))
        self._pushes.clear()
        return frames

    def _userdata_in_parts(self, answer: s7.S7Pdu) -> bytes:
        """The first part of a userdata answer longer than the PDU (a long SZL at PDU 240); the client
        asks for the others with next-part requests naming the sequence number."""
        head = userdata.parse_userdata_parameter(answer.parameter)
        self._userdata_sequence = self._userdata_sequence % 255 + 1
        parts = szl.split_userdata_answer(head.group, head.subfunction, answer.data,
                                          self.info.pdu_size - szl.PART_OVERHEAD, self._userdata_sequence)
        self._userdata_parts = (self._userdata_sequence, parts[1:])
        return s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, answer.pdu_ref, *parts[0]))

    def _next_userdata_part(self, pdu: s7.S7Pdu) -> bytes | None:
        """The next part, where ``pdu`` asks for it; None leaves the PDU to the dispatcher."""
        assert self._userdata_parts is not None
        try:
            head = userdata.parse_userdata_parameter(pdu.parameter)
        except NckProtocolError:
            return None
        sequence, parts = self._userdata_parts
        if not szl.is_next_part_request(head) or head.sequence != sequence or not parts:
            return None
        parameter, data = parts.pop(0)
        if not parts:
            self._userdata_parts = None
        return s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, pdu.pdu_ref, parameter, data))

    def _handle_setup(self, pdu: s7.S7Pdu) -> bytes:
        try:
            request = s7.parse_setup_communication(pdu.parameter)
        except NckProtocolError:
            return self._error_answer(pdu, HeaderError.WRONG_FRAMES)
        # The granted AMQ is the server's own (as real CPUs and python-snap7's server answer a
        # fixed value); python-snap7 3.3 asks for 1 and then pipelines up to 8 jobs anyway.
        # A PDU size below 240 (even 0) is raised to 240, as C snap7's PerformFunctionNegotiate does
        # (MinPduSize; notes/catalogue.md 5 (f)): granted verbatim, every job would be refused.
        pdu_size = max(min(request.pdu_length, self.limits.pdu_size_max), MIN_PDU_SIZE)
        self.info.pdu_size = pdu_size
        self.info.amq = self.limits.max_amq
        self._advance(Event.SETUP)
        granted = s7.SetupCommunication(self.limits.max_amq, self.limits.max_amq, pdu_size)
        return s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref,
                                     s7.build_setup_communication(granted)))

    def _error_answer(self, pdu: s7.S7Pdu, error: int) -> bytes:
        """ACK_DATA with header error ``error`` (class << 8 | code), echoing the job's function."""
        self.info.errors += 1
        error_class, error_code = error >> 8, error & 0xFF
        function = pdu.parameter[:1]
        if pdu.rosctr == s7.Rosctr.USERDATA:
            return s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref, function,
                                         error_class=error_class, error_code=error_code))
        if function and function[0] not in _ACK_DATA_FUNCTIONS:
            return s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK, pdu.pdu_ref, error_class=error_class,
                                         error_code=error_code))
        parameter = function
        if function and function[0] in (s7.Function.READ_VAR, s7.Function.WRITE_VAR):
            parameter = function + b"\x00"
        return s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref, parameter,
                                     error_class=error_class, error_code=error_code))
