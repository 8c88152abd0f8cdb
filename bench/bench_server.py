"""Server throughput and latency: nckemu against python-snap7's own Server, same load, same run.

Loads (each from 1 and 8 client processes over loopback):
* NCK REAL8 read: one NCK item (SD43900 of axis 4);
* DB read: 4 bytes of a DB.
Drivers: ``snap7``, python-snap7's Client (``iso_exchange_buffer`` and ``db_read``), and ``raw``, a
load generator that sends the very same request frames from pre-built bytes over a plain socket
and reads the answers. python-snap7's Client is pure Python and, on a small machine, the client
processes take most of the CPU; the raw driver leaves the CPU to the server under test.
The anchor (python-snap7 3.3 Server) answers the NCK read with DB1 bytes (it ignores the syntax
ID), so it does the same amount of work per request: the comparison is of request handling.

Usage: .venv/bin/python bench/bench_server.py [--seconds 3] [--clients 1 8] [--drivers snap7 raw]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
NCK_READ_PDU = bytes.fromhex("32010000000100 0c 0000 04 01 12088264AB7C00011601".replace(" ", ""))
ANCHOR_SCRIPT = """
import sys, time, snap7
from snap7.type import SrvArea
server = snap7.server.Server(log=False)
db = bytearray(64)
server.register_area(SrvArea.DB, 1, db)
server.register_area(SrvArea.DB, 130, bytearray(64))
server.start(tcp_port=int(sys.argv[1]))
print("ready", flush=True)
while True:
    time.sleep(1)
"""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def wait_port(port: int, timeout_s: float = 20.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.5):
                return
        except OSError:
            time.sleep(0.05)
    raise RuntimeError(f"server on port {port} did not come up")


def start_nckemu(port: int) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=REPO)


def start_anchor(port: int) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-c", ANCHOR_SCRIPT, str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def client_worker(port: int, load: str, seconds: float, db: int, out: mp.Queue) -> None:  # type: ignore[type-arg]
    import logging

    import snap7

    logging.disable(logging.CRITICAL)
    client = snap7.Client()
    client.connect("127.0.0.1", 0, 4, port)
    latencies: list[float] = []
    request = bytearray(NCK_READ_PDU)
    deadline = time.perf_counter() + seconds
    while True:
        start = time.perf_counter()
        if start >= deadline:
            break
        if load == "nck":
            client.iso_exchange_buffer(request)
        else:
            client.db_read(db, 0, 4)
        latencies.append(time.perf_counter() - start)
    client.disconnect()
    out.put(latencies)


def _raw_frames(load: str, db: int) -> tuple[bytes, bytes, bytes]:
    """COTP CR (rack 0, slot 4), setup communication (PDU 480, AMQ 1) and the request, as sent by
    python-snap7."""
    sys.path.insert(0, str(REPO))
    from nckemu.protocol import cotp, s7
    from nckemu.protocol.addresses import S7AnyAddress

    connect = cotp.build_frame(cotp.ConnectRequest(src_ref=1, calling_tsap=b"\x01\x00", called_tsap=b"\x01\x04",
                                                   tpdu_size=1024))
    setup = cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, 0, s7.build_setup_communication(
        s7.SetupCommunication(1, 1, 480)))))
    if load == "nck":
        request = cotp.build_data_frame(NCK_READ_PDU)
    else:
        item = S7AnyAddress(transport_size=0x02, count=4, db_number=db, area=0x84, byte_address=0)
        request = cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, 1, s7.build_read_var_request(
            s7.ReadVarRequest((item,))))))
    return connect, setup, request


def _receive_frame(sock: socket.socket) -> bytes:
    head = b""
    while len(head) < 4:
        chunk = sock.recv(4 - len(head))
        if not chunk:
            raise ConnectionError("server closed the connection")
        head += chunk
    length = int.from_bytes(head[2:4], "big")
    body = b""
    while len(body) < length - 4:
        chunk = sock.recv(length - 4 - len(body))
        if not chunk:
            raise ConnectionError("server closed the connection")
        body += chunk
    return head + body


def raw_worker(port: int, load: str, seconds: float, db: int, out: mp.Queue) -> None:  # type: ignore[type-arg]
    connect, setup, request = _raw_frames(load, db)
    sock = socket.create_connection(("127.0.0.1", port))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    for frame in (connect, setup):
        sock.sendall(frame)
        _receive_frame(sock)
    latencies: list[float] = []
    deadline = time.perf_counter() + seconds
    while True:
        start = time.perf_counter()
        if start >= deadline:
            break
        sock.sendall(request)
        answer = _receive_frame(sock)
        if len(answer) < 22 or answer[21] != 0xFF:  # TPKT 4 + COTP 3 + ack header 12 + parameter 2
            raise RuntimeError(f"the read failed: {answer.hex()}")
        latencies.append(time.perf_counter() - start)
    sock.close()
    out.put(latencies)


def measure(port: int, load: str, clients: int, seconds: float, db: int, driver: str = "snap7") -> dict[str, float]:
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    target = raw_worker if driver == "raw" else client_worker
    workers = [ctx.Process(target=target, args=(port, load, seconds, db, queue))
               for _ in range(clients)]
    for worker in workers:
        worker.start()
    latencies: list[float] = []
    for _ in workers:
        latencies.extend(queue.get(timeout=seconds + 60))
    for worker in workers:
        worker.join()
    latencies.sort()
    return {
        "requests_per_s": len(latencies) / seconds,
        "p50_ms": 1000 * statistics.median(latencies),
        "p99_ms": 1000 * latencies[int(0.99 * (len(latencies) - 1))],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--clients", type=int, nargs="+", default=[1, 8])
    parser.add_argument("--drivers", nargs="+", choices=("snap7", "raw"), default=["snap7", "raw"])
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    results = []
    for name, starter, db in (("python-snap7 Server (anchor)", start_anchor, 1), ("nckemu", start_nckemu, 130)):
        port = free_port()
        process = starter(port)
        try:
            wait_port(port)
            for driver in args.drivers:
                for load in ("nck", "db"):
                    for clients in args.clients:
                        figures = measure(port, load, clients, args.seconds, db, driver)
                        results.append({"server": name, "driver": driver, "load": load, "clients": clients,
                                        **figures})
        finally:
            process.terminate()
            process.wait(timeout=10)
    anchor = {(r["driver"], r["load"], r["clients"]): r for r in results if r["server"].startswith("python-snap7")}
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    print(f"machine: {os.cpu_count()} cores; {args.seconds:.0f} s per point")
    print(f"{'server':30} {'driver':6} {'load':5} {'clients':>7} {'req/s':>9} {'p50 ms':>8} {'p99 ms':>8} "
          f"{'x anchor':>9}")
    for r in sorted(results, key=lambda r: (r["driver"], r["load"], r["clients"], r["server"])):
        ratio = r["requests_per_s"] / anchor[(r["driver"], r["load"], r["clients"])]["requests_per_s"]
        print(f"{r['server']:30} {r['driver']:6} {r['load']:5} {r['clients']:>7} {r['requests_per_s']:>9.0f} "
              f"{r['p50_ms']:>8.3f} {r['p99_ms']:>8.3f} {ratio:>9.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
