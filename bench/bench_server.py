"""Server throughput and latency: nckemu against python-snap7's own Server and the native snap7
server (C, through node-snap7), same load, same run.

Loads (each from 1 and 8 client processes over loopback):
* NCK REAL8 read: one NCK item (SD43900 of axis 4);
* DB read: 4 bytes of a DB;
* PIW read: 2 bytes at input byte 420 (``read_area(Area.PE, 0, 420, 2)``; nckemu wires a sensor there).
Drivers: ``snap7``, python-snap7's Client (``iso_exchange_buffer``, ``db_read``, ``read_area``), and
``raw``, a load generator that sends the very same request frames from pre-built bytes over a plain
socket and reads the answers. python-snap7's Client is pure Python and, on a small machine, the client
processes take most of the CPU; the raw driver leaves the CPU to the server under test.
The anchors: python-snap7 3.3's Server (it answers the NCK read with DB1 bytes, ignoring the syntax
ID, so it does the same amount of work per request) and the native snap7 server from the npm package
node-snap7 (installed into ``--cache``; S7ANY loads only: it does not serve NCK items). Where node or
npm is missing, or the native build fails, the native anchor is skipped with one line.
With ``--idle N`` every server is measured again at the largest client count with N further
connections open (COTP connected, setup communication done) and idle: the cost per request must
not grow with them.
Each point also reports the CPU time per request of the server process and of the client processes
together, and, for loads with more client processes than cores, the throughput the cores allow at
that CPU cost: it shows when the clients, not the server, set the pace.

Usage: .venv/bin/python bench/bench_server.py [--seconds 3] [--clients 1 8] [--drivers snap7 raw]
                                              [--loads nck db piw] [--idle 256] [--floor]
                                              [--rounds 3]
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
PIW_BYTE = 420
NCK_READ_PDU = bytes.fromhex("32010000000100 0c 0000 04 01 12088264AB7C00011601".replace(" ", ""))
ANCHOR_SCRIPT = """
import sys, time, snap7
from snap7.type import SrvArea
server = snap7.server.Server(log=False, max_clients=1024)
db = bytearray(64)
server.register_area(SrvArea.DB, 1, db)
server.register_area(SrvArea.DB, 130, bytearray(64))
server.register_area(SrvArea.PE, 0, bytearray(2048))
server.start(tcp_port=int(sys.argv[1]))
print("ready", flush=True)
while True:
    time.sleep(1)
"""

NATIVE_SCRIPT = """
const s7 = require(process.argv[1]);
const server = new s7.S7Server();
server.SetParam(server.LocalPort, parseInt(process.argv[2]));
server.SetParam(server.MaxClients, 1024);
server.SetEventMask(0);
server.RegisterArea(server.srvAreaDB, 1, Buffer.alloc(64));
server.RegisterArea(server.srvAreaDB, 130, Buffer.alloc(64));
server.RegisterArea(server.srvAreaPE, Buffer.alloc(2048));
if (server.StartTo("127.0.0.1") === false) { console.error(server.ErrorText(server.LastError())); process.exit(1); }
setInterval(() => {}, 1 << 30);
"""
# The floor of a Python server on uvloop: each read job seen before is answered with the bytes
# answered to it the first time, its PDU reference put in; the first sight of a job and the
# connection's handshake go through nckemu's session. What is left is the event loop, the
# protocol callback and the socket calls: what no pure-Python server can go below.
FLOOR_SCRIPT = """
import asyncio, sys, uvloop
from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.faces.s7.session import ServerSession
emulator = Emulator()

class Floor(asyncio.BufferedProtocol):
    def __init__(self):
        self.buffer = bytearray(4096)
        self.view = memoryview(self.buffer)
        self.session = ServerSession(Dispatcher.for_machine(emulator))
        self.answers = {}

    def connection_made(self, transport):
        self.transport = transport

    def get_buffer(self, sizehint):
        return self.buffer

    def buffer_updated(self, nbytes):
        data = bytes(self.view[:nbytes])
        known = self.answers.get(data[13:])
        if known is not None and data.startswith(known[0]):
            self.transport.write(known[1] + data[11:13] + known[2])
            return
        out = self.session.receive(data)
        if len(out) == 1 and len(data) > 17 and data[7] == 0x32 and data[8] == 1 and data[17] == 4:
            self.answers[data[13:]] = (data[:11], out[0][:11], out[0][13:])
        for frame in out:
            self.transport.write(frame)

async def main():
    server = await asyncio.get_running_loop().create_server(Floor, "127.0.0.1", int(sys.argv[1]))
    print("ready", flush=True)
    await server.serve_forever()

uvloop.run(main())
"""
DEFAULT_CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "nckemu-bench"


def native_snap7(cache: Path) -> tuple[Path | None, str]:
    """The node-snap7 package directory (installed into ``cache`` by npm on first use), or None and why."""
    import shutil

    if shutil.which("node") is None or shutil.which("npm") is None:
        return None, "node or npm is not installed"
    package = cache / "node_modules" / "node-snap7"
    if not (package / "package.json").exists():
        print(f"installing node-snap7 (the native snap7 anchor) into {cache} ...", file=sys.stderr, flush=True)
        cache.mkdir(parents=True, exist_ok=True)
        done = subprocess.run(["npm", "install", "--prefix", str(cache), "node-snap7"], capture_output=True,
                              text=True, check=False)
        if done.returncode != 0:
            return None, f"npm install node-snap7 failed: {done.stderr.strip().splitlines()[-1:]}"
    check = subprocess.run(["node", "-e", "const s7 = require(process.argv[1]); new s7.S7Server();", str(package)],
                           capture_output=True, text=True, check=False)
    if check.returncode != 0:
        return None, f"node-snap7 does not load (native build missing?): {check.stderr.strip().splitlines()[-1:]}"
    return package, ""


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
    return subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", str(port),
                             "--max-connections", "1024"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=REPO)


def start_anchor(port: int) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-c", ANCHOR_SCRIPT, str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def start_floor(port: int) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-c", FLOOR_SCRIPT, str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=REPO)


def start_native(package: Path, port: int) -> subprocess.Popen[bytes]:
    return subprocess.Popen(["node", "-e", NATIVE_SCRIPT, str(package), str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def open_idle(port: int, count: int, db: int) -> list[socket.socket]:
    """``count`` connections that connect (COTP), set up communication and then stay idle."""
    connect, setup, _request = _raw_frames("db", db)
    sockets = []
    for _ in range(count):
        sock = socket.create_connection(("127.0.0.1", port))
        for frame in (connect, setup):
            sock.sendall(frame)
            _receive_frame(sock)
        sockets.append(sock)
    return sockets


def client_worker(port: int, load: str, seconds: float, db: int, out: mp.Queue,  # type: ignore[type-arg]
                  start: Any) -> None:
    import logging

    import snap7
    from snap7.type import Area

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
        elif load == "piw":
            client.read_area(Area.PE, 0, PIW_BYTE, 2)
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
        item = S7AnyAddress(transport_size=0x02, count=4, db_number=db, area=0x84, byte_address=0) \
            if load == "db" else S7AnyAddress(transport_size=0x02, count=2, db_number=0, area=0x81,
                                              byte_address=PIW_BYTE)
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


def percentile(values: list[float], fraction: float) -> float:
    """The value below which ``fraction`` of ``values`` lie (nearest rank); NaN for none."""
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(fraction * len(ordered)))]


def process_figures(pid: int) -> tuple[int, int]:
    """Resident set in KiB and open descriptors of a process (Linux /proc)."""
    rss = 0
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            rss = int(line.split()[1])
    return rss, len(os.listdir(f"/proc/{pid}/fd"))


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
    parser.add_argument("--loads", nargs="+", choices=("nck", "db", "piw"), default=["nck", "db", "piw"])
    parser.add_argument("--idle", type=int, default=256,
                        help="idle connections held open for the extra rows at the largest client count (0: none)")
    parser.add_argument("--cache", type=Path, default=DEFAULT_CACHE, help="where npm installs node-snap7")
    parser.add_argument("--rounds", type=int, default=3,
                        help="measure every point this many times, the servers in turn (medians reported)")
    parser.add_argument("--floor", action="store_true",
                        help="also measure the floor of a Python server on uvloop (canned answers)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    package, why = native_snap7(args.cache)
    if package is None:
        print(f"native snap7 anchor skipped: {why}", flush=True)
    servers: list[tuple[str, Any, int]] = [("python-snap7 Server", start_anchor, 1)]
    if package is not None:
        servers.append(("native snap7", lambda port: start_native(package, port), 130))
    servers.append(("nckemu", start_nckemu, 130))
    if args.floor:
        servers.append(("uvloop floor", start_floor, 130))
    # Every server runs for the whole bench and each point measures them one after the other, in an
    # order that turns each round: the speed of a small shared machine drifts over minutes, and
    # measuring one server after another would put that drift into the ratios.
    running: list[tuple[str, int, subprocess.Popen[bytes], int]] = []
    try:
        for name, starter, db in servers:
            port = free_port()
            running.append((name, port, starter(port), db))
        for _name, port, _process, _db in running:
            wait_port(port)
        rounds: list[list[dict[str, Any]]] = []
        for round_index in range(args.rounds):
            turn = round_index % len(running)
            order_this_round = running[turn:] + running[:turn]
            results: list[dict[str, Any]] = []
            for driver in args.drivers:
                for load in args.loads:
                    points = [(clients, 0) for clients in args.clients]
                    if args.idle:
                        points.append((max(args.clients), args.idle))
                    for clients, idle_count in points:
                        for name, port, process, db in order_this_round:
                            if load == "nck" and name == "native snap7":
                                continue  # it does not serve NCK items
                            idle = open_idle(port, idle_count, db) if idle_count else []
                            try:
                                figures = measure(port, load, clients, args.seconds, db, driver, process.pid)
                            finally:
                                for sock in idle:
                                    sock.close()
                            results.append({"server": name, "driver": driver, "load": load, "clients": clients,
                                            "idle": idle_count, **figures})
            rounds.append(results)
    finally:
        for _name, _port, process, _db in running:
            process.terminate()
            process.wait(timeout=10)
    if args.json:
        print(json.dumps(rounds, indent=2))
        return 0

    point_keys = ("driver", "load", "clients", "idle")

    def same_point(a: dict[str, Any], b: dict[str, Any]) -> bool:
        return all(a[k] == b[k] for k in point_keys)

    def ratios(server: str, anchor_name: str, r: dict[str, Any]) -> list[float]:
        """Per round: the server's throughput over the anchor's at the same point."""
        out = []
        for results in rounds:
            mine = [a for a in results if a["server"] == server and same_point(a, r)]
            theirs = [a for a in results if a["server"] == anchor_name and same_point(a, r)]
            if mine and theirs:
                out.append(mine[0]["requests_per_s"] / theirs[0]["requests_per_s"])
        return out

    def median_of(server: str, r: dict[str, Any], key: str) -> float | None:
        values = [a[key] for results in rounds for a in results
                  if a["server"] == server and same_point(a, r) and key in a]
        return statistics.median(values) if values else None

    def ratio_text(server: str, anchor_name: str, r: dict[str, Any]) -> str:
        values = ratios(server, anchor_name, r)
        if not values:
            return f"{'-':>16}"
        spread = f"({min(values):.2f}-{max(values):.2f})" if len(values) > 1 else ""
        return f"{statistics.median(values):>5.2f} {spread:>10}"

    cores = os.cpu_count() or 1
    print(f"machine: {cores} cores; {args.seconds:g} s per point, {args.rounds} rounds, servers in turn at each "
          "point; medians over the rounds; CPU in microseconds per request (server process; all client "
          "processes together); x py / x nat: throughput over python-snap7's Server / the native snap7 "
          "server at the same point and round, median (least-most)")
    print(f"{'server':20} {'driver':6} {'load':5} {'clients':>7} {'idle':>5} {'req/s':>9} {'p50 ms':>8} "
          f"{'p99 ms':>8} {'x py':>16} {'x nat':>16} {'srv CPU':>8} {'cli CPU':>8}")
    order = {name: index for index, (name, _s, _d) in enumerate(servers)}
    summary: list[dict[str, Any]] = []
    for r in sorted(rounds[0], key=lambda r: (r["driver"], r["load"], r["clients"], r["idle"], order[r["server"]])):
        name = r["server"]
        figures = {key: median_of(name, r, key)
                   for key in ("requests_per_s", "p50_ms", "p99_ms", "server_cpu_us", "client_cpu_us")}
        summary.append({**{k: r[k] for k in ("server", *point_keys)}, **figures})
        server_cpu = f"{figures['server_cpu_us']:8.1f}" if figures["server_cpu_us"] is not None else f"{'?':>8}"
        print(f"{name:20} {r['driver']:6} {r['load']:5} {r['clients']:>7} {r['idle']:>5} "
              f"{figures['requests_per_s']:>9.0f} {figures['p50_ms']:>8.3f} {figures['p99_ms']:>8.3f} "
              f"{ratio_text(name, 'python-snap7 Server', r)} {ratio_text(name, 'native snap7', r)} "
              f"{server_cpu} {figures['client_cpu_us']:8.1f}")
    for r in summary:
        if r["server"] == "nckemu" and r["clients"] > cores and r["server_cpu_us"] is not None:
            bound = cores * 1e6 / (r["server_cpu_us"] + r["client_cpu_us"])
            print(f"{r['driver']} {r['load']} x{r['clients']} idle {r['idle']}: {cores} cores allow at most "
                  f"{bound:,.0f} req/s at this CPU per request (nckemu {r['server_cpu_us']:.1f} us + clients "
                  f"{r['client_cpu_us']:.1f} us); measured {r['requests_per_s']:,.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
