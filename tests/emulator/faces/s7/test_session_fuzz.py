"""Fuzzing the whole input path in-process: TPKT -> COTP -> S7 -> items -> NCK model.

Contract: every input gets protocol answers or a clean close, no exception escapes the session,
memory stays bounded, and the model stays consistent (a fresh connection reads what the model holds).
"""

from __future__ import annotations

import logging
import struct

from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.protocol import pi, s7, szl
from nckemu.protocol.addresses import NckAddress, S7AnyAddress

CR = bytes.fromhex("0300001611E00000000100C0010AC1020100C2020104")
SETUP = bytes.fromhex("32010000000100080000F0000008000803C0")
SENTINEL = NckAddress(3, 1, 43900, 1, 0x16)  # SD43900 of axis 1
LIMITS = SessionLimits(max_frame_bytes=4096, max_reassembly_bytes=8192, max_buffer_bytes=4100)


def dt(pdu: bytes, eot: bool = True) -> bytes:
    return struct.pack(">BBH", 3, 0, 7 + len(pdu)) + bytes([2, 0xF0, 0x80 if eot else 0]) + pdu


def pdu(ref: int, parameter: bytes, data: bytes = b"", rosctr: int = 1) -> bytes:
    return s7.build_pdu(s7.S7Pdu(rosctr, ref, parameter, data))


VALID_JOBS = [
    pdu(2, s7.build_read_var_request(s7.ReadVarRequest((NckAddress(3, 4, 43900, 1, 0x16),
                                                        NckAddress(2, 1, 1, 1, 0x15, 10))))),
    pdu(3, *s7.build_write_var_request(s7.WriteVarRequest(
        (NckAddress(2, 1, 1, 2, 0x15), S7AnyAddress(2, 4, 100, 0x84, 0)),
        (s7.DataItem(0, 9, struct.pack("<d", 1.5)), s7.DataItem(0, 4, b"\x01\x02\x03\x04"))))),
    pdu(4, pi.build_pi_request(pi.PiServiceRequest("_N_SELECT", ("201", "/_N_MPF_DIR/_N_TEST_MPF")))),
    pdu(5, *szl.build_szl_request(szl.SzlReadRequest(0x001C, 0)), rosctr=7),
    pdu(6, s7.build_read_var_request(s7.ReadVarRequest((S7AnyAddress(1, 1, 100, 0x84, 3, 2),)))),
]


@st.composite
def mutated_streams(draw: st.DrawFn) -> list[bytes]:
    jobs = draw(st.lists(st.sampled_from(VALID_JOBS), min_size=1, max_size=6))
    frames = [CR, dt(SETUP)] + [dt(j) for j in jobs]
    stream = bytearray(b"".join(frames))
    for _ in range(draw(st.integers(0, 6))):
        kind = draw(st.sampled_from(["flip", "truncate", "insert", "length", "huge", "count", "function"]))
        if not stream:
            break
        position = draw(st.integers(0, len(stream) - 1))
        if kind == "flip":
            stream[position] ^= draw(st.integers(1, 255))
        elif kind == "truncate":
            del stream[position:]
        elif kind == "insert":
            stream[position:position] = draw(st.binary(min_size=1, max_size=16))
        elif kind in ("length", "huge") and position + 1 < len(stream):
            value = 0xFFFF if kind == "huge" else draw(st.integers(0, 0xFFFF))
            stream[position:position + 2] = struct.pack(">H", value)
        elif kind == "count":
            stream[position] = draw(st.sampled_from([0, 1, 2, 0x7F, 0xFF]))
        elif kind == "function":
            stream[position] = draw(st.sampled_from([0x00, 0x1A, 0x1D, 0x28, 0x29, 0xF0, 0xB0, 0xA2, 0x83]))
    cuts = sorted(draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    chunks, start = [], 0
    for cut in cuts + [len(stream)]:
        chunks.append(bytes(stream[start:cut]))
        start = cut
    return chunks


def _answers_are_frames(answers: list[bytes]) -> None:
    for answer in answers:
        assert answer[:2] == b"\x03\x00" and struct.unpack(">H", answer[2:4])[0] == len(answer)


class _Errors(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@given(chunks=mutated_streams())
def test_fuzzed_streams_get_answers_or_a_clean_close(chunks: list[bytes]) -> None:
    errors = _Errors()
    logging.getLogger("nckemu").addHandler(errors)
    try:
        _fuzz(chunks)
    finally:
        logging.getLogger("nckemu").removeHandler(errors)
    # An exception the session had to catch is a bug even though the client got an answer.
    assert not errors.records, [r.getMessage() for r in errors.records]


def _fuzz(chunks: list[bytes]) -> None:
    emulator = Emulator()
    emulator.nck.write(SENTINEL, [0.125], AccessContext(level=0))
    session = ServerSession(Dispatcher.for_machine(emulator), limits=LIMITS, peer="fuzz")
    for chunk in chunks:
        _answers_are_frames(session.receive(chunk))  # nothing may escape
        assert len(session._buffer) <= LIMITS.max_buffer_bytes
    # Other connections see a consistent model: a fresh session reads what the model holds.
    fresh = ServerSession(Dispatcher.for_machine(emulator), limits=LIMITS)
    fresh.receive(CR)
    fresh.receive(dt(SETUP))
    (answer,) = fresh.receive(dt(pdu(9, s7.build_read_var_request(s7.ReadVarRequest((SENTINEL,))))))
    value = struct.unpack("<d", answer[-8:])[0]
    assert value == emulator.nck.read(SENTINEL, AccessContext(level=0))[0]
    if not session.closed and not session.has_partial_frame and session.state.value == "ready":
        (again,) = session.receive(dt(pdu(10, s7.build_read_var_request(s7.ReadVarRequest((SENTINEL,))))))
        assert struct.unpack("<d", again[-8:])[0] == value


@given(st.binary(max_size=400), st.integers(1, 50))
def test_random_bytes_after_a_valid_connect(garbage: bytes, chunk: int) -> None:
    session = ServerSession(Dispatcher.for_machine(Emulator()), limits=LIMITS)
    session.receive(CR + dt(SETUP))
    for start in range(0, len(garbage), chunk):
        _answers_are_frames(session.receive(garbage[start:start + chunk]))
