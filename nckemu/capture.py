"""Writing S7 traffic as a capture file that Wireshark and tshark decode.

Frames are wrapped in synthetic Ethernet/IPv4/TCP headers with consistent sequence numbers per
connection, so tshark's TCP reassembly and the s7comm dissector work on them. The server side is
port 102 by default: there tshark decodes TPKT without a ``-d tcp.port==N,tpkt`` option.
"""

from __future__ import annotations

import itertools
import socket
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import dpkt

S7_PORT = 102
_MAC_CLIENT = b"\x02\x00\x00\x00\x00\x01"
_MAC_SERVER = b"\x02\x00\x00\x00\x00\x02"
_TCP_WINDOW = 65535
_MAX_SEGMENT = 65000  # an IPv4 packet holds at most 65535 bytes; longer payloads are split


@dataclass
class _Flow:
    client_ip: bytes
    client_port: int
    server_ip: bytes
    server_port: int
    client_seq: int
    server_seq: int
    opened: bool = False


@dataclass
class CaptureWriter:
    """Writes a pcapng (default) or classic pcap file of one or more TCP connections."""

    stream: BinaryIO
    pcapng: bool = True
    server_port: int = S7_PORT
    _writer: object = field(init=False)
    _flows: dict[object, _Flow] = field(init=False, default_factory=dict)
    _ports: itertools.count = field(init=False, default_factory=lambda: itertools.count(49152))
    _lock: threading.Lock = field(init=False, default_factory=threading.Lock)

    def __post_init__(self) -> None:
        self._writer = (dpkt.pcapng.Writer(self.stream) if self.pcapng
                        else dpkt.pcap.Writer(self.stream))

    @classmethod
    def open(cls, path: str | Path, *, server_port: int = S7_PORT) -> CaptureWriter:
        path = Path(path)
        return cls(path.open("wb"), pcapng=path.suffix.lower() != ".pcap", server_port=server_port)

    def _flow(self, connection: object, client: tuple[str, int] | None) -> _Flow:
        flow = self._flows.get(connection)
        if flow is None:
            host, port = client if client else ("127.0.0.1", next(self._ports))
            try:
                client_ip = socket.inet_aton(host)
            except OSError:
                client_ip = socket.inet_aton("127.0.0.1")
            flow = _Flow(client_ip, port, socket.inet_aton("127.0.0.1"), self.server_port,
                         client_seq=1000, server_seq=5000)
            self._flows[connection] = flow
        return flow

    def _packet(self, flow: _Flow, from_client: bool, flags: int, payload: bytes, ts: float) -> None:
        if from_client:
            src, dst, sport, dport = flow.client_ip, flow.server_ip, flow.client_port, flow.server_port
            seq, ack = flow.client_seq, flow.server_seq
        else:
            src, dst, sport, dport = flow.server_ip, flow.client_ip, flow.server_port, flow.client_port
            seq, ack = flow.server_seq, flow.client_seq
        tcp = dpkt.tcp.TCP(sport=sport, dport=dport, seq=seq & 0xFFFFFFFF, ack=ack & 0xFFFFFFFF,
                           flags=flags, win=_TCP_WINDOW, data=payload)
        ip = dpkt.ip.IP(src=src, dst=dst, p=dpkt.ip.IP_PROTO_TCP, ttl=64, data=tcp)
        ip.len = len(ip)
        eth = dpkt.ethernet.Ethernet(src=_MAC_CLIENT if from_client else _MAC_SERVER,
                                     dst=_MAC_SERVER if from_client else _MAC_CLIENT,
                                     type=dpkt.ethernet.ETH_TYPE_IP, data=ip)
        self._writer.writepkt(bytes(eth), ts=ts)  # type: ignore[attr-defined]
        advance = len(payload) + (1 if flags & (dpkt.tcp.TH_SYN | dpkt.tcp.TH_FIN) else 0)
        if from_client:
            flow.client_seq += advance
        else:
            flow.server_seq += advance

    def _open(self, flow: _Flow, ts: float) -> None:
        if flow.opened:
            return
        flow.opened = True
        flow.client_seq -= 1
        flow.server_seq -= 1
        self._packet(flow, True, dpkt.tcp.TH_SYN, b"", ts)
        self._packet(flow, False, dpkt.tcp.TH_SYN | dpkt.tcp.TH_ACK, b"", ts)
        self._packet(flow, True, dpkt.tcp.TH_ACK, b"", ts)

    def segment(self, connection: object, from_client: bool, payload: bytes, *,
                timestamp: float | None = None, client: tuple[str, int] | None = None) -> None:
        """Record bytes that crossed one connection in one direction (split as IPv4 requires)."""
        ts = time.time() if timestamp is None else timestamp
        with self._lock:
            flow = self._flow(connection, client)
            self._open(flow, ts)
            for start in range(0, max(len(payload), 1), _MAX_SEGMENT):
                chunk = payload[start:start + _MAX_SEGMENT]
                if chunk:
                    self._packet(flow, from_client, dpkt.tcp.TH_PUSH | dpkt.tcp.TH_ACK, chunk, ts)

    def close_connection(self, connection: object, *, timestamp: float | None = None) -> None:
        ts = time.time() if timestamp is None else timestamp
        with self._lock:
            flow = self._flows.pop(connection, None)
            if flow is not None and flow.opened:
                self._packet(flow, True, dpkt.tcp.TH_FIN | dpkt.tcp.TH_ACK, b"", ts)
                self._packet(flow, False, dpkt.tcp.TH_FIN | dpkt.tcp.TH_ACK, b"", ts)

    def flush(self) -> None:
        with self._lock:
            self.stream.flush()

    def close(self) -> None:
        with self._lock:
            for connection in list(self._flows):
                flow = self._flows.pop(connection)
                if flow.opened:
                    ts = time.time()
                    self._packet(flow, True, dpkt.tcp.TH_FIN | dpkt.tcp.TH_ACK, b"", ts)
                    self._packet(flow, False, dpkt.tcp.TH_FIN | dpkt.tcp.TH_ACK, b"", ts)
            self.stream.close()


def write_capture(path: str | Path, frames: list[tuple[bool, bytes]], *, server_port: int = S7_PORT,
                  connection: object = 0, start_s: float = 1_700_000_000.0, step_s: float = 0.001) -> None:
    """Write one connection's frames, each ``(from_client, tpkt_bytes)``, as a capture file."""
    writer = CaptureWriter.open(path, server_port=server_port)
    try:
        for index, (from_client, payload) in enumerate(frames):
            writer.segment(connection, from_client, payload, timestamp=start_s + index * step_s)
    finally:
        writer.close()
