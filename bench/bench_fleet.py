"""``nckemu fleet``: memory for 1, 10 and 100 machines in one process, and read throughput spread over
100 machines against the same clients on one machine, same fleet process, same run.

Memory: the resident set (VmRSS) of ``nckemu fleet --count N`` after every machine has answered one
NCK read (each then holds a session's worth of state). The anchor, measured in the same run: one
``nckemu serve`` process, the cost per machine without a fleet (N machines = N such processes).
Target: 100 machines under 250 MB in all.

Throughput: 8 python-snap7 client processes, each with one connection to every 8th machine of a
100-machine fleet, reading SD43900[AX4] from its machines in turn; then the same 8 processes with the
same number of connections each, all to machine 1. The ratio says what spreading the load over many
machines (many listening sockets, many emulators) costs the one event loop.

OPC UA: the same fleet with an OPC UA face on each machine (``--opcua-base-port``), its RSS and the time
until every face listens, for ``--opcua`` machines (0 skips), against one ``nckemu serve --opcua``.

Usage: .venv/bin/python bench/bench_fleet.py [--counts 1 10 100] [--seconds 3] [--clients 8] [--opcua 5]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import random
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # run as a script from anywhere (make bench)

from bench.bench_server import NCK_READ_PDU, free_port, process_cpu_s, process_figures, wait_port  # noqa: E402

REPO = Path(__file__).resolve().parent.parent


def rss_mb(pid: int) -> float:
    return process_figures(pid)[0] / 1024


def free_range(count: int) -> int:
    """A base port with ``count`` free ports from it on."""
    for _ in range(200):
        base = random.randrange(20000, 60000 - count)
        sockets = []
        try:
            for port in range(base, base + count):
                sock = socket.socket()
                sockets.append(sock)
                sock.bind(("127.0.0.1", port))
            return base
        except OSError:
            continue
        finally:
            for sock in sockets:
                sock.close()
    raise RuntimeError(f"no {count} consecutive free ports")


def start_fleet(count: int, base: int, *extra: str) -> tuple[subprocess.Popen[str], list[int]]:
    process = subprocess.Popen([sys.executable, "-m", "nckemu", "fleet", "--count", str(count), "--base-port",
                                str(base), "--max-connections", "1024", "--json", *extra], cwd=REPO,
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    assert process.stdout is not None
    ready = json.loads(process.stdout.readline())
    return process, [machine["port"] for machine in ready["machines"]]


def touch(ports: list[int]) -> None:
    """One NCK read from every machine (python-snap7), so each has served a connection."""
    import snap7

    for port in ports:
        client = snap7.Client()
        client.connect("127.0.0.1", 0, 4, port)
        client.iso_exchange_buffer(bytearray(NCK_READ_PDU))
        client.disconnect()


def serve_rss_mb() -> float:
    port = free_port()
    process = subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", str(port)], cwd=REPO,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_port(port)
        touch([port])
        return rss_mb(process.pid)
    finally:
        process.terminate()
        process.wait()


def _opcua_fleet(count: int) -> tuple[float, float, float]:
    """RSS (MB) after one read from each machine, seconds to ready, and seconds from SIGTERM to exit of
    ``nckemu fleet --count N --opcua-base-port``."""
    base = free_range(2 * count)
    started = time.monotonic()
    process, ports = start_fleet(count, base, "--opcua-base-port", str(base + count))
    try:
        ready_s = time.monotonic() - started
        touch(ports)
        fleet_mb = rss_mb(process.pid)
    finally:
        signalled = time.monotonic()
        process.terminate()
        process.wait()
        stop_s = time.monotonic() - signalled
    return fleet_mb, ready_s, stop_s


def opcua_figures(count: int) -> dict[str, float]:
    """RSS, seconds to ready and to stop: a fleet of ``count`` machines with OPC UA faces, the same fleet
    of one machine (the figure per extra machine is the difference over count - 1, what `fleet --help`
    quotes), and one ``serve --opcua`` (the anchor)."""
    one_mb, _one_s, _ = _opcua_fleet(1)
    fleet_mb, fleet_s, stop_s = _opcua_fleet(count)
    port, ua_port = free_port(), free_port()
    started = time.monotonic()
    serve = subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", str(port), "--opcua", str(ua_port),
                              "--json"], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert serve.stdout is not None
        serve.stdout.readline()
        serve_s = time.monotonic() - started
        touch([port])
        serve_mb = rss_mb(serve.pid)
    finally:
        serve.terminate()
        serve.wait()
    return {"machines": count, "fleet_rss_mb": fleet_mb, "fleet_ready_s": fleet_s, "serve_rss_mb": serve_mb,
            "serve_ready_s": serve_s, "fleet_stop_s": stop_s, "one_machine_rss_mb": one_mb,
            "mb_per_extra_machine": (fleet_mb - one_mb) / max(1, count - 1)}


def reader(ports: list[int], seconds: float, out: Any, start: Any) -> None:
    import logging

    import snap7

    logging.disable(logging.CRITICAL)
    clients = []
    for port in ports:
        client = snap7.Client()
        client.connect("127.0.0.1", 0, 4, port)
        clients.append(client)
    request = bytearray(NCK_READ_PDU)
    start.wait()
    reads = 0
    deadline = time.perf_counter() + seconds
    while time.perf_counter() < deadline:
        for client in clients:
            client.iso_exchange_buffer(request)
        reads += len(clients)
    for client in clients:
        client.disconnect()
    out.put(reads)


def throughput(assignments: list[list[int]], seconds: float, server_pid: int) -> dict[str, float]:
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    start = ctx.Barrier(len(assignments) + 1)
    workers = [ctx.Process(target=reader, args=(ports, seconds, queue, start)) for ports in assignments]
    for worker in workers:
        worker.start()
    start.wait(timeout=120)
    cpu_before = process_cpu_s(server_pid) or 0.0
    reads = sum(queue.get(timeout=seconds + 60) for _ in workers)
    for worker in workers:
        worker.join()
    cpu_after = process_cpu_s(server_pid) or 0.0
    return {"reads_per_s": reads / seconds, "server_cpu_us_per_read": 1e6 * (cpu_after - cpu_before) / reads}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--counts", type=int, nargs="+", default=[1, 10, 100])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--clients", type=int, default=8)
    parser.add_argument("--opcua", type=int, default=20, help="machines of the OPC UA fleet (0: skip)")
    parser.add_argument("--opcua-only", action="store_true", help="only the OPC UA fleet (memory, start, stop)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    if args.opcua_only:
        ua = opcua_figures(args.opcua)
        print(json.dumps(ua) if args.json else _opcua_line(ua))
        return 0
    anchor = serve_rss_mb()
    memory = []
    for count in args.counts:
        process, ports = start_fleet(count, free_range(count))
        try:
            touch(ports)
            memory.append({"machines": count, "rss_mb": rss_mb(process.pid)})
        finally:
            process.terminate()
            process.wait()
    for row in memory:
        row["mb_per_machine_over_one"] = (row["rss_mb"] - memory[0]["rss_mb"]) / max(1, row["machines"] - 1)
        row["separate_serves_mb"] = anchor * row["machines"]

    count = max(args.counts)
    process, ports = start_fleet(count, free_range(count))
    try:
        spread = [ports[i::args.clients] for i in range(args.clients)]
        one = [[ports[0]] * len(assignment) for assignment in spread]
        fleet_rate = throughput(spread, args.seconds, process.pid)
        one_rate = throughput(one, args.seconds, process.pid)
    finally:
        process.terminate()
        process.wait()
    result = {"serve_rss_mb": anchor, "memory": memory, "machines": count, "clients": args.clients,
              "connections": sum(len(a) for a in spread), "spread": fleet_rate, "one_machine": one_rate,
              "ratio_spread_over_one": fleet_rate["reads_per_s"] / one_rate["reads_per_s"]}
    if args.opcua > 0:
        result["opcua"] = opcua_figures(args.opcua)
    if args.json:
        print(json.dumps(result))
        return 0
    print(f"anchor: one `nckemu serve` process, one machine: {anchor:.1f} MB RSS")
    print("machines  fleet RSS MB  MB/extra machine  as separate serves MB")
    for row in memory:
        print(f"{row['machines']:8d}  {row['rss_mb']:12.1f}  {row['mb_per_machine_over_one']:16.3f}  "
              f"{row['separate_serves_mb']:21.0f}")
    print(f"reads/s, {args.clients} python-snap7 processes, {result['connections']} connections: "
          f"spread over {count} machines {fleet_rate['reads_per_s']:.0f} "
          f"({fleet_rate['server_cpu_us_per_read']:.0f} us server CPU/read), all on one machine "
          f"{one_rate['reads_per_s']:.0f} ({one_rate['server_cpu_us_per_read']:.0f} us); "
          f"ratio {result['ratio_spread_over_one']:.2f}")
    if "opcua" in result:
        print(_opcua_line(result["opcua"]))
    return 0


def _opcua_line(ua: dict[str, float]) -> str:
    """The figures `fleet --help` quotes (MB per extra machine with OPC UA) and the stop after SIGTERM."""
    return (f"with an OPC UA face each: {ua['machines']:.0f} machines {ua['fleet_rss_mb']:.0f} MB RSS "
            f"(one machine {ua['one_machine_rss_mb']:.0f} MB: {ua['mb_per_extra_machine']:.1f} MB per extra machine), "
            f"ready in {ua['fleet_ready_s']:.1f} s, exits {ua['fleet_stop_s']:.2f} s after SIGTERM (target < 2 s); "
            f"anchor: one `serve --opcua` {ua['serve_rss_mb']:.0f} MB, ready in {ua['serve_ready_s']:.1f} s")


if __name__ == "__main__":
    sys.exit(main())
