"""Replay a capture's client side against an emulator and compare every answer with the recorded one."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from nckemu.errors import NckConnectionError, NckError, NckTimeoutError
from nckemu.protocol import cotp, s7, tpkt
from nckemu.protocol.addresses import NckAddress
from nckemu.protocol.codes import RETURN_CODE_TEXTS

from .decode import PUSH, S7COMM_PLUS, Exchange, _value, decode, name_of
from .reader import Capture


@dataclass
class ReplayReport:
    matching_items: int = 0
    differing_values: int = 0
    differing_return_codes: int = 0
    differing_errors: int = 0
    missing_answers: int = 0
    jobs: int = 0
    differences: list[dict[str, Any]] = field(default_factory=list)
    # What a replay cannot send to an emulator, counted: pushes (the CPU sends them on its own), block
    # transfers (downloads and uploads: a programming device's traffic, with jobs from the PLC) and
    # S7comm-plus frames.
    skipped: dict[str, int] = field(default_factory=lambda: {"pushes": 0, "block transfers": 0, "S7comm-plus frames": 0})
    # What the replay did that the capture does not show (a connection set up by the replay itself).
    notes: list[str] = field(default_factory=list)

    @property
    def all_match(self) -> bool:
        return not (self.differing_values or self.differing_return_codes or self.differing_errors
                    or self.missing_answers)

    def to_json(self) -> dict[str, Any]:
        return {"jobs": self.jobs, "matching_items": self.matching_items, "differing_values": self.differing_values,
                "differing_return_codes": self.differing_return_codes, "differing_errors": self.differing_errors,
                "missing_answers": self.missing_answers, "all_match": self.all_match,
                "skipped": self.skipped, "notes": self.notes, "differences": self.differences}


# A capture that begins after a connection was set up (TCP, COTP connect and S7 setup communication
# before the first frame) is replayed on a connection the replay sets up itself: a connection request
# as python-snap7 sends it (rack 0, slot 4: the NCK; any TSAP is accepted) and this setup
# communication (the PDU size the captured jobs' answers may need).
REPLAY_CALLED_TSAP = b"\x01\x04"
REPLAY_SETUP = s7.SetupCommunication(max_amq_calling=1, max_amq_called=1, pdu_length=960)
_SETUP_REF = 0xFFFF  # the PDU reference of the replay's own setup job

# Seconds to wait for the connection confirm: a peer that accepts TCP but does not answer the
# connection request is not an S7 server, and waiting a job timeout for each job would only delay that.
CONNECT_TIMEOUT_S = 2.0


class _Link:
    """One replayed connection: raw frames over a socket."""

    def __init__(self, host: str, port: int, timeout_s: float) -> None:
        self.address = f"{host}:{port}"
        try:
            self.sock = socket.create_connection((host, port), timeout=timeout_s)
        except TimeoutError:
            raise NckTimeoutError(f"no connection to {host}:{port} within {timeout_s} s") from None
        except OSError as exc:
            raise NckConnectionError(f"cannot connect to {host}:{port}: {exc.strerror or exc} "
                                     f"(is an emulator listening there? nckemu serve --port {port})") from None
        self.buffer = b""
        self.timeout_s = timeout_s

    @classmethod
    def connect(cls, host: str, port: int, request: bytes, timeout_s: float, connect_timeout_s: float) -> _Link:
        """A connection whose connection request (``request``, a COTP CR frame) was answered within
        ``connect_timeout_s``; a peer that stays silent is given up (NckTimeoutError naming it)."""
        link = cls(host, port, connect_timeout_s)
        try:
            link.send_frame(request)
            answer = link.receive_frame()
        except OSError:
            answer = None
        if answer is None:
            link.close()
            raise NckTimeoutError(f"{link.address} accepted the TCP connection but did not answer the connection "
                                  f"request within {connect_timeout_s:g} s (not an S7 server? --connect-timeout "
                                  "sets the wait)")
        # Whatever the answer (a confirm, or a refusal the recorded server may have given too), the
        # peer speaks COTP: the jobs that follow are compared as usual.
        link.sock.settimeout(timeout_s)
        return link

    def send_frame(self, frame: bytes) -> None:
        self.sock.sendall(frame)

    def receive_frame(self) -> bytes | None:
        while True:
            try:
                frames, rest = tpkt.split_frames(self.buffer)
            except NckError:
                return None
            if frames:
                first = frames[0]
                self.buffer = self.buffer[len(first):]
                return first
            try:
                chunk = self.sock.recv(65536)
            except (TimeoutError, OSError):
                return None
            if not chunk:
                return None
            self.buffer += chunk

    def receive_pdu(self) -> bytes | None:
        fragments = []
        while True:
            frame = self.receive_frame()
            if frame is None:
                return None
            tpdu = cotp.parse_cotp(tpkt.parse_tpkt(frame))
            if isinstance(tpdu, cotp.DataTpdu):
                fragments.append(tpdu.payload)
                if tpdu.eot and (fragments[-1] or len(fragments) > 1):
                    return b"".join(fragments)

    def close(self) -> None:
        self.sock.close()


def _difference(report: ReplayReport, exchange: Exchange, kind: str, name: str, recorded: Any,
                emulated: Any) -> None:
    report.differences.append({"frame": exchange.job.frame, "connection": exchange.connection,
                               "function": exchange.function, "item": name, "kind": kind,
                               "recorded": recorded, "emulated": emulated})


def _compare(report: ReplayReport, exchange: Exchange, recorded: s7.S7Pdu, emulated: s7.S7Pdu) -> None:
    if (recorded.error_class, recorded.error_code) != (emulated.error_class, emulated.error_code):
        report.differing_errors += 1
        _difference(report, exchange, "header error", exchange.detail or exchange.service_name,
                    f"0x{recorded.error_class:02X}{recorded.error_code:02X}",
                    f"0x{emulated.error_class:02X}{emulated.error_code:02X}")
        return
    if recorded.error_class or recorded.error_code:
        report.matching_items += 1
        return
    if exchange.function == "read":
        got = s7.parse_read_var_response(emulated.parameter, emulated.data).items
        want = s7.parse_read_var_response(recorded.parameter, recorded.data).items
        for item, expected, actual in zip(exchange.items, want, got, strict=False):
            if expected.return_code != actual.return_code:
                report.differing_return_codes += 1
                _difference(report, exchange, "return code", item.name,
                            RETURN_CODE_TEXTS.get(expected.return_code, hex(expected.return_code)),
                            RETURN_CODE_TEXTS.get(actual.return_code, hex(actual.return_code)))
            elif expected.data != actual.data:
                report.differing_values += 1
                address = item.target
                _name, nck_type, length, _unit = name_of(address)
                recorded_value = _value(address, expected.data, nck_type, length)
                emulated_value = _value(address, actual.data, nck_type, length)
                _difference(report, exchange, "value", item.name,
                            expected.data.hex() if recorded_value is None else recorded_value,
                            actual.data.hex() if emulated_value is None else emulated_value)
            else:
                report.matching_items += 1
    elif exchange.function == "write":
        got_codes = s7.parse_write_var_response(emulated.parameter, emulated.data).return_codes
        want_codes = s7.parse_write_var_response(recorded.parameter, recorded.data).return_codes
        for item, expected, actual in zip(exchange.items, want_codes, got_codes, strict=False):
            if expected != actual:
                report.differing_return_codes += 1
                _difference(report, exchange, "return code", item.name, RETURN_CODE_TEXTS.get(expected, hex(expected)),
                            RETURN_CODE_TEXTS.get(actual, hex(actual)))
            else:
                report.matching_items += 1
    else:
        report.matching_items += 1  # setup (negotiated values may differ), PI, userdata: status matched


_BLOCK_TRANSFERS = frozenset({"request download", "download block", "download ended", "start upload", "upload",
                              "end upload"})


def seed_values(exchanges: list[Exchange]) -> dict[NckAddress, bytes]:
    """The state at the start of the trace: the first read answer of each address read before any write."""
    seen: set[NckAddress] = set()
    values: dict[NckAddress, bytes] = {}
    for exchange in exchanges:
        for item in exchange.items:
            address = item.target
            if not isinstance(address, NckAddress) or address in seen:
                continue
            seen.add(address)
            if exchange.function == "read" and item.return_code == 0xFF and item.raw:
                values[address] = bytes.fromhex(item.raw)
    return values


def _is_setup_job(data: bytes) -> bool:
    """An S7 job whose function is setup communication (0xF0)."""
    return len(data) > 10 and data[0] == 0x32 and data[1] == s7.Rosctr.JOB and data[10] == s7.Function.SETUP_COMMUNICATION


def _set_up(link: _Link, report: ReplayReport, pdu: Any, connected_here: bool) -> None:
    """Send the replay's own setup communication on ``link`` before the first recorded job of a
    connection that the capture shows only after its setup, and say so in the report."""
    what = ("TCP, COTP connect (rack 0, slot 4) and setup communication" if connected_here
            else "setup communication")
    link.send_frame(cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(
        s7.Rosctr.JOB, _SETUP_REF, s7.build_setup_communication(REPLAY_SETUP)))))
    answer = link.receive_pdu()
    granted = ""
    if answer is not None:
        try:
            parsed = s7.parse_pdu(answer)
            granted = f", PDU {s7.parse_setup_communication(parsed.parameter).pdu_length} granted"
        except NckError:
            granted = ", its answer not understood"
    else:
        granted = ", no answer"
    report.notes.append(f"connection c{pdu.connection} starts in the capture after its setup (first frame #{pdu.frame} "
                        f"is a job): the replay did the {what} itself (PDU {REPLAY_SETUP.pdu_length} asked{granted})")


def replay(capture: Capture, host: str, port: int, *, realtime: bool = False, timeout_s: float = 5.0,
           progress: Callable[[int, int], None] | None = None,
           connect_timeout_s: float = CONNECT_TIMEOUT_S) -> ReplayReport:
    exchanges = decode(capture)
    report = ReplayReport()
    by_job: dict[int, Exchange] = {}
    not_sent: set[int] = set()  # client PDUs not to send: answers to the PLC's jobs, block transfers
    for exchange in exchanges:
        if exchange.function == PUSH:
            report.skipped["pushes"] += 1
        elif exchange.function in _BLOCK_TRANSFERS:
            report.skipped["block transfers"] += 1
            not_sent.add(id(exchange.job))
        elif exchange.function != S7COMM_PLUS and exchange.job.from_client:
            by_job[id(exchange.job)] = exchange
        if exchange.answer is not None and exchange.answer.from_client:
            not_sent.add(id(exchange.answer))
    links: dict[int, _Link] = {}
    set_up: set[int] = set()  # connections whose setup communication was sent (recorded or the replay's)
    client_pdus = [p for p in capture.pdus if p.from_client]
    started_wall = time.monotonic()
    first_time = client_pdus[0].time_s if client_pdus else 0.0
    try:
        for index, pdu in enumerate(client_pdus):
            if realtime:
                delay = (pdu.time_s - first_time) - (time.monotonic() - started_wall)
                if delay > 0:
                    time.sleep(delay)
            link = links.get(pdu.connection)
            if pdu.kind == "cr":
                if link is not None:
                    link.close()
                link = links[pdu.connection] = _Link.connect(host, port, pdu.data, timeout_s, connect_timeout_s)
                set_up.discard(pdu.connection)
                continue
            if pdu.kind != "s7":
                continue
            if pdu.data[:1] == b"\x72":
                report.skipped["S7comm-plus frames"] += 1
                continue
            if id(pdu) in not_sent:
                continue
            connected_here = link is None
            if link is None:  # the capture began after the connect: make one like python-snap7 does
                link = links[pdu.connection] = _Link.connect(
                    host, port, cotp.build_frame(cotp.ConnectRequest(src_ref=1, calling_tsap=b"\x01\x00",
                                                                     called_tsap=REPLAY_CALLED_TSAP, tpdu_size=1024)),
                    timeout_s, connect_timeout_s)
            if pdu.connection not in set_up:
                if _is_setup_job(pdu.data):
                    set_up.add(pdu.connection)
                else:  # a job before any setup communication: a server refuses it (0x8401), so set it up
                    _set_up(link, report, pdu, connected_here)
                    set_up.add(pdu.connection)
            exchange = by_job.get(id(pdu))
            link.send_frame(cotp.build_data_frame(pdu.data))
            if exchange is None:
                continue
            report.jobs += 1
            answer = link.receive_pdu()
            if answer is None:
                report.missing_answers += 1
                _difference(report, exchange, "missing answer", exchange.detail or exchange.service_name, "answer", None)
                link.close()
                links.pop(pdu.connection)
                set_up.discard(pdu.connection)
            elif exchange.answer is not None:  # a job whose answer was not captured is not compared
                try:
                    _compare(report, exchange, s7.parse_pdu(exchange.answer.data), s7.parse_pdu(answer))
                except NckError as exc:
                    report.differing_errors += 1
                    _difference(report, exchange, "undecodable answer", exchange.function, "", str(exc))
            if progress is not None:
                progress(index + 1, len(client_pdus))
    finally:
        for link in links.values():
            link.close()
    return report
