"""Latency of a well-behaved client alone and while 10 hostile clients misbehave (p50/p99).

Hostile: 2 send one byte every 0.2 s, 2 flood jobs and never read, 2 send more jobs than the AMQ,
2 open and drop connections in a loop, 2 send garbage. Each runs in its own process.
Usage: .venv/bin/python bench/bench_hostile.py [--seconds 5]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bench_server import free_port, wait_port  # noqa: E402

CR = bytes.fromhex("0300001611E00000000100C0010AC1020100C2020104")
SETUP = bytes.fromhex("0300001902F08032010000000100080000F0000008000803C0")


def job(ref: int) -> bytes:
    parameter = bytes.fromhex("040112088241000100011564")
    pdu = struct.pack(">BBHHHH", 0x32, 1, 0, ref & 0xFFFF, len(parameter), 0) + parameter
    return struct.pack(">BBH", 3, 0, 7 + len(pdu)) + b"\x02\xf0\x80" + pdu


def hostile(kind: str, port: int, stop: mp.Event) -> None:  # type: ignore[valid-type]
    while not stop.is_set():  # type: ignore[attr-defined]
        try:
            sock = socket.create_connection(("127.0.0.1", port), timeout=2)
            if kind == "flood-connect":
                sock.close()
                continue
            if kind == "garbage":
                sock.sendall(os.urandom(200))
                sock.close()
                continue
            sock.sendall(CR + SETUP)
            time.sleep(0.05)
            if kind == "slow":
                for byte in job(1):
                    if stop.is_set():  # type: ignore[attr-defined]
                        break
                    sock.sendall(bytes([byte]))
                    time.sleep(0.2)
            elif kind == "never-read":
                sock.setblocking(False)
                while not stop.is_set():  # type: ignore[attr-defined]
                    try:
                        sock.send(b"".join(job(i) for i in range(50)))
                    except BlockingIOError:
                        time.sleep(0.05)
            elif kind == "amq":
                for _ in range(200):
                    sock.sendall(b"".join(job(i) for i in range(20)))
                    sock.recv(1 << 20)
            sock.close()
        except OSError:
            time.sleep(0.05)


def good_client(port: int, seconds: float) -> tuple[float, float, int]:
    from nckemu.clients import NckClient

    latencies = []
    with NckClient("127.0.0.1", port) as client:
        deadline = time.perf_counter() + seconds
        while time.perf_counter() < deadline:
            started = time.perf_counter()
            client.get("SD43900[AX4]")
            latencies.append(time.perf_counter() - started)
    latencies.sort()
    return 1000 * latencies[len(latencies) // 2], 1000 * latencies[int(0.99 * (len(latencies) - 1))], len(latencies)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--kinds", nargs="+", default=["slow", "slow", "never-read", "never-read", "amq", "amq",
                                                        "flood-connect", "flood-connect", "garbage", "garbage"])
    args = parser.parse_args()
    port = free_port()
    server = subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", str(port)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_port(port)
        alone = good_client(port, args.seconds)
        ctx = mp.get_context("spawn")
        stop = ctx.Event()
        processes = [ctx.Process(target=hostile, args=(kind, port, stop), daemon=True) for kind in args.kinds]
        for process in processes:
            process.start()
        time.sleep(1.0)
        attacked = good_client(port, args.seconds)
        stop.set()
        for process in processes:
            process.join(timeout=5)
            if process.is_alive():
                process.kill()
    finally:
        server.terminate()
        server.wait(timeout=10)
    print(f"good client alone      : p50 {alone[0]:.3f} ms  p99 {alone[1]:.3f} ms  ({alone[2]} reads)")
    print(f"next to {len(args.kinds)} hostile ones: p50 {attacked[0]:.3f} ms  p99 {attacked[1]:.3f} ms  ({attacked[2]} reads)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
