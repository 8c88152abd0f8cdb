"""Load and consistency: N client processes write and read disjoint and shared NCK variables and DB
areas at once; afterwards every last write is there and no REAL8 was ever seen torn.

Each process w owns R parameter w and DB100 bytes 4w..4w+3; all of them also write R99.
A value written is w * 1e6 + i + 0.123456789 (the fraction makes a torn double almost surely not a
written value). Usage: .venv/bin/python bench/load_consistency.py [--clients 64] [--ops 100000]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import socket
import struct
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

SHARED = "R99"  # every process also writes this one
FRACTION = 0.123456789


def value_of(worker: int, index: int) -> float:
    return worker * 1e6 + index + FRACTION


def decodes_to_a_write(value: float, workers: int, ops: int) -> bool:
    if value == 0.0:
        return True
    worker, rest = divmod(value - FRACTION, 1e6)
    return 0 <= worker < workers and abs(rest - round(rest)) < 1e-6 and 0 <= round(rest) < ops


def worker(port: int, number: int, workers: int, ops: int, out: mp.Queue) -> None:  # type: ignore[type-arg]
    import logging

    from nckemu.clients import NckClient

    logging.disable(logging.CRITICAL)
    torn = 0
    last_shared = None
    with NckClient("127.0.0.1", port, timeout_s=30) as client:
        for index in range(ops):
            value = value_of(number, index)
            client.put({f"R{number}": value, SHARED: value})
            client.db_write(100, 4 * number, struct.pack(">I", index))
            last_shared = value
            own, shared = client.get(f"R{number}", SHARED)
            if own != value or not decodes_to_a_write(shared, workers, ops):
                torn += 1
            if struct.unpack(">I", client.db_read(100, 4 * number, 4))[0] != index:
                torn += 1
    out.put((number, torn, last_shared, time.time()))


def run_load(port: int, clients: int, ops: int) -> dict[str, float]:
    from nckemu.clients import NckClient

    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    started = time.perf_counter()
    processes = [ctx.Process(target=worker, args=(port, w, clients, ops, queue)) for w in range(clients)]
    for process in processes:
        process.start()
    results = [queue.get(timeout=600 + ops) for _ in processes]
    for process in processes:
        process.join()
    elapsed_s = time.perf_counter() - started
    lost = 0
    with NckClient("127.0.0.1", port) as client:
        for number, _torn, _last, _t in results:
            if client.get(f"R{number}") != [value_of(number, ops - 1)]:
                lost += 1
            if struct.unpack(">I", client.db_read(100, 4 * number, 4))[0] != ops - 1:
                lost += 1
        (shared,) = client.get(SHARED)
    last_writer = max(results, key=lambda r: r[3])
    return {"clients": clients, "operations": clients * ops * 6, "seconds": elapsed_s,
            "torn": sum(r[1] for r in results), "lost": lost,
            "shared_is_a_last_write": float(shared in {r[2] for r in results}),
            "shared_from_last_finisher": float(shared == last_writer[2])}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clients", type=int, default=64)
    parser.add_argument("--ops", type=int, default=100_000, help="write/read rounds per client")
    args = parser.parse_args()
    import subprocess

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", str(port),
                               "--max-connections", str(args.clients + 8)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        from bench.bench_server import wait_port

        wait_port(port)
        result = run_load(port, args.clients, args.ops)
    finally:
        server.terminate()
        server.wait(timeout=10)
    print(f"{result['clients']} clients, {result['operations']:,.0f} operations in {result['seconds']:.1f} s: "
          f"{result['lost']:.0f} lost, {result['torn']:.0f} torn, shared value is a last write: "
          f"{bool(result['shared_is_a_last_write'])}")
    return 0 if not result["lost"] and not result["torn"] and result["shared_is_a_last_write"] else 1


if __name__ == "__main__":
    sys.exit(main())
