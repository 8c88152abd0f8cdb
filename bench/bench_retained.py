"""Retained writes with ``--state``: saved on the event loop, one fsync each (as before issue 34's
group saves), against saved off the loop, many writes to one save (``emulator/machine/saves.py``).

In one process and one run, for each way: a server with a state file in a temporary directory (on
this machine's disk), W writer connections putting R parameters as fast as they are acknowledged,
and one reader connection polling a setting datum. Printed: acknowledged writes per second, the
reader's p50/p99/max, the saves done, and the ratios of the two ways.

Usage: .venv/bin/python bench/bench_retained.py [--writers 16] [--seconds 10] [--json]
Loopback only.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bench_server import percentile  # noqa: E402
from nckemu.clients.async_client import AsyncNckClient  # noqa: E402
from nckemu.emulator.faces.s7.server import EmulatorServer  # noqa: E402
from nckemu.emulator.machine.core import Emulator  # noqa: E402


def percentile_ms(values: list[float], fraction: float) -> float:
    return round(1000 * percentile(values, fraction), 2)


async def one_way(on_the_loop: bool, writers: int, seconds: float) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(dir=Path.home()) as scratch:  # the home disk, not a tmpfs
        emulator = Emulator(state_path=Path(scratch) / "state.json")
        server = await EmulatorServer(emulator, port=0).start()
        if on_the_loop:
            server.dispatcher.persist_later = None  # every write saves before it answers, on the loop
        deadline = time.perf_counter() + seconds
        acknowledged = 0
        reads: list[float] = []

        async def writer(number: int) -> None:
            nonlocal acknowledged
            async with AsyncNckClient("127.0.0.1", server.port) as nck:
                step = 0
                while time.perf_counter() < deadline:
                    step += 1
                    await nck.put({f"R{number}": step + 0.5})
                    acknowledged += 1

        async def reader() -> None:
            async with AsyncNckClient("127.0.0.1", server.port) as nck:
                while time.perf_counter() < deadline:
                    asked = time.perf_counter()
                    await nck.get("SD43900[AX4]")
                    reads.append(time.perf_counter() - asked)

        try:
            await asyncio.gather(reader(), *(writer(n) for n in range(writers)))
        finally:
            await server.stop()
    return {"way": "on the loop, one save per write" if on_the_loop else "off the loop, grouped",
            "writes_per_s": round(acknowledged / seconds, 1), "saves": emulator.saves.saves if not on_the_loop
            else acknowledged, "reader_p50_ms": percentile_ms(reads, 0.5), "reader_p99_ms": percentile_ms(reads, 0.99),
            "reader_max_ms": round(1000 * max(reads, default=float("nan")), 1), "reads": len(reads)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--writers", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    before = asyncio.run(one_way(True, args.writers, args.seconds))
    after = asyncio.run(one_way(False, args.writers, args.seconds))
    ratios = {"writes_per_s": round(after["writes_per_s"] / max(before["writes_per_s"], 1e-9), 2),
              "reader_p99": round(after["reader_p99_ms"] / max(before["reader_p99_ms"], 1e-9), 3)}
    if args.json:
        print(json.dumps({"on_the_loop": before, "grouped": after, "ratio_grouped_to_on_the_loop": ratios}))
    else:
        for result in (before, after):
            print(f"{result['way']:<34} {result['writes_per_s']:>8} writes/s  {result['saves']:>6} saves  "
                  f"reader p50 {result['reader_p50_ms']} ms, p99 {result['reader_p99_ms']} ms, "
                  f"max {result['reader_max_ms']} ms ({result['reads']} reads)")
        print(f"grouped / on the loop: {ratios['writes_per_s']} x the writes, {ratios['reader_p99']} x the reader's p99")
    return 0


if __name__ == "__main__":
    sys.exit(main())
