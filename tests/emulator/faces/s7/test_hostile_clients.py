"""Misbehaving clients hit each transport limit; the other clients do not notice."""

from __future__ import annotations

import shutil
import socket
import struct
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from nckemu.clients import NckClient
from nckemu.emulator.faces.s7.server import ServerLimits
from nckemu.emulator.runner import EmulatorThread

CR = bytes.fromhex("0300001611E00000000100C0010AC1020100C2020104")
SETUP = bytes.fromhex("0300001902F08032010000000100080000F0000008000803C0")


def job(pdu_ref: int, parameter: bytes) -> bytes:
    pdu = struct.pack(">BBHHHH", 0x32, 1, 0, pdu_ref, len(parameter), 0) + parameter
    return struct.pack(">BBH", 3, 0, 7 + len(pdu)) + b"\x02\xf0\x80" + pdu


R_ALL = job(9, bytes.fromhex("0401120882410001000115 64".replace(" ", "")))  # R0..R99: 800 bytes back


def raw_connect(port: int, *, rcvbuf: int | None = None) -> socket.socket:
    sock = socket.socket()
    if rcvbuf is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    sock.settimeout(5)
    sock.connect(("127.0.0.1", port))
    return sock


def recv_frame(sock: socket.socket) -> bytes:
    header = b""
    while len(header) < 4:
        chunk = sock.recv(4 - len(header))
        if not chunk:
            return b""
        header += chunk
    length = struct.unpack(">H", header[2:4])[0]
    body = b""
    while len(body) < length - 4:
        chunk = sock.recv(length - 4 - len(body))
        if not chunk:
            return b""
        body += chunk
    return header + body


def handshake(sock: socket.socket) -> None:
    sock.sendall(CR)
    assert recv_frame(sock)[5] == 0xD0
    sock.sendall(SETUP)
    assert recv_frame(sock)[8] == 3


def closed_by_server(sock: socket.socket, within_s: float) -> bool:
    sock.settimeout(within_s)
    try:
        while True:
            if not sock.recv(65536):
                return True
    except TimeoutError:
        return False
    except ConnectionResetError:
        return True


LIMITS = ServerLimits(max_connections=4, idle_timeout_s=0.6, write_buffer_high_bytes=16 * 1024,
                      write_stall_timeout_s=0.6, partial_frame_timeout_s=0.6)


@pytest.fixture
def emulator() -> Iterator[EmulatorThread]:
    with EmulatorThread(limits=LIMITS) as emu:
        yield emu


def test_idle_connection_is_closed(emulator: EmulatorThread) -> None:
    sock = raw_connect(emulator.port)
    handshake(sock)
    assert closed_by_server(sock, 3.0)


def test_one_byte_per_interval_hits_the_partial_frame_timeout(emulator: EmulatorThread) -> None:
    sock = raw_connect(emulator.port)
    handshake(sock)
    started = time.monotonic()
    closed = False
    for byte in R_ALL:
        try:
            sock.sendall(bytes([byte]))
        except OSError:
            closed = True
            break
        time.sleep(0.1)  # never idle for the idle timeout, but the frame takes too long
        if time.monotonic() - started > 3:
            break
    assert closed or closed_by_server(sock, 2.0)


def test_client_that_never_reads_is_cut_off(emulator: EmulatorThread) -> None:
    sock = raw_connect(emulator.port, rcvbuf=4096)
    handshake(sock)
    sock.settimeout(0.2)
    burst = b"".join(job(i, bytes.fromhex("040112088241000100011564")) for i in range(1, 200))
    sent = 0
    deadline = time.monotonic() + 10
    cut = False
    while time.monotonic() < deadline:
        try:
            sent += sock.send(burst)
        except TimeoutError:
            time.sleep(0.05)
        except OSError:
            cut = True
            break
    assert cut, f"still connected after sending {sent} bytes"
    with NckClient("127.0.0.1", emulator.port) as good:  # the others did not notice
        assert good.get("R1") == [0.0]


def test_more_jobs_than_amq_get_the_resource_error(emulator: EmulatorThread) -> None:
    sock = raw_connect(emulator.port)
    handshake(sock)
    sock.sendall(b"".join(job(100 + i, bytes.fromhex("040112088241000100011501")) for i in range(10)))
    answers = [recv_frame(sock) for _ in range(10)]
    errors = [(a[17], a[18]) for a in answers]
    assert errors[:8] == [(0, 0)] * 8 and errors[8:] == [(0x83, 0x02)] * 2


def test_connection_flood_beyond_the_limit_is_refused(emulator: EmulatorThread) -> None:
    held = [raw_connect(emulator.port) for _ in range(4)]
    for sock in held:
        handshake(sock)
    extra = raw_connect(emulator.port)
    assert closed_by_server(extra, 2.0)
    held[0].close()
    time.sleep(0.2)
    with NckClient("127.0.0.1", emulator.port) as good:
        assert good.get("R1") == [0.0]


def test_garbage_closes_only_that_connection(emulator: EmulatorThread) -> None:
    with NckClient("127.0.0.1", emulator.port) as good:
        bad = raw_connect(emulator.port)
        bad.sendall(b"\x16\x03\x01\x02\x00" + bytes(200))  # a TLS hello is not TPKT
        assert closed_by_server(bad, 2.0)
        good.put({"R2": 2.0})
        assert good.get("R2") == [2.0]


def test_unwritable_state_raises_an_alarm_and_keeps_serving(tmp_path: Path) -> None:
    directory = tmp_path / "state"
    directory.mkdir()
    with EmulatorThread(state_path=directory / "state.json") as emu, NckClient("127.0.0.1", emu.port) as client:
        client.put({"SD43900[AX4]": 0.1})
        assert client.get("numAlarms") == [0]
        shutil.rmtree(directory)
        directory.write_text("a file where the state directory was")  # every save now fails
        client.put({"SD43900[AX4]": 0.2})  # still served, still acknowledged
        assert client.get("numAlarms", "SD43900[AX4]") == [1, 0.2]
        directory.unlink()
        directory.mkdir()
        client.put({"SD43900[AX4]": 0.3})
        assert client.get("numAlarms") == [0]


def test_gross_flood_beyond_the_amq_is_disconnected(emulator: EmulatorThread) -> None:
    sock = raw_connect(emulator.port)
    handshake(sock)
    sock.sendall(b"".join(job(200 + i, bytes.fromhex("040112088241000100011501")) for i in range(40)))
    assert closed_by_server(sock, 3.0)  # 40 > 4 x AMQ 8: a flood, not a pipelining client
    with NckClient("127.0.0.1", emulator.port) as good:
        assert good.get("R1") == [0.0]
