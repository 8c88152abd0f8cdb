"""A client that floods a server, for the spawned processes of the fairness test: kept apart from the test
file so that a spawned process imports the client alone (the test file's imports made each take seconds
to start flooding)."""

from __future__ import annotations

import time
from typing import Any

from nckemu.clients import NckClient


def flood(port: int, seconds: float, out: Any, flooding: Any, stop: Any) -> None:
    """S7 jobs without a pause from the first one on (then says so on ``flooding``) until ``stop`` is set
    or ``seconds`` pass; how many it sent goes to ``out``."""
    done = 0
    deadline = time.monotonic() + seconds
    with NckClient("127.0.0.1", port, timeout_s=10) as client:
        while time.monotonic() < deadline and not stop.is_set():
            client.get("R1", "R2", "SD43900[AX4]")
            client.db_write(100, 0, b"\x01\x02")
            if done == 0:
                flooding.put(True)
            done += 2
    out.put(done)
