"""Long fuzz run of the sans-IO session (the in-process input path): N mutated frames, counts crashes.

A crash is any exception escaping ``ServerSession.receive``; a hang is a receive call over 1 s.
The mutations are those of tests/emulator/faces/s7/test_session_fuzz.py, driven by ``random`` for speed.

Usage: .venv/bin/python bench/fuzz_session.py [--frames 1000000] [--seed 1]
"""

from __future__ import annotations

import argparse
import logging
import random
import struct
import sys
import time
import traceback
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits  # noqa: E402
from nckemu.emulator.machine.core import Emulator  # noqa: E402
from tests.emulator.faces.s7.test_session_fuzz import CR, SETUP, VALID_JOBS, dt  # noqa: E402


def mutate(rng: random.Random, frame: bytes) -> bytes:
    data = bytearray(frame)
    for _ in range(rng.randint(0, 4)):
        if not data:
            break
        position = rng.randrange(len(data))
        kind = rng.randrange(6)
        if kind == 0:
            data[position] ^= rng.randint(1, 255)
        elif kind == 1:
            del data[position:]
        elif kind == 2:
            data[position:position] = rng.randbytes(rng.randint(1, 16))
        elif kind == 3 and position + 1 < len(data):
            data[position:position + 2] = struct.pack(">H", rng.choice([0, 1, 7, 0xFFFF, rng.randint(0, 0xFFFF)]))
        elif kind == 4:
            data[position] = rng.choice([0, 1, 2, 0x7F, 0xFF])
        else:
            data[position] = rng.choice([0x00, 0x1A, 0x28, 0x29, 0xF0, 0xB0, 0xA2, 0x83, 0x12])
    return bytes(data)


class _ErrorCounter(logging.Handler):
    """Exceptions the session caught are bugs too: they are logged at ERROR by the session."""

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.count = 0
        self.first: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.count += 1
        if len(self.first) < 3:
            self.first.append(self.format(record))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    internal = _ErrorCounter()
    logging.getLogger("nckemu").addHandler(internal)
    logging.getLogger("nckemu").propagate = False
    emulator = Emulator()
    limits = SessionLimits(max_frame_bytes=4096, max_reassembly_bytes=8192, max_buffer_bytes=4100)
    crashes = hangs = sessions = closes = answers = 0
    started = time.perf_counter()
    frames = 0
    while frames < args.frames:
        session = ServerSession(Dispatcher.for_machine(emulator), limits=limits)
        sessions += 1
        session.receive(CR + dt(SETUP))
        for _ in range(rng.randint(1, 50)):
            frame = mutate(rng, dt(rng.choice(VALID_JOBS)))
            frames += 1
            call_started = time.perf_counter()
            try:
                answers += len(session.receive(frame))
            except Exception:
                crashes += 1
                if crashes <= 3:
                    traceback.print_exc()
            if time.perf_counter() - call_started > 1.0:
                hangs += 1
            if session.closed:
                closes += 1
                break
    elapsed_s = time.perf_counter() - started
    print(f"frames {frames}  sessions {sessions}  answers {answers}  closed {closes}  "
          f"crashes {crashes}  internal errors {internal.count}  hangs {hangs}  "
          f"{frames / elapsed_s:,.0f} frames/s  ({elapsed_s:.1f} s)")
    for text in internal.first:
        print(text)
    return 1 if crashes or hangs or internal.count else 0


if __name__ == "__main__":
    sys.exit(main())
