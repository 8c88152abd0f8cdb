"""Hostile NC transfer telegrams through the sans-IO session: whatever the subfunctions, sequences,
data units and payloads, the session answers without an exception, keeps the connection, answers
every NC request, and the program store changes only by a whole, well-formed download."""

from __future__ import annotations

import struct

from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits
from nckemu.emulator.machine.core import Emulator
from nckemu.protocol import ncprog, s7
from tests.emulator.faces.s7.test_session import connected, dt, s7_of

OLD = b"G0 X0\nM30\n"
PATH = "/_N_MPF_DIR/_N_TEST_MPF"


def _userdata(pdu_ref: int, parameter: bytes, data: bytes) -> bytes:
    return struct.pack(">BBHHHH", 0x32, 7, 0, pdu_ref, len(parameter), len(data)) + parameter + data


TELEGRAMS = st.builds(
    lambda kind, sub, seq, long, ref, last, payload, raw_data: (
        ncprog.build_nc_parameter(ncprog.NcParameter(kind, sub, seq, long, ref if long else 0,
                                                     last if long else 0)),
        raw_data if raw_data is not None else ncprog.build_nc_data(ncprog.NcData(payload))),
    st.sampled_from(sorted(ncprog.NC_TYPES)), st.integers(0, 10), st.integers(0, 3), st.booleans(),
    st.integers(0, 255), st.integers(0, 2),
    st.one_of(st.binary(max_size=60), st.sampled_from([b"_N_TEST_MPF", b"\x14\x00_N_TEST_MPF", b"\x08\x00",
                                                       b"\x00\xFB00000010" + b" " * 16 + b";$PATH=/\n"])),
    st.none() | st.binary(max_size=12))


@settings(max_examples=150, deadline=None)
@given(st.lists(TELEGRAMS, max_size=25))
def test_hostile_transfers_never_break_the_session_or_the_store(telegrams: list[tuple[bytes, bytes]]) -> None:
    emulator = Emulator()
    emulator.nck.programs.write(PATH, OLD)
    before = dict(emulator.nck.programs.texts)
    session = connected(ServerSession(Dispatcher.for_machine(emulator), limits=SessionLimits()))
    stored = False
    for index, (parameter, data) in enumerate(telegrams):
        answers = session.receive(dt(_userdata(index + 2, parameter, data)))
        assert not session.closed
        for frame in answers:
            pdu = s7.parse_pdu(s7_of(frame))  # every answer is a well-formed PDU
            if ncprog.is_nc_parameter(pdu.parameter):
                answer = ncprog.parse_nc_parameter(pdu.parameter)
                stored |= answer.subfunction == ncprog.NcSubfunction.DOWNLOAD_ENDED and not answer.error_code
        if parameter[5] == ncprog.NC_REQUEST and len(data) >= 4:
            assert answers, "an NC request is always answered"
    if not stored:  # nothing accepted at "download ended": nothing changed
        assert emulator.nck.programs.texts == before
    # and the session still serves a read afterwards
    read = struct.pack(">BBHHHH", 0x32, 1, 0, 99, 14, 0) + bytes.fromhex("0401120A10020001000184000000")
    (answer,) = session.receive(dt(read))
    assert s7_of(answer)[1] == 3
