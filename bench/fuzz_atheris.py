"""Coverage-guided fuzzing of the session with atheris (libFuzzer): ``pip install -e '.[fuzz]'``, then
``.venv/bin/python bench/fuzz_atheris.py -runs=1000000`` (any libFuzzer flag works).

Each input is fed, in two chunks, to a fresh session that has already connected and set up
communication. An exception escaping ``receive`` or an error the session had to log is a crash.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

with atheris.instrument_imports():
    from nckemu.emulator.faces.s7.dispatch import Dispatcher
    from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits
    from nckemu.emulator.machine.core import Emulator
    from nckemu.protocol import s7

CR = bytes.fromhex("0300001611E00000000100C0010AC1020100C2020104")
SETUP = bytes.fromhex("0300001902F08032010000000100080000F0000008000803C0")
EMULATOR = Emulator()
LIMITS = SessionLimits(max_frame_bytes=4096, max_reassembly_bytes=8192, max_buffer_bytes=4100)


class _Fail(logging.Handler):
    def emit(self, record: logging.LogRecord) -> None:
        raise RuntimeError(f"the session caught an internal error: {record.getMessage()}")


logging.getLogger("nckemu").addHandler(_Fail(logging.ERROR))
logging.getLogger("nckemu").propagate = False


def one_input(data: bytes) -> None:
    session = ServerSession(Dispatcher.for_machine(EMULATOR), limits=LIMITS)
    session.receive(CR + SETUP)
    cut = data[0] if data else 0
    for chunk in (data[1:1 + cut], data[1 + cut:]):
        for frame in session.receive(chunk):
            assert frame[:2] == b"\x03\x00"
    assert s7.Rosctr.JOB == 1


if __name__ == "__main__":
    atheris.Setup(sys.argv, one_input)
    atheris.Fuzz()
