"""Captures with lost segments: bytes cut out of a recorded session at random places (as a port mirror or
a filtered export loses them). After the gap the reader resyncs on the next TPKT header, reports the gap
once with its size, and every exchange the cut left whole is still paired; tshark is the oracle where
installed."""

from __future__ import annotations

import collections
import json
from pathlib import Path

import dpkt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.cli import main
from nckemu.traces.decode import decode
from nckemu.traces.reader import Capture, read_capture
from tests.support.tshark_tools import requires_tshark, tshark_fields
from tests.traces.test_traces import record_session

Packet = tuple[float, bytes]


@pytest.fixture(scope="module")
def session_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("lost") / "session.pcapng"
    record_session(path)
    return path


def _packets(path: Path) -> list[Packet]:
    with path.open("rb") as handle:
        return [(ts, bytes(frame)) for ts, frame in dpkt.pcapng.Reader(handle)]


def _write(path: Path, packets: list[Packet]) -> None:
    with path.open("wb") as handle:
        writer = dpkt.pcap.Writer(handle)
        for ts, frame in packets:
            writer.writepkt(frame, ts=ts)


def _stream_key(tcp: dpkt.tcp.TCP) -> tuple[int, int]:
    return tcp.sport, tcp.dport


def _streams(packets: list[Packet]) -> dict[tuple[int, int], list[tuple[int, int]]]:
    """Per direction (ports): (packet index, payload length) of each data segment, in order."""
    streams: dict[tuple[int, int], list[tuple[int, int]]] = collections.defaultdict(list)
    for index, (_ts, frame) in enumerate(packets):
        tcp = dpkt.ethernet.Ethernet(frame).data.data
        if tcp.data:
            streams[_stream_key(tcp)].append((index, len(tcp.data)))
    return streams


def cut(packets: list[Packet], direction: tuple[int, int], start: int, end: int) -> list[Packet]:
    """The capture without bytes ``start``..``end`` of one direction's stream: segments inside the range
    are gone, segments it overlaps lose their part of it (sequence numbers of what stays unchanged)."""
    out: list[Packet] = []
    offset = 0
    for ts, frame in packets:
        ethernet = dpkt.ethernet.Ethernet(frame)
        ip = ethernet.data
        tcp = ip.data
        if not tcp.data or _stream_key(tcp) != direction:
            out.append((ts, frame))
            continue
        first, last = offset, offset + len(tcp.data)
        offset = last
        if last <= start or first >= end:
            out.append((ts, frame))
            continue
        keep_head = tcp.data[:max(0, start - first)]
        keep_tail = tcp.data[max(0, end - first):]
        if keep_head and keep_tail:  # the cut lies inside one segment: two segments remain
            pieces = [(tcp.seq, keep_head), ((tcp.seq + len(tcp.data) - len(keep_tail)) & 0xFFFFFFFF, keep_tail)]
        elif keep_head:
            pieces = [(tcp.seq, keep_head)]
        elif keep_tail:
            pieces = [((tcp.seq + len(tcp.data) - len(keep_tail)) & 0xFFFFFFFF, keep_tail)]
        else:
            continue
        for seq, payload in pieces:
            tcp.seq, tcp.data, tcp.sum = seq, payload, 0
            ip.data, ip.len, ip.sum = tcp, 20 + len(bytes(tcp)), 0
            ethernet.data = ip
            out.append((ts, bytes(ethernet)))
    return out


def _exchanges(capture: Capture) -> collections.Counter[tuple[str, bytes, bytes]]:
    return collections.Counter((capture.connections[e.connection], e.job.data, e.answer.data)
                               for e in decode(capture) if e.answer is not None)


def _intact(packets: list[Packet], capture: Capture, direction: tuple[int, int], start: int, end: int
            ) -> collections.Counter[tuple[str, bytes, bytes]]:
    """The exchanges of the original capture whose job and answer lie outside the cut (frames are whole
    segments in a recorded session: a PDU's frame is the segment that carried it)."""
    streams = _streams(packets)
    touched = set()
    offset = 0
    for index, length in streams[direction]:
        if offset < end and offset + length > start:
            touched.add(index + 1)
        offset += length
    return collections.Counter((capture.connections[e.connection], e.job.data, e.answer.data)
                               for e in decode(capture)
                               if e.answer is not None and e.job.frame not in touched
                               and e.answer.frame not in touched)


@st.composite
def cuts(draw: st.DrawFn, packets: list[Packet]) -> tuple[tuple[int, int], int, int]:
    streams = _streams(packets)
    direction = draw(st.sampled_from(sorted(streams)))
    total = sum(length for _index, length in streams[direction])
    start = draw(st.integers(0, total - 2))
    end = draw(st.integers(start + 1, min(total - 1, start + 400)))  # data stays after the cut
    return direction, start, end


def _cut_at_random(session_path: Path, tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
                   ) -> tuple[list[Packet], tuple[int, int], int, int, Path]:
    """The recorded session with a random cut, written to a new file: packets, direction, cut, path."""
    packets = _packets(session_path)
    direction, start, end = data.draw(cuts(packets))
    path = tmp_path_factory.mktemp("cut") / "cut.pcap"
    _write(path, cut(packets, direction, start, end))
    return packets, direction, start, end, path


@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_every_answer_after_a_gap_is_paired(session_path: Path, tmp_path_factory: pytest.TempPathFactory,
                                            data: st.DataObject) -> None:
    packets, direction, start, end, path = _cut_at_random(session_path, tmp_path_factory, data)
    original = read_capture(session_path)
    damaged = read_capture(path)
    assert len(damaged.gaps) == 1, damaged.gaps  # reported once
    (gap,) = damaged.gaps
    assert gap.missing_bytes == end - start
    assert gap.from_client == (direction[1] == 102)
    assert not [p for p in damaged.problems if "answer without a job" in p]
    missing = _intact(packets, original, direction, start, end) - _exchanges(damaged)
    assert not missing


def test_a_lost_segment_in_the_middle_of_a_frame(session_path: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """A gap in a segment: the frame it cut is skipped (counted), the next frame decodes; trace show
    prints a gap line there, --json lists the gap, stderr counts it once."""
    packets = _packets(session_path)
    client = next(d for d in sorted(_streams(packets)) if d[1] == 102)
    path = tmp_path / "cut.pcap"
    _write(path, cut(packets, client, 200, 210))
    (gap,) = read_capture(path).gaps
    assert gap.missing_bytes == 10 and gap.skipped_bytes > 0
    assert "10 bytes from the client not captured" in gap.describe()
    assert main(["trace", "show", str(path)]) == 0
    out, err = capsys.readouterr()
    assert [line for line in out.splitlines() if f"#{gap.frame}" in line and " gap " in line]
    assert err.count("1 gap in the TCP streams (10 bytes not captured)") == 1
    assert main(["trace", "show", str(path), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert [(g["frame"], g["sender"], g["missing_bytes"]) for g in document["gaps"]] == [(gap.frame, "client", 10)]


@requires_tshark
@settings(max_examples=8, deadline=None)
@given(data=st.data())
def test_pairs_every_answer_tshark_pairs(session_path: Path, tmp_path_factory: pytest.TempPathFactory,
                                        data: st.DataObject) -> None:
    packets, direction, start, end, path = _cut_at_random(session_path, tmp_path_factory, data)
    answered = {e.answer.frame for e in decode(read_capture(path)) if e.answer is not None}
    jobs: set[tuple[str, str]] = set()
    tshark_paired = set()
    for row in tshark_fields(path, ["frame.number", "tcp.stream", "s7comm.header.rosctr", "s7comm.header.pduref"]):
        key = (row["tcp.stream"], row["s7comm.header.pduref"])
        if row["s7comm.header.rosctr"] == "1":
            jobs.add(key)
        elif row["s7comm.header.rosctr"] in ("2", "3") and key in jobs:
            jobs.discard(key)  # a job takes one answer
            tshark_paired.add(int(row["frame.number"]))
    assert tshark_paired <= answered
