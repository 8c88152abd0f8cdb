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
Each point also reports the CPU time per request of the server process and of the client processes
together, and, for loads with more client processes than cores, the throughput the cores allow at
that CPU cost: it shows when the clients, not the server, set the pace.

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
from typing import Any

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


def client_worker(port: int, load: str, seconds: float, db: int, out: mp.Queue,  # type: ignore[type-arg]
                  start: Any) -> None:
    import logging

    import snap7

    logging.disable(logging.CRITICAL)
    client = snap7.Client()
    client.connect("127.0.0.1", 0, 4, port)
    latencies: list[float] = []
    request = bytearray(NCK_READ_PDU)
    start.wait()  # all clients connected and idle: the measurement starts together
    cpu_start_s = time.process_time()
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
    cpu_s = time.process_time() - cpu_start_s
    client.disconnect()
    out.put((latencies, cpu_s))


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
    """One TPKT frame; usually one recv call (a small answer arrives whole), so the load generator
    spends as little CPU as it can."""
    data = sock.recv(65536)
    while True:
        if not data:
            raise ConnectionError("server closed the connection")
        if len(data) >= 4 and len(data) >= int.from_bytes(data[2:4], "big"):
            return data
        more = sock.recv(65536)
        if not more:
            raise ConnectionError("server closed the connection")
        data += more


def raw_worker(port: int, load: str, seconds: float, db: int, out: mp.Queue,  # type: ignore[type-arg]
               start: Any) -> None:
    connect, setup, request = _raw_frames(load, db)
    sock = socket.create_connection(("127.0.0.1", port))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    for frame in (connect, setup):
        sock.sendall(frame)
        _receive_frame(sock)
    latencies: list[float] = []
    start.wait()
    cpu_start_s = time.process_time()
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
    cpu_s = time.process_time() - cpu_start_s
    sock.close()
    out.put((latencies, cpu_s))


def process_cpu_s(pid: int) -> float | None:
    """User + system CPU seconds of a process so far (Linux /proc), None elsewhere."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(port: int, load: str, clients: int, seconds: float, db: int, driver: str = "snap7",
            server_pid: int | None = None) -> dict[str, float]:
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    target = raw_worker if driver == "raw" else client_worker
    # Clients start, import and connect first, then all begin together: Python start-up (a third of a
    # second of CPU each) would otherwise fall into the others' measurement and into its tail.
    start = ctx.Barrier(clients + 1)
    workers = [ctx.Process(target=target, args=(port, load, seconds, db, queue, start))
               for _ in range(clients)]
    for worker in workers:
        worker.start()
    start.wait(timeout=120)
    server_cpu_start = process_cpu_s(server_pid) if server_pid is not None else None
    latencies: list[float] = []
    client_cpu_s = 0.0
    for _ in workers:
        worker_latencies, worker_cpu_s = queue.get(timeout=seconds + 60)
        latencies.extend(worker_latencies)
        client_cpu_s += worker_cpu_s
    for worker in workers:
        worker.join()
    server_cpu_end = process_cpu_s(server_pid) if server_pid is not None else None
    latencies.sort()
    figures = {
        "requests_per_s": len(latencies) / seconds,
        "p50_ms": 1000 * statistics.median(latencies),
        "p99_ms": 1000 * latencies[int(0.99 * (len(latencies) - 1))],
        "client_cpu_us": 1e6 * client_cpu_s / len(latencies),
    }
    if server_cpu_start is not None and server_cpu_end is not None:
        figures["server_cpu_us"] = 1e6 * (server_cpu_end - server_cpu_start) / len(latencies)
    return figures


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
                        figures = measure(port, load, clients, args.seconds, db, driver, process.pid)
                        results.append({"server": name, "driver": driver, "load": load, "clients": clients,
                                        **figures})
        finally:
            process.terminate()
            process.wait(timeout=10)
    anchor = {(r["driver"], r["load"], r["clients"]): r for r in results if r["server"].startswith("python-snap7")}
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    cores = os.cpu_count() or 1
    print(f"machine: {cores} cores; {args.seconds:.0f} s per point; CPU in microseconds per request "
          "(server process; all client processes together)")
    print(f"{'server':30} {'driver':6} {'load':5} {'clients':>7} {'req/s':>9} {'p50 ms':>8} {'p99 ms':>8} "
          f"{'x anchor':>9} {'srv CPU':>8} {'cli CPU':>8}")
    for r in sorted(results, key=lambda r: (r["driver"], r["load"], r["clients"], r["server"])):
        ratio = r["requests_per_s"] / anchor[(r["driver"], r["load"], r["clients"])]["requests_per_s"]
        server_cpu = f"{r['server_cpu_us']:8.1f}" if "server_cpu_us" in r else f"{'?':>8}"
        print(f"{r['server']:30} {r['driver']:6} {r['load']:5} {r['clients']:>7} {r['requests_per_s']:>9.0f} "
              f"{r['p50_ms']:>8.3f} {r['p99_ms']:>8.3f} {ratio:>9.2f} {server_cpu} {r['client_cpu_us']:8.1f}")
    for r in results:
        if r["server"] == "nckemu" and r["clients"] > cores and "server_cpu_us" in r:
            bound = cores * 1e6 / (r["server_cpu_us"] + r["client_cpu_us"])
            print(f"{r['driver']} {r['load']} x{r['clients']}: {cores} cores allow at most {bound:,.0f} req/s at "
                  f"this CPU per request (nckemu {r['server_cpu_us']:.1f} us + clients {r['client_cpu_us']:.1f} us); "
                  f"measured {r['requests_per_s']:,.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
