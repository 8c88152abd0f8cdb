"""Reading S7 traffic out of pcap / pcapng captures (dpkt), with TCP reassembly per direction.

Out-of-order and duplicate segments are put right by sequence number; a capture that starts in
the middle of a connection is taken from its first segment. What cannot be parsed is reported with
its frame number and skipped; only a file from which nothing can be read is an error.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import dpkt

from nckemu.protocol import cotp, tpkt
from nckemu.protocol.errors import NckConfigError, NckProtocolError

S7_PORT = 102
_MAX_PENDING_BYTES = 4 * 1024 * 1024


@dataclass(slots=True)
class TracePdu:
    """One S7 PDU (or COTP connect) as it crossed the wire. (Not frozen: a frozen dataclass takes four
    times as long to build, and a capture has millions.)"""

    frame: int                 # capture frame number (1-based) of the packet that completed it
    time_s: float
    connection: int            # 1, 2, ... in order of appearance
    from_client: bool
    kind: str                  # "s7", "cr", "cc", "dr"
    data: bytes                # the S7 PDU, or the whole TPKT frame for COTP connects


@dataclass
class Capture:
    source: str
    pdus: list[TracePdu] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    frames: int = 0
    connections: dict[int, str] = field(default_factory=dict)


@dataclass
class _Direction:
    isn: int | None = None
    next_seq: int | None = None
    pending: dict[int, bytes] = field(default_factory=dict)
    buffer: bytes = b""
    fragments: list[bytes] = field(default_factory=list)
    broken: bool = False


@dataclass
class _Connection:
    number: int
    label: str
    directions: dict[bool, _Direction] = field(default_factory=lambda: {True: _Direction(), False: _Direction()})


def _packets(handle: BinaryIO, source: str, capture: Capture) -> Iterator[tuple[int, float, bytes, int]]:
    head = handle.read(4)
    handle.seek(0)
    if len(head) < 4:
        raise NckConfigError("empty or too short to be a capture file", path=source)
    try:
        reader = dpkt.pcapng.Reader(handle) if head == b"\x0a\x0d\x0d\x0a" else dpkt.pcap.Reader(handle)
    except (ValueError, dpkt.dpkt.Error, EOFError) as exc:
        raise NckConfigError(f"not a pcap or pcapng file ({exc})", path=source) from None
    link = reader.datalink()
    number = 0
    iterator = iter(reader)
    while True:
        try:
            ts, frame = next(iterator)
        except StopIteration:
            return
        except (ValueError, dpkt.dpkt.Error, EOFError, struct.error) as exc:
            capture.problems.append(f"frame {number + 1}: capture ends in a damaged record ({exc}); "
                                    "the frames before it were read")
            return
        number += 1
        yield number, float(ts), bytes(frame), link


@dataclass(frozen=True, slots=True)
class _Segment:
    sport: int
    dport: int
    seq: int
    flags: int
    data: bytes


_ETH_IPV4_TCP = struct.Struct(">12xH")
# IPv4 total length and flags/fragment offset; TCP ports, sequence number, data offset and flags.
_FAST_HEADERS = struct.Struct(">16xH2xH12xHHI4xBB")
_FAST_EXCLUDED_FLAGS = dpkt.tcp.TH_SYN | dpkt.tcp.TH_FIN | dpkt.tcp.TH_RST
_TCP_HEADER = struct.Struct(">HHIIBB")


def _fast_ipv4_tcp(frame: bytes) -> tuple[str, str, _Segment] | None:
    """Ethernet + IPv4 + TCP, the usual layout, without building dpkt objects (the hot path)."""
    if len(frame) < 54 or _ETH_IPV4_TCP.unpack_from(frame)[0] != 0x0800 or frame[14] >> 4 != 4:
        return None
    ip_header = (frame[14] & 0x0F) * 4
    total = int.from_bytes(frame[16:18], "big")
    if frame[23] != 6 or (int.from_bytes(frame[20:22], "big") & 0x3FFF):  # not TCP, or a fragment
        return None
    tcp_start = 14 + ip_header
    if len(frame) < tcp_start + 20:
        return None
    sport, dport, seq, _ack, offset, flags = _TCP_HEADER.unpack_from(frame, tcp_start)
    data_start = tcp_start + (offset >> 4) * 4
    end = min(len(frame), 14 + total) if total else len(frame)
    src = socket.inet_ntop(socket.AF_INET, frame[26:30])
    dst = socket.inet_ntop(socket.AF_INET, frame[30:34])
    return src, dst, _Segment(sport, dport, seq, flags, frame[data_start:end])


def _tcp(frame: bytes, link: int) -> tuple[str, str, dpkt.tcp.TCP | _Segment] | None:
    if link == dpkt.pcap.DLT_EN10MB:
        fast = _fast_ipv4_tcp(frame)
        if fast is not None:
            return fast
    try:
        if link == dpkt.pcap.DLT_EN10MB:
            ip = dpkt.ethernet.Ethernet(frame).data
        elif link == dpkt.pcap.DLT_LINUX_SLL:
            ip = dpkt.sll.SLL(frame).data
        elif link in (dpkt.pcap.DLT_NULL, dpkt.pcap.DLT_LOOP):
            ip = dpkt.loopback.Loopback(frame).data
        elif link == dpkt.pcap.DLT_RAW or link == 101:
            ip = dpkt.ip.IP(frame) if frame[:1] and frame[0] >> 4 == 4 else dpkt.ip6.IP6(frame)
        else:
            return None
    except (dpkt.dpkt.Error, ValueError, IndexError):
        return None
    if isinstance(ip, dpkt.ip.IP):
        family = socket.AF_INET
    elif isinstance(ip, dpkt.ip6.IP6):
        family = socket.AF_INET6
    else:
        return None
    segment = ip.data
    if not isinstance(segment, dpkt.tcp.TCP):
        return None
    return socket.inet_ntop(family, ip.src), socket.inet_ntop(family, ip.dst), segment


def read_capture(path: str | Path, *, port: int = S7_PORT) -> Capture:
    """All S7 PDUs of all connections on ``port`` (the server side), in capture order."""
    path = Path(path)
    source = str(path)
    try:
        handle = path.open("rb")
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=source) from None
    capture = Capture(source)
    connections: dict[tuple[str, int, str], _Connection] = {}
    # The hot path: Ethernet + IPv4 without options + TCP, one whole TPKT/COTP DT frame per segment,
    # in order. Anything else takes the general path below.
    fast_connections: dict[bytes, tuple[_Connection, bool]] = {}
    pdus = capture.pdus
    unpack_headers = _FAST_HEADERS.unpack_from
    with handle:
        for number, ts, frame, link in _packets(handle, source, capture):
            capture.frames = number
            if link == dpkt.pcap.DLT_EN10MB and len(frame) >= 61 and frame[12:15] == b"\x08\x00\x45" \
                    and frame[23] == 6:
                total, fragment, sport, dport, seq, offset, flags = unpack_headers(frame)
                if not fragment & 0x3FFF and not flags & _FAST_EXCLUDED_FLAGS and offset >> 4 == 5:
                    key = frame[26:38]  # addresses and ports: one connection direction
                    known = fast_connections.get(key)
                    if known is not None:
                        connection, from_client = known
                        direction = connection.directions[from_client]
                        end = 14 + total if total else len(frame)
                        if seq == direction.next_seq and not direction.pending and not direction.buffer \
                                and not direction.fragments and not direction.broken and end <= len(frame) \
                                and frame[54:56] == b"\x03\x00" and frame[58:61] == b"\x02\xf0\x80" \
                                and (frame[56] << 8 | frame[57]) == end - 54 and end > 61:
                            direction.next_seq = (seq + end - 54) & 0xFFFFFFFF
                            pdus.append(TracePdu(number, float(ts), connection.number, from_client, "s7",
                                                 frame[61:end]))
                            continue
            parsed = _tcp(frame, link)
            if parsed is None:
                continue
            src, dst, segment = parsed
            if segment.dport == port:
                key, from_client = (src, segment.sport, dst), True
            elif segment.sport == port:
                key, from_client = (dst, segment.dport, src), False
            else:
                continue
            connection = connections.get(key)
            if connection is None:
                connection = _Connection(len(connections) + 1, f"{key[0]}:{key[1]} -> {key[2]}:{port}")
                connections[key] = connection
                capture.connections[connection.number] = connection.label
            if isinstance(segment, _Segment):
                fast_connections.setdefault(frame[26:38], (connection, from_client))
            _feed(capture, connection, from_client, segment, number, ts)
    if capture.frames == 0:
        raise NckConfigError("no frames could be read", path=source)
    return capture


def _feed(capture: Capture, connection: _Connection, from_client: bool, segment: dpkt.tcp.TCP | _Segment,
          number: int, ts: float) -> None:
    direction = connection.directions[from_client]
    seq = segment.seq
    payload = bytes(segment.data)
    if segment.flags & dpkt.tcp.TH_SYN:
        if direction.isn is None and direction.next_seq is not None \
                and ((direction.next_seq - (seq + 1)) & 0xFFFFFFFF) < 0x80000000:
            direction.isn = seq  # captured after data it precedes: the stream so far stands
            return
        if direction.isn != seq:  # a retransmitted SYN changes nothing; a new one starts afresh
            direction.isn = seq
            direction.next_seq = (seq + 1) & 0xFFFFFFFF
            direction.pending.clear()
            direction.buffer = b""
            direction.fragments.clear()
        return
    if not payload:
        return
    if direction.next_seq is None:
        direction.next_seq = seq
    offset = (seq - direction.next_seq) & 0xFFFFFFFF
    if offset >= 0x80000000:  # before what we have: a retransmission, maybe overlapping
        overlap = (direction.next_seq - seq) & 0xFFFFFFFF
        if overlap >= len(payload):
            return
        payload = payload[overlap:]
        seq = direction.next_seq
        offset = 0
    if offset > 0:
        if sum(len(p) for p in direction.pending.values()) < _MAX_PENDING_BYTES:
            direction.pending.setdefault(seq, payload)
        return
    stream = payload
    direction.next_seq = (seq + len(payload)) & 0xFFFFFFFF
    while direction.next_seq in direction.pending:
        more = direction.pending.pop(direction.next_seq)
        stream += more
        direction.next_seq = (direction.next_seq + len(more)) & 0xFFFFFFFF
    # Segments that the stream has overtaken are duplicates.
    for stale in [s for s in direction.pending if ((s - direction.next_seq) & 0xFFFFFFFF) >= 0x80000000]:
        direction.pending.pop(stale)
    _frames(capture, connection, from_client, direction, stream, number, ts)


def _frames(capture: Capture, connection: _Connection, from_client: bool, direction: _Direction, data: bytes,
            number: int, ts: float) -> None:
    if direction.broken:
        if data[:2] != b"\x03\x00":
            return
        direction.broken = False
    buffer = direction.buffer + data
    try:
        frames, direction.buffer = tpkt.split_frames(buffer)
    except NckProtocolError as exc:
        capture.problems.append(f"frame {number}: connection {connection.number}: not TPKT ({exc}); "
                                "skipped until a frame starts again")
        direction.buffer = b""
        direction.fragments.clear()
        direction.broken = True
        return
    for frame in frames:
        try:
            tpdu = cotp.parse_cotp(tpkt.parse_tpkt(frame))
        except NckProtocolError as exc:
            capture.problems.append(f"frame {number}: connection {connection.number}: not COTP ({exc})")
            continue
        if isinstance(tpdu, cotp.DataTpdu):
            direction.fragments.append(tpdu.payload)
            if not tpdu.eot:
                continue
            pdu = b"".join(direction.fragments)
            direction.fragments.clear()
            if pdu:
                capture.pdus.append(TracePdu(number, ts, connection.number, from_client, "s7", pdu))
        else:
            kind = {cotp.ConnectRequest: "cr", cotp.ConnectConfirm: "cc"}.get(type(tpdu), "dr")
            capture.pdus.append(TracePdu(number, ts, connection.number, from_client, kind, frame))
