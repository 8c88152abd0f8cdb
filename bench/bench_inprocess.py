"""In-process cost of one read job through ``ServerSession.receive``: no sockets, no event loop.

Loads (the frames python-snap7 sends):
* ``nck``: NCK REAL8, SD43900 of axis 4 (``iso_exchange_buffer``);
* ``db``: 4 bytes of DB130 (``db_read(130, 0, 4)``: S7ANY BYTE x4, area 0x84);
* ``piw``: 2 bytes at input byte 420 (``read_area(Area.PE, 0, 420, 2)``), wired to a sensor.

Wall-clock microseconds per job are noisy on a loaded machine; ``--callgrind`` counts the
instructions per job instead (valgrind; repeatable under load): the script runs itself under
callgrind at two loop lengths per load and prints the difference per job, which leaves out start-up.

Usage: .venv/bin/python bench/bench_inprocess.py [--jobs 40000] [--callgrind] [--loads nck db piw]
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from nckemu.emulator.faces.s7.dispatch import Dispatcher  # noqa: E402
from nckemu.emulator.faces.s7.session import ServerSession  # noqa: E402
from nckemu.emulator.machine.clock import SimulatedClock  # noqa: E402
from nckemu.emulator.machine.core import Emulator  # noqa: E402
from nckemu.protocol import cotp, s7  # noqa: E402

CR = bytes.fromhex("0300001611E00000000100C0010AC1020100C2020104")
ITEMS = {
    "nck": "12088264AB7C00011601",
    "db": "120A10020004008284000000",
    "piw": "120A10020002000081000D20",  # byte 420 = bit address 3360 = 0x000D20
}


def _frame(pdu: bytes) -> bytes:
    return cotp.build_data_frame(pdu)


def ready_session(emulator: Emulator) -> ServerSession:
    session = ServerSession(Dispatcher.for_machine(emulator))
    session.receive(CR)
    session.receive(_frame(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, 1, s7.build_setup_communication(
        s7.SetupCommunication(1, 1, 480))))))
    return session


def job_frame(load: str) -> bytes:
    parameter = bytes([4, 1]) + bytes.fromhex(ITEMS[load])
    return _frame(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, 2, parameter)))


def run(load: str, jobs: int, repeats: int) -> float:
    """Best microseconds per job over ``repeats`` loops of ``jobs``."""
    session = ready_session(Emulator(clock=SimulatedClock(100.0)))
    frame = job_frame(load)
    answer = session.receive(frame)
    if len(answer) != 1 or answer[0][21] != 0xFF:  # TPKT 4 + COTP 3 + ack header 12 + parameter 2
        raise RuntimeError(f"{load}: the read failed: {answer!r}")
    receive = session.receive
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(jobs):
            receive(frame)
        best = min(best, (time.perf_counter() - start) / jobs * 1e6)
    return best


def instructions(load: str, jobs: int) -> int:
    result = subprocess.run(
        ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", sys.executable, __file__,
         "--loads", load, "--jobs", str(jobs), "--repeats", "1", "--quiet"],
        capture_output=True, text=True, check=True)
    match = re.search(r"Collected : (\d+)", result.stderr)
    if match is None:
        raise RuntimeError(f"no callgrind count in: {result.stderr[-500:]}")
    return int(match.group(1))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--loads", nargs="+", choices=tuple(ITEMS), default=list(ITEMS))
    parser.add_argument("--jobs", type=int, default=40000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--callgrind", action="store_true", help="instructions per job (valgrind)")
    parser.add_argument("--quiet", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.callgrind:
        if shutil.which("valgrind") is None:
            print("valgrind not found: instruction counts skipped")
            return 0
        for load in args.loads:
            short, long = 1000, 3000
            per_job = (instructions(load, long) - instructions(load, short)) / (long - short)
            print(f"{load:4} {per_job:10,.0f} instructions per job (callgrind)")
        return 0
    for load in args.loads:
        us = run(load, args.jobs, args.repeats)
        if not args.quiet:
            print(f"{load:4} {us:8.2f} us per job (best of {args.repeats} x {args.jobs})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
