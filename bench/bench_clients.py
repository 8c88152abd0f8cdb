"""Client call rates against the emulator (served from another process): get/put per second, sync
and async, and the speed-up of 8 variables in one job over 8 jobs of one variable.

Usage: .venv/bin/python bench/bench_clients.py [--seconds 2]
"""

from __future__ import annotations

import argparse
import asyncio
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bench_server import free_port, wait_port  # noqa: E402
from nckemu.clients import AsyncNckClient, NckClient  # noqa: E402

EIGHT = [f"R{i}" for i in range(8)]


def rate(call, seconds: float) -> float:  # type: ignore[no-untyped-def]
    count, deadline = 0, time.perf_counter() + seconds
    while time.perf_counter() < deadline:
        call()
        count += 1
    return count / seconds


async def async_rate(call, seconds: float) -> float:  # type: ignore[no-untyped-def]
    count, deadline = 0, time.perf_counter() + seconds
    while time.perf_counter() < deadline:
        await call()
        count += 1
    return count / seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    port = free_port()
    server = subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", str(port)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_port(port)
        with NckClient("127.0.0.1", port) as nck:
            get_1 = rate(lambda: nck.get("SD43900[AX4]"), args.seconds)
            put_1 = rate(lambda: nck.put({"SD43900[AX4]": 0.1}), args.seconds)
            get_8 = rate(lambda: nck.get(*EIGHT), args.seconds)
            get_8_singly = rate(lambda: [nck.get(name) for name in EIGHT], args.seconds)

        async def async_figures() -> tuple[float, float]:
            async with AsyncNckClient("127.0.0.1", port) as client:
                return (await async_rate(lambda: client.get("SD43900[AX4]"), args.seconds),
                        await async_rate(lambda: client.put({"SD43900[AX4]": 0.1}), args.seconds))

        async_get, async_put = asyncio.run(async_figures())
    finally:
        server.terminate()
        server.wait(timeout=10)
    print(f"sync  get 1 variable : {get_1:8.0f} calls/s")
    print(f"sync  put 1 variable : {put_1:8.0f} calls/s")
    print(f"async get 1 variable : {async_get:8.0f} calls/s")
    print(f"async put 1 variable : {async_put:8.0f} calls/s")
    print(f"8 variables in 1 job : {get_8:8.0f} jobs/s = {8 * get_8:8.0f} variables/s")
    print(f"8 jobs of 1 variable : {get_8_singly:8.0f} rounds/s = {8 * get_8_singly:8.0f} variables/s")
    print(f"multi-variable speed-up: {get_8 / get_8_singly:.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
