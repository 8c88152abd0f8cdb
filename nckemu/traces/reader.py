"""Reading S7 traffic out of pcap / pcapng captures (dpkt), with TCP reassembly per direction.

Out-of-order and duplicate segments are put right by sequence number; a capture that starts in
the middle of a connection is taken from its first segment. Segments the capture lost (a port mirror,
a filtered export: tshark's "previous segment not captured") leave a gap: once the peer has acknowledged
bytes the capture never showed, or the stream has waited too long, the gap is recorded (``Gap``) and
the stream resyncs on the next TPKT header, as tshark does. What cannot be parsed is reported with
its frame number and skipped; only a file from which nothing can be read is an error.
"""

from __future__ import annotations

import gc
import io
import mmap
import re
import socket
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import dpkt

from nckemu.errors import NckConfigError
from nckemu.protocol import cotp, tpkt
from nckemu.protocol.errors import NckProtocolError

S7_PORT = 102
_MAX_PENDING_BYTES = 4 * 1024 * 1024
# A hole in a stream is a lost segment, not a late one, once this many of the peer's segments have
# acknowledged bytes past it (one is not enough: a capture can see a segment after the peer's answer
# to it, out of order), or when this many segments or seconds of capture wait behind it (a
# retransmission comes within a few RTOs).
_GAP_ACK_VOTES = 3
_GAP_WAIT_SEGMENTS = 64
_GAP_WAIT_S = 3.0
_SEQ_MASK = 0xFFFFFFFF
_HALF_SEQ = 0x80000000
# Where a frame can start again after a gap: a TPKT header (version 3, reserved 0, a length) followed by
# a COTP data TPDU (length indicator 2, DT, EOT bit) or a connect / disconnect TPDU.
_TPKT_START = re.compile(rb"\x03\x00..(?:\x02\xf0[\x00\x80]|[\x06-\xfe][\xe0\xd0\x80\xc0])", re.DOTALL)


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


@dataclass(slots=True)
class Gap:
    """Bytes of one TCP direction the capture never showed: ``missing_bytes`` before ``frame`` (the
    first segment after the hole), and ``skipped_bytes`` of frames the hole cut (their captured parts,
    before and after it) until a TPKT header started a frame again."""

    frame: int
    time_s: float
    connection: int
    from_client: bool
    missing_bytes: int
    skipped_bytes: int = 0

    def describe(self) -> str:
        side = "client" if self.from_client else "server"
        text = f"{_bytes(self.missing_bytes)} from the {side} not captured before this frame"
        if self.skipped_bytes:
            text += f", {_bytes(self.skipped_bytes)} of cut frames skipped"
        return text + "; resynced on the next TPKT header"

    def to_json(self) -> dict[str, object]:
        return {"frame": self.frame, "time_s": self.time_s, "connection": self.connection,
                "sender": "client" if self.from_client else "server", "missing_bytes": self.missing_bytes,
                "skipped_bytes": self.skipped_bytes}


def _bytes(count: int) -> str:
    return "1 byte" if count == 1 else f"{count} bytes"


@dataclass
class Capture:
    source: str
    pdus: list[TracePdu] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    frames: int = 0
    connections: dict[int, str] = field(default_factory=dict)
    gaps: list[Gap] = field(default_factory=list)


@dataclass
class _Direction:
    isn: int | None = None
    next_seq: int | None = None
    # segments ahead of next_seq: sequence number -> (payload, frame number, time)
    pending: dict[int, tuple[bytes, int, float]] = field(default_factory=dict)
    pending_since_s: float = 0.0
    ack_votes: int = 0  # the peer's segments that acknowledged past the hole before the waiting ones
    buffer: bytes = b""
    fragments: list[bytes] = field(default_factory=list)
    broken: bool = False
    gap: Gap | None = None  # the last gap, while frames it cut are being skipped


@dataclass
class _Connection:
    number: int
    label: str
    directions: dict[bool, _Direction] = field(default_factory=lambda: {True: _Direction(), False: _Direction()})


_Record = tuple[int, float, "bytes | mmap.mmap", int, int]  # number, time, buffer, start, captured length
_NANOSECOND_MAGICS = (dpkt.pcap.TCPDUMP_MAGIC_NANO, dpkt.pcap.PMUDPCT_MAGIC_NANO)


def _dpkt_records(reader: dpkt.pcap.Reader | dpkt.pcapng.Reader, capture: Capture) -> Iterator[_Record]:
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
        frame = bytes(frame)
        yield number, float(ts), frame, 0, len(frame)


def _mapped_pcap_records(records: mmap.mmap, magic: int, capture: Capture) -> Iterator[_Record]:
    """The records of a classic pcap file, walked in place (dpkt reads a record with two file reads
    and a header object: half the decode time of a big capture). dpkt has checked the file header;
    the record header layout and timestamp resolution are dpkt's for this magic number."""
    header_type = dpkt.pcap.MAGIC_TO_PKT_HDR[magic]
    # tv_sec, tv_usec (or nsec), caplen: the first fields of dpkt's record header for this magic
    unpack_record = struct.Struct(header_type.__hdr_fmt__[:4]).unpack_from
    record_length = header_type.__hdr_len__
    divisor = 1e9 if magic in _NANOSECOND_MAGICS else 1e6
    size = len(records)
    position = 24
    number = 0
    while position < size:
        if position + record_length > size:
            capture.problems.append(f"frame {number + 1}: capture ends in a damaged record (its header cut "
                                    "short); the frames before it were read")
            return
        seconds, fraction, caplen = unpack_record(records, position)
        start = position + record_length
        position = start + caplen
        if position > size:
            capture.problems.append(f"frame {number + 1}: capture ends in a damaged record ({caplen} bytes "
                                    f"announced, {size - start} there); the frames before it were read")
            return
        number += 1
        yield number, seconds + fraction / divisor, records, start, caplen


def _mapped_pcapng_records(records: mmap.mmap, first_block: int, reader: dpkt.pcapng.Reader,
                           capture: Capture) -> Iterator[_Record]:
    """The packet blocks of a pcapng file, walked in place, with dpkt's reading of it: dpkt has read the
    section header and the first interface description (byte order, timestamp resolution and offset,
    link type for all frames), and, as dpkt does, enhanced and obsolete packet blocks are frames and
    other blocks are skipped."""
    little_endian = isinstance(reader.idb, dpkt.pcapng.InterfaceDescriptionBlockLE)
    order = "<" if little_endian else ">"
    unpack_block = struct.Struct(order + "II").unpack_from
    # interface id (and drop count in the obsolete block), timestamp high and low words, captured length
    unpack_packet = struct.Struct(order + "4xIII").unpack_from
    packet_blocks = (dpkt.pcapng.PCAPNG_BT_EPB, dpkt.pcapng.PCAPNG_BT_PB)
    divisor = reader._divisor    # from the interface's if_tsresol
    offset_s = reader._tsoffset  # and if_tsoffset
    size = len(records)
    position = first_block  # where dpkt stopped reading: after the first interface description
    number = 0
    while position + 8 <= size:
        block_type, block_length = unpack_block(records, position)
        block_end = position + block_length
        if block_length < 12 or block_end > size:
            capture.problems.append(f"frame {number + 1}: capture ends in a damaged record (a block of "
                                    f"{block_length} bytes, {size - position} there); the frames before it "
                                    "were read")
            return
        if block_type in packet_blocks:
            if block_length < 32:
                capture.problems.append(f"frame {number + 1}: capture ends in a damaged record (a packet "
                                        f"block of {block_length} bytes); the frames before it were read")
                return
            ts_high, ts_low, caplen = unpack_packet(records, position + 8)
            start = position + 28
            if start + caplen > block_end - 4:
                capture.problems.append(f"frame {number + 1}: capture ends in a damaged record ({caplen} "
                                        "bytes announced in a shorter block); the frames before it were read")
                return
            number += 1
            yield number, offset_s + ((ts_high << 32) | ts_low) / divisor, records, start, caplen
        position = block_end
    if position < size:
        capture.problems.append(f"frame {number + 1}: capture ends in a damaged record (a block header cut "
                                "short); the frames before it were read")


@dataclass(frozen=True, slots=True)
class _Segment:
    sport: int
    dport: int
    seq: int
    ack: int
    flags: int
    data: bytes


_ETH_IPV4_TCP = struct.Struct(">12xH")
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
    sport, dport, seq, ack, offset, flags = _TCP_HEADER.unpack_from(frame, tcp_start)
    data_start = tcp_start + (offset >> 4) * 4
    end = min(len(frame), 14 + total) if total else len(frame)
    src = socket.inet_ntop(socket.AF_INET, frame[26:30])
    dst = socket.inet_ntop(socket.AF_INET, frame[30:34])
    return src, dst, _Segment(sport, dport, seq, ack, flags, frame[data_start:end])


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


# Link types the hot path reads, by the length of their header (which ends in the 2-byte EtherType):
# Ethernet, and Linux "cooked" captures (tcpdump -i any).
_HOT_LINK_HEADERS = {dpkt.pcap.DLT_EN10MB: 14, dpkt.pcap.DLT_LINUX_SLL: 16}


def _hot_headers(link_header: int) -> struct.Struct:
    """One unpack for the hot path, from the EtherType to the COTP DT header: EtherType; IPv4
    version/IHL, total length, flags/fragment offset, protocol; addresses and ports (one connection
    direction); TCP sequence number, data offset, flags; TPKT version/reserved and length; COTP DT."""
    return struct.Struct(f">{link_header - 2}xHBxH2xHxB2x12sI4xBB6xHH3s")


class _Reassembly:
    """Connections and TCP streams of one capture, fed frame by frame."""

    def __init__(self, capture: Capture, port: int) -> None:
        self.capture = capture
        self.port = port
        self.connections: dict[tuple[str, int, str], _Connection] = {}
        # Ethernet/IPv4/TCP address-and-port bytes -> (connection, from_client, direction, the other one)
        self.hot: dict[bytes, tuple[_Connection, bool, _Direction, _Direction]] = {}

    def walk(self, records: Iterator[_Record], link: int) -> None:
        """Every record, as (frame number, time, buffer, start, captured length). Frames that are one whole
        S7 frame in order (Ethernet or Linux cooked, IPv4 without options, TCP, TPKT, COTP DT) on a known
        connection give their PDU straight from the buffer: no dpkt objects, no reassembly. Anything else
        is reassembled."""
        general = self._general
        hot_connections = self.hot
        pdus = self.capture.pdus
        ip = _HOT_LINK_HEADERS.get(link, 0)  # where IPv4 starts; 0: no hot path for this link type
        unpack_headers = _hot_headers(ip or 14).unpack_from
        tpkt_at = ip + 40  # after IPv4 and TCP without options
        pdu_at = tpkt_at + 7  # after TPKT and COTP DT
        number = 0
        for number, ts, buffer, start, caplen in records:
            if ip and caplen >= pdu_at:
                ethertype, version_ihl, total, fragment, protocol, key, seq, offset, flags, tpkt_head, \
                    tpkt_length, cotp_dt = unpack_headers(buffer, start)
                if ethertype == 0x0800 and version_ihl == 0x45 and protocol == 6 and not fragment & 0x3FFF \
                        and not flags & _FAST_EXCLUDED_FLAGS and offset >> 4 == 5 and tpkt_head == 0x0300 \
                        and cotp_dt == b"\x02\xf0\x80":
                    known = hot_connections.get(key)
                    if known is not None:
                        connection, from_client, direction, other = known
                        end = ip + total if total else caplen
                        # (a hole in the other direction: this segment's ACK may say it was lost)
                        if seq == direction.next_seq and tpkt_length == end - tpkt_at and pdu_at < end <= caplen \
                                and not (direction.pending or direction.buffer or direction.fragments
                                         or direction.broken or other.pending):
                            direction.next_seq = (seq + tpkt_length) & 0xFFFFFFFF
                            pdus.append(TracePdu(number, ts, connection.number, from_client, "s7",
                                                 buffer[start + pdu_at:start + end]))
                            continue
            general(number, ts, buffer[start:start + caplen], link)
        self.capture.frames = number

    def _general(self, number: int, ts: float, frame: bytes, link: int) -> None:
        parsed = _tcp(frame, link)
        if parsed is None:
            return
        src, dst, segment = parsed
        port = self.port
        if segment.dport == port:
            key, from_client = (src, segment.sport, dst), True
        elif segment.sport == port:
            key, from_client = (dst, segment.dport, src), False
        else:
            return
        connection = self.connections.get(key)
        if connection is None:
            connection = _Connection(len(self.connections) + 1, f"{key[0]}:{key[1]} -> {key[2]}:{port}")
            self.connections[key] = connection
            self.capture.connections[connection.number] = connection.label
        ip = _HOT_LINK_HEADERS.get(link)
        if ip is not None and len(frame) >= ip + 24 and frame[ip - 2:ip + 1] == b"\x08\x00\x45":  # hot layout
            self.hot.setdefault(frame[ip + 12:ip + 24], (connection, from_client, connection.directions[from_client],
                                                         connection.directions[not from_client]))
        _feed(self.capture, connection, from_client, segment, number, ts)

    def finish(self) -> None:
        """The end of the capture: what still waits behind a hole is past a gap. PDUs delivered after
        later frames' PDUs are put back in frame order."""
        for connection in self.connections.values():
            for from_client, direction in connection.directions.items():
                while direction.pending:
                    _skip_gap(self.capture, connection, from_client, direction)
        if self.capture.gaps:
            self.capture.pdus.sort(key=_frame_of)


def _frame_of(pdu: TracePdu) -> int:
    return pdu.frame


@contextmanager
def collector_paused() -> Iterator[None]:
    """Python's cycle collector off while a capture's millions of small objects are built: none of them
    form cycles, and each collection would scan them all again (half the decode time of a big capture)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def read_capture(path: str | Path, *, port: int = S7_PORT) -> Capture:
    """All S7 PDUs of all connections on ``port`` (the server side), in capture order."""
    path = Path(path)
    source = str(path)
    try:
        handle = path.open("rb")
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=source) from None
    capture = Capture(source)
    reassembly = _Reassembly(capture, port)
    with handle, collector_paused():
        head = handle.read(4)
        handle.seek(0)
        if len(head) < 4:
            raise NckConfigError("empty or too short to be a capture file", path=source)
        pcapng = head == b"\x0a\x0d\x0d\x0a"
        try:
            reader = dpkt.pcapng.Reader(handle) if pcapng else dpkt.pcap.Reader(handle)
        except (ValueError, dpkt.dpkt.Error, EOFError) as exc:
            raise NckConfigError(f"not a pcap or pcapng file ({exc})", path=source) from None
        mapped = _mapped(handle)
        if mapped is None:
            reassembly.walk(_dpkt_records(reader, capture), reader.datalink())
        else:
            with mapped:
                records = _mapped_pcapng_records(mapped, handle.tell(), reader, capture) if pcapng \
                    else _mapped_pcap_records(mapped, int.from_bytes(head, "big"), capture)
                reassembly.walk(records, reader.datalink())
        reassembly.finish()
    if capture.frames == 0:
        raise NckConfigError("no frames could be read", path=source)
    return capture


def _mapped(handle: BinaryIO) -> mmap.mmap | None:
    """The file in memory, or None where it cannot be mapped (a pipe): dpkt then reads it record by record."""
    try:
        return mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ)
    except (ValueError, OSError, io.UnsupportedOperation):
        return None


def _feed(capture: Capture, connection: _Connection, from_client: bool, segment: dpkt.tcp.TCP | _Segment,
          number: int, ts: float) -> None:
    direction = connection.directions[from_client]
    other = connection.directions[not from_client]
    if other.pending and segment.flags & dpkt.tcp.TH_ACK and other.next_seq is not None \
            and 0 < ((segment.ack - other.next_seq) & _SEQ_MASK) < _HALF_SEQ:
        # The peer acknowledges bytes of the other direction that the capture has not shown: lost, once
        # it has done so a few times (or late: then they come and fill the hole).
        other.ack_votes += 1
        if other.ack_votes >= _GAP_ACK_VOTES:
            ack = segment.ack
            while other.pending and other.next_seq is not None \
                    and 0 < ((ack - other.next_seq) & _SEQ_MASK) < _HALF_SEQ:
                _skip_gap(capture, connection, not from_client, other)
            other.ack_votes = 0
    seq = segment.seq
    payload = bytes(segment.data)
    if segment.flags & dpkt.tcp.TH_SYN:
        if direction.isn is None and direction.next_seq is not None \
                and ((direction.next_seq - (seq + 1)) & _SEQ_MASK) < _HALF_SEQ:
            direction.isn = seq  # captured after data it precedes: the stream so far stands
            return
        if direction.isn != seq:  # a retransmitted SYN changes nothing; a new one starts afresh
            direction.isn = seq
            direction.next_seq = (seq + 1) & _SEQ_MASK
            direction.pending.clear()
            direction.buffer = b""
            direction.fragments.clear()
        return
    if not payload:
        return
    if direction.next_seq is None:
        direction.next_seq = seq
    offset = (seq - direction.next_seq) & _SEQ_MASK
    if offset >= _HALF_SEQ:  # before what we have: a retransmission, maybe overlapping
        overlap = (direction.next_seq - seq) & _SEQ_MASK
        if overlap >= len(payload):
            return
        payload = payload[overlap:]
        seq = direction.next_seq
        offset = 0
    if offset > 0:
        pending = direction.pending
        if not pending:
            direction.pending_since_s = ts
        if sum(len(p[0]) for p in pending.values()) < _MAX_PENDING_BYTES:
            pending.setdefault(seq, (payload, number, ts))
        if len(pending) >= _GAP_WAIT_SEGMENTS or ts - direction.pending_since_s > _GAP_WAIT_S:
            _skip_gap(capture, connection, from_client, direction)
        return
    stream = payload
    next_seq = (seq + len(payload)) & _SEQ_MASK
    while next_seq in direction.pending:
        more = direction.pending.pop(next_seq)[0]
        stream += more
        next_seq = (next_seq + len(more)) & _SEQ_MASK
    direction.next_seq = next_seq
    direction.ack_votes = 0  # the hole filled: it was late, not lost
    _drop_stale(direction, next_seq)
    _frames(capture, connection, from_client, direction, stream, number, ts)


def _drop_stale(direction: _Direction, next_seq: int) -> None:
    """Segments that the stream (now at ``next_seq``) has overtaken are duplicates."""
    for stale in [s for s in direction.pending if ((s - next_seq) & _SEQ_MASK) >= _HALF_SEQ]:
        direction.pending.pop(stale)


def _skip_gap(capture: Capture, connection: _Connection, from_client: bool, direction: _Direction) -> None:
    """Jump over the hole before the nearest waiting segment: record the gap, drop the frame it cut,
    and go on from that segment (and those after it in sequence), each PDU at the frame that brought it."""
    next_seq = direction.next_seq
    assert next_seq is not None
    first = min(direction.pending, key=lambda s: (s - next_seq) & _SEQ_MASK)
    payload, number, ts = direction.pending.pop(first)
    cut = len(direction.buffer) + sum(len(f) for f in direction.fragments)
    gap = Gap(number, ts, connection.number, from_client, (first - next_seq) & _SEQ_MASK, cut)
    capture.gaps.append(gap)
    direction.gap = gap
    direction.buffer = b""
    direction.fragments.clear()
    direction.broken = True
    while True:
        next_seq = direction.next_seq = (first + len(payload)) & _SEQ_MASK
        _frames(capture, connection, from_client, direction, payload, number, ts)
        following = direction.pending.pop(next_seq, None)
        if following is None:
            break
        first = next_seq
        payload, number, ts = following
    _drop_stale(direction, next_seq)
    if direction.pending:
        direction.pending_since_s = min(p[2] for p in direction.pending.values())


def _frames(capture: Capture, connection: _Connection, from_client: bool, direction: _Direction, data: bytes,
            number: int, ts: float) -> None:
    if direction.broken:
        match = _TPKT_START.search(data)
        skipped = len(data) if match is None else match.start()
        if direction.gap is not None:
            direction.gap.skipped_bytes += skipped
        if match is None:
            return
        data = data[skipped:]
        direction.broken = False
        direction.gap = None
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
