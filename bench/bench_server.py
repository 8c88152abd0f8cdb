"""Server throughput and latency: nckemu against python-snap7's own Server, same load, same run.

Loads (each from 1 and 8 client processes, python-snap7 Client over loopback):
* NCK REAL8 read: one NCK item (SD43900 of axis 4) through ``iso_exchange_buffer``;
* DB read: ``db_read(db, 0, 4)``.
The anchor (python-snap7 3.3 Server) answers the NCK read with DB1 bytes (it ignores the syntax
ID), so it does the same amount of work per request: the comparison is of request handling.

Usage: .venv/bin/python bench/bench_server.py [--seconds 3] [--clients 1 8]
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


def measure(port: int, load: str, clients: int, seconds: float, db: int) -> dict[str, float]:
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    workers = [ctx.Process(target=client_worker, args=(port, load, seconds, db, queue))
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
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    results = []
    for name, starter, db in (("python-snap7 Server (anchor)", start_anchor, 1), ("nckemu", start_nckemu, 130)):
        port = free_port()
        process = starter(port)
        try:
            wait_port(port)
            for load in ("nck", "db"):
                for clients in args.clients:
                    figures = measure(port, load, clients, args.seconds, db)
                    results.append({"server": name, "load": load, "clients": clients, **figures})
        finally:
            process.terminate()
            process.wait(timeout=10)
    anchor = {(r["load"], r["clients"]): r for r in results if r["server"].startswith("python-snap7")}
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    print(f"machine: {os.cpu_count()} cores; {args.seconds:.0f} s per point")
    print(f"{'server':30} {'load':5} {'clients':>7} {'req/s':>9} {'p50 ms':>8} {'p99 ms':>8} {'x anchor':>9}")
    for r in results:
        ratio = r["requests_per_s"] / anchor[(r["load"], r["clients"])]["requests_per_s"]
        print(f"{r['server']:30} {r['load']:5} {r['clients']:>7} {r['requests_per_s']:>9.0f} "
              f"{r['p50_ms']:>8.3f} {r['p99_ms']:>8.3f} {ratio:>9.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
