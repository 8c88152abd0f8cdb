"""The session answers a read job by a short path (no S7Pdu objects); it must answer exactly as the
general path does, for any items, valid or not, in any PDU size, byte for byte."""

from __future__ import annotations

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.protocol import cotp, s7
from nckemu.protocol.addresses import NckAddress, S7AnyAddress
from tests.protocol.test_codec_properties import addresses

CR = bytes.fromhex("0300001611E00000000100C0010AC1020100C2020104")
EMULATOR = Emulator(clock=SimulatedClock(100.0))
# Items that exist, so that answers carry values and not only item errors.
KNOWN = st.sampled_from([NckAddress(3, 4, 43900, 1, 0x16), NckAddress(2, 1, 1, 1, 0x15, 3),
                         NckAddress(0, 1, 5, 1, 0x7A), NckAddress(3, 1, 32750, 1, 0x1A),
                         S7AnyAddress(0x02, 4, 130, 0x84, 0), S7AnyAddress(0x01, 1, 130, 0x84, 3, 5),
                         S7AnyAddress(0x04, 3, 0, 0x83, 10), S7AnyAddress(0x02, 2, 0, 0x81, 0)])


def _ready(pdu_size: int, tpdu_size_code: int = 0x0A) -> ServerSession:
    session = ServerSession(Dispatcher.for_machine(EMULATOR), limits=SessionLimits(pdu_size_max=pdu_size, max_amq=8))
    session.receive(CR[:-9] + bytes([tpdu_size_code]) + CR[-8:])  # TPDU size 2 ** code
    setup = s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, 1, s7.build_setup_communication(
        s7.SetupCommunication(1, 1, pdu_size))))
    session.receive(cotp.build_data_frame(setup))
    return session


@settings(max_examples=300, deadline=None)
@given(items=st.lists(st.one_of(KNOWN, addresses), min_size=1, max_size=20), pdu_ref=st.integers(0, 0xFFFF),
       pdu_size=st.sampled_from([240, 480, 960]))
def test_fast_read_answers_as_the_general_path(items: list[object], pdu_ref: int, pdu_size: int) -> None:
    """The first sight of a job makes its plan, later ones (another PDU reference) answer from the
    plan kept by frame: both as the general path answers."""
    parameter = s7.build_read_var_request(s7.ReadVarRequest(tuple(items)))
    fast_session, general_session = _ready(pdu_size), _ready(pdu_size)
    for ref in (pdu_ref, pdu_ref ^ 0x5AA5, pdu_ref):
        job = s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, ref, parameter))
        fast = fast_session.receive(cotp.build_data_frame(job))
        general_answer = general_session._handle_pdu(job, over_amq=False)
        assert general_answer is not None
        assert fast == [cotp.build_data_frame(general_answer)]
        assert fast_session.info.jobs == general_session.info.jobs
        assert not fast_session.closed


# S7ANY items near what exists: DBs and their ends, the sensor word at input byte 420 and its
# neighbours, areas served or not, every transport size, counts that do and do not fit.
PLANNED = st.builds(
    S7AnyAddress,
    transport_size=st.sampled_from([0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x1C, 0x1D, 0x00, 0x13]),
    count=st.one_of(st.integers(0, 8), st.integers(0, 0xFFFF)),
    db_number=st.sampled_from([0, 41, 100, 130, 131, 999]),
    area=st.sampled_from([0x80, 0x81, 0x82, 0x83, 0x84, 0x85, 0x86, 0x1C]),
    byte_address=st.one_of(st.sampled_from([0, 1, 62, 63, 64, 254, 255, 256, 419, 420, 421, 2046, 2047, 2048]),
                           st.integers(0, 0x1FFFF)),
    bit_address=st.integers(0, 7),
)


@settings(max_examples=400, deadline=None)
@example(items=[S7AnyAddress(0x02, 0, 0, 0x80, 0), S7AnyAddress(0x08, 8190, 0, 0x80, 0),
                S7AnyAddress(0x08, 8191, 0, 0x80, 0)], pdu_ref=0, fill=b"\x00", temperature_C=0.0)  # > 64 KiB
@example(items=[S7AnyAddress(0x02, 0, 41, 0x84, 254)], pdu_ref=0, fill=b"\x00", temperature_C=0.0)  # empty, beyond
@given(items=st.lists(PLANNED, min_size=1, max_size=6), pdu_ref=st.integers(0, 0xFFFF),
       fill=st.binary(min_size=1, max_size=1), temperature_C=st.floats(-200.0, 200.0))
def test_planned_s7any_reads_answer_as_the_general_path(items: list[S7AnyAddress], pdu_ref: int, fill: bytes,
                                                        temperature_C: float) -> None:
    """``Dispatcher.read_answer`` answers byte-sized S7ANY reads from a plan made once per parameter;
    the values must be those of the moment (after writes and sensor changes), the bytes those of
    ``Dispatcher.job``."""
    emulator = Emulator(clock=SimulatedClock(100.0))
    dispatcher = Dispatcher.for_machine(emulator)
    ctx = dispatcher.new_access_context("test")
    parameter = s7.build_read_var_request(s7.ReadVarRequest(tuple(items)))
    job = s7.S7Pdu(s7.Rosctr.JOB, pdu_ref, parameter)
    for round_ in range(2):  # the first answer makes the plan, the second uses it
        general = dispatcher.job(job, ctx)
        assert general is not None
        try:
            expected = s7.build_pdu(general)
        except Exception:  # noqa: BLE001 - data beyond 64 KiB: the session answers it the general way
            with pytest.raises(Exception):  # noqa: B017
                dispatcher.read_answer(pdu_ref, parameter, ctx)
        else:
            assert dispatcher.read_answer(pdu_ref, parameter, ctx) == expected
        for block in emulator.plc.data_blocks.values():
            block[:] = fill * len(block)
        emulator.plc.areas[0x81][:] = fill * len(emulator.plc.areas[0x81])
        emulator.nck.set_sensor_temperature("bed", temperature_C + round_)


@settings(max_examples=200, deadline=None)
@given(items=st.lists(st.one_of(KNOWN, PLANNED), min_size=1, max_size=8), pdu_ref=st.integers(0, 0xFFFF),
       split=st.integers(1, 200), copies=st.integers(1, 3), tpdu_size_code=st.sampled_from([0x07, 0x08, 0x0A]))
def test_read_jobs_answer_alike_whole_split_or_pipelined(items: list[object], pdu_ref: int, split: int,
                                                        copies: int, tpdu_size_code: int) -> None:
    """A read job alone in a segment takes the session's shortest path; split across segments or
    pipelined with others it goes through the framing loop: the answers are the same bytes (in as
    many DTs as the TPDU size needs)."""
    job = s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, pdu_ref, s7.build_read_var_request(s7.ReadVarRequest(tuple(items)))))
    frame = cotp.build_data_frame(job)
    general = _ready(480, tpdu_size_code)
    general_answer = general._handle_pdu(job, over_amq=False)
    assert general_answer is not None
    expected = general._data_frames(general_answer)
    whole, pieces = _ready(480, tpdu_size_code), _ready(480, tpdu_size_code)
    jobs_before = whole.info.jobs
    assert whole.receive(frame) == expected
    assert whole.receive(frame) == expected  # now from the plan kept by frame
    stream = frame * copies
    cut = min(split, len(stream) - 1)
    answers = pieces.receive(stream[:cut]) + pieces.receive(stream[cut:])
    assert answers == expected * copies
    assert whole.info.jobs == jobs_before + 2 and pieces.info.jobs == jobs_before + copies


def _ready_on(emulator: Emulator) -> ServerSession:
    session = ServerSession(Dispatcher.for_machine(emulator), limits=SessionLimits(pdu_size_max=480, max_amq=8))
    session.receive(CR)
    session.receive(cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, 1, s7.build_setup_communication(
        s7.SetupCommunication(1, 1, 480))))))
    return session


@settings(max_examples=300, deadline=None)
@given(items=st.lists(st.one_of(KNOWN, PLANNED), min_size=1, max_size=4), position=st.integers(0, 10),
       value=st.integers(0, 255))
def test_a_frame_like_a_polled_one_but_for_its_head_is_not_taken_for_it(items: list[object], position: int,
                                                                        value: int) -> None:
    """Polled jobs are kept by their bytes from 13 on and checked against bytes 0..10: a frame that
    differs in those (TPKT, COTP, S7 header) is answered as a server that never saw the job answers it."""
    frame = cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, 7, s7.build_read_var_request(
        s7.ReadVarRequest(tuple(items))))))
    changed = bytearray(frame)
    changed[position] = value
    seen, unseen = _ready_on(Emulator(clock=SimulatedClock(100.0))), _ready_on(Emulator(clock=SimulatedClock(100.0)))
    seen.receive(frame)
    assert seen.receive(bytes(changed)) == unseen.receive(bytes(changed))
    assert seen.closed == unseen.closed and seen.info.jobs - 1 == unseen.info.jobs
