"""kill -9 cycles: a write burst against a server with --state, SIGKILL in the middle, restart; every
acknowledged write must be there after the restart.

Usage: .venv/bin/python bench/soak_kill9.py [--cycles 20]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from nckemu.clients import NckClient  # noqa: E402
from nckemu.errors import NckError  # noqa: E402


def serve(port: int, state: Path) -> subprocess.Popen[str]:
    process = subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", str(port), "--state", str(state),
                                "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert process.stdout is not None
    if not process.stdout.readline():
        raise RuntimeError(process.stderr.read() if process.stderr else "server did not start")
    return process


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cycles", type=int, default=20)
    parser.add_argument("--burst-s", type=float, default=0.5)
    args = parser.parse_args()
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    lost = 0
    acknowledged_total = 0
    write_times: list[float] = []
    with tempfile.TemporaryDirectory() as scratch:
        state = Path(scratch) / "state.json"
        counter = 0
        for cycle in range(args.cycles):
            server = serve(port, state)
            with NckClient("127.0.0.1", port, timeout_s=2) as client:
                (before,) = client.get("R1")
                if before < counter:
                    lost += 1
                    print(f"cycle {cycle}: R1 = {before}, but {counter} was acknowledged")
                killer = threading.Timer(args.burst_s * (0.5 + (cycle % 5) / 10), os.kill, (server.pid, signal.SIGKILL))
                killer.start()
                try:
                    while True:
                        started = time.perf_counter()
                        client.put({"R1": float(counter + 1)})
                        write_times.append(time.perf_counter() - started)
                        counter += 1
                        acknowledged_total += 1
                except NckError:
                    pass
                killer.join()
            server.wait(timeout=10)
        server = serve(port, state)
        with NckClient("127.0.0.1", port) as client:
            (final,) = client.get("R1")
        server.send_signal(signal.SIGINT)
        server.wait(timeout=10)
        if final < counter:
            lost += 1
    write_times.sort()
    print(json.dumps({"cycles": args.cycles, "acknowledged_writes": acknowledged_total, "lost_cycles": lost,
                      "retained_write_p50_ms": round(1000 * write_times[len(write_times) // 2], 3),
                      "retained_write_p99_ms": round(1000 * write_times[int(0.99 * (len(write_times) - 1))], 3)}))
    return 1 if lost else 0


if __name__ == "__main__":
    sys.exit(main())
