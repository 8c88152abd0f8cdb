"""The decoder's shortcuts give what the general paths give.

Classic pcap records are walked over a memory map instead of through dpkt's reader, and polled read
jobs are decoded once, their all-good answers by a learnt layout: each is checked here against the
general path on generated input.
"""

from __future__ import annotations

import itertools
import json
import mmap
import struct
from collections.abc import Callable, Iterator
from pathlib import Path

import dpkt
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from nckemu.capture import CaptureWriter
from nckemu.cli import main
from nckemu.errors import NckConfigError
from nckemu.protocol import cotp, s7
from nckemu.protocol.addresses import NckAddress, NckArea, S7AnyAddress
from nckemu.traces import decode as decoder
from nckemu.traces.reader import (
    Capture,
    TracePdu,
    _dpkt_records,
    _mapped,
    _mapped_pcap_records,
    _mapped_pcapng_records,
    read_capture,
)

_FRAMES = st.lists(st.tuples(st.integers(0, 2**31), st.integers(0, 999_999), st.binary(max_size=120)),
                   max_size=12)


def _write_pcap(path: Path, frames: list[tuple[int, int, bytes]], *, big_endian: bool, nanoseconds: bool) -> None:
    """A classic pcap file in either byte order (dpkt's writer knows only the machine's)."""
    order = ">" if big_endian else "<"
    magic = dpkt.pcap.TCPDUMP_MAGIC_NANO if nanoseconds else dpkt.pcap.TCPDUMP_MAGIC
    parts = [struct.pack(order + "IHHiIII", magic, 2, 4, 0, 0, 65535, dpkt.pcap.DLT_EN10MB)]
    for seconds, fraction, frame in frames:
        parts.append(struct.pack(order + "IIII", seconds, fraction, len(frame), len(frame)) + frame)
    path.write_bytes(b"".join(parts))


_Walked = list[tuple[int, float, bytes]]


def _frames(records: Iterator[tuple[int, float, bytes | mmap.mmap, int, int]]) -> _Walked:
    return [(n, ts, bytes(buffer[start:start + length])) for n, ts, buffer, start, length in records]


def _walk_both(path: Path) -> tuple[_Walked, _Walked, Capture]:
    """Our walk over the mapped file (pcap or pcapng, by the suffix) and dpkt's own reading of it."""
    pcapng = path.suffix == ".pcapng"
    reader_type = dpkt.pcapng.Reader if pcapng else dpkt.pcap.Reader
    capture = Capture(str(path))
    with path.open("rb") as handle:
        magic = int.from_bytes(handle.read(4), "big")
        handle.seek(0)
        reader = reader_type(handle)
        mapped = _mapped(handle)
        assert mapped is not None
        with mapped:
            ours = _frames(_mapped_pcapng_records(mapped, handle.tell(), reader, capture) if pcapng
                           else _mapped_pcap_records(mapped, magic, capture))
    with path.open("rb") as handle:
        theirs = _frames(_dpkt_records(reader_type(handle), Capture(str(path))))
    return ours, theirs, capture


@settings(max_examples=80, deadline=None)
@given(frames=_FRAMES, big_endian=st.booleans(), nanoseconds=st.booleans())
def test_mapped_records_are_dpkts_records(tmp_path_factory: pytest.TempPathFactory,
                                          frames: list[tuple[int, int, bytes]], big_endian: bool,
                                          nanoseconds: bool) -> None:
    path = tmp_path_factory.mktemp("pcap") / "f.pcap"
    _write_pcap(path, frames, big_endian=big_endian, nanoseconds=nanoseconds)
    ours, theirs, capture = _walk_both(path)
    assert [(n, frame) for n, _ts, frame in ours] == [(n, frame) for n, _ts, frame in theirs]
    assert [ts for _n, ts, _f in ours] == pytest.approx([ts for _n, ts, _f in theirs], abs=1e-9)
    assert capture.problems == []


def _check_cut(path: Path, header_bytes: int, record_ends: list[int], frames: list[tuple[int, int, bytes]],
               cut: int, walk: Callable[[Path], tuple[list[tuple[int, float, bytes]], object, Capture]]) -> None:
    """Cut the file at some byte after its header: the whole records before the cut are read, and a
    cut inside a record is one problem naming the frame where the file breaks."""
    data = path.read_bytes()
    keep = header_bytes + cut % (len(data) - header_bytes)
    path.write_bytes(data[:keep])
    whole = sum(1 for end in record_ends if end <= keep)
    ours, _theirs, capture = walk(path)
    assert [frame for _n, _ts, frame in ours] == [frame for _s, _f, frame in frames[:whole]]
    if keep in record_ends or keep == header_bytes:
        assert capture.problems == []
    else:
        assert len(capture.problems) == 1 and f"frame {whole + 1}: capture ends in a damaged record" \
            in capture.problems[0]


@settings(max_examples=80, deadline=None)
@given(frames=_FRAMES.filter(bool), cut=st.integers(1, 10_000))
def test_a_cut_pcap_gives_its_whole_records_and_says_where_it_breaks(
        tmp_path_factory: pytest.TempPathFactory, frames: list[tuple[int, int, bytes]], cut: int) -> None:
    path = tmp_path_factory.mktemp("pcap") / "cut.pcap"
    _write_pcap(path, frames, big_endian=False, nanoseconds=False)
    ends = list(itertools.accumulate((16 + len(frame) for _s, _f, frame in frames), initial=24))[1:]
    _check_cut(path, 24, ends, frames, cut, _walk_both)


def test_a_cut_classic_pcap_is_shown_up_to_the_damage(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "session.pcap"
    writer = CaptureWriter.open(path)
    for reference in (1, 2):
        job = s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, reference, s7.build_read_var_request(
            s7.ReadVarRequest(_ITEMS[:1]))))
        answer = s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, reference, *s7.build_read_var_response(
            s7.ReadVarResponse((s7.DataItem(0xFF, 0x09, struct.pack("<d", 0.3)),)))))
        writer.segment(1, True, cotp.build_data_frame(job))
        writer.segment(1, False, cotp.build_data_frame(answer))
    writer.close()
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(path.read_bytes()[:-5])
    assert main(["trace", "show", str(cut)]) == 0
    shown = capsys.readouterr()
    assert "damaged record" in shown.err and "TEMP_COMP_ABS_VALUE[AX4] = 0.300000" in shown.out
    assert len(decoder.decode(read_capture(cut))) == 2


# Items of every kind the fast paths treat differently: single numbers in both byte orders, arrays,
# strings, BOOL-less bytes, S7ANY items, and NCK items of no known variable.
_ITEMS = (
    NckAddress(NckArea.A, 4, 43900, 1, 0x16),                    # SD REAL8, little-endian
    NckAddress(2, 1, 32750, 1, 0x1A),                             # MD BYTE
    NckAddress(2, 1, 38000, 1, 0x1A),                             # MD DINT
    NckAddress(0, 1, 7, 1, 0x7F),                                 # WORD
    NckAddress(0, 1, 5, 1, 0x7A),                                 # STRING[32]
    NckAddress(2, 1, 1, 1, 0x15, line_count=3),                  # R[1..3]: an array
    NckAddress(NckArea.V, 1, 43900, 1, 0x16),                    # a drive area: big-endian
    NckAddress(0, 1, 999, 1, 0x55),                               # nothing known there
    S7AnyAddress(0x02, 4, 10, 0x84, 0),                           # DB10.DBB0, 4 bytes
    S7AnyAddress(0x08, 1, 0, 0x83, 300),                          # MD300 REAL: a big-endian value
    S7AnyAddress(0x01, 1, 0, 0x83, 102, 3),                       # M102.3: a bit
    S7AnyAddress(0x07, 2, 3, 0x84, 4),                            # DB3.DBD4 DINT x2: an array
)
_SIZES = {0x16: 8, 0x1A: 1, 0x7F: 2, 0x7A: 32, 0x15: 24, 0x55: 4}


def _answer_item(address: object, good: bool, size_error: bool, seed: bytes) -> s7.DataItem:
    if not good:
        return s7.DataItem(0x0A, 0x00, b"")
    if isinstance(address, S7AnyAddress):
        if address.transport_size == 0x01:
            return s7.DataItem(0xFF, 0x03, bytes([seed[0] & 1]))
        size = 8 if address.transport_size == 0x07 else 4
        return s7.DataItem(0xFF, 0x07 if address.transport_size in (0x07, 0x08) else 0x04, (seed * size)[:size])
    assert isinstance(address, NckAddress)
    size = 4 if address.module == 0x1A and address.column == 38000 else _SIZES[address.module]
    size += 1 if size_error else 0
    return s7.DataItem(0xFF, 0x09, (seed * size)[:size] if seed else bytes(size))


_ANSWERS = st.lists(st.lists(st.tuples(st.sampled_from([True, True, True, False]),
                                       st.sampled_from([False] * 6 + [True]), st.binary(min_size=1, max_size=8)),
                             min_size=len(_ITEMS), max_size=len(_ITEMS)), min_size=1, max_size=6)


def _reference(capture: Capture) -> list[decoder.Exchange]:
    """The general path only: every PDU parsed in full, every value decoded from its type."""
    open_jobs: dict[int, decoder.Exchange] = {}
    exchanges = []
    for pdu in capture.pdus:
        parsed = s7.parse_pdu(pdu.data)
        if pdu.from_client:
            open_jobs[parsed.pdu_ref] = decoder._describe_job(pdu, parsed, capture)
            exchanges.append(open_jobs[parsed.pdu_ref])
        else:
            exchange = open_jobs.pop(parsed.pdu_ref)
            exchange.answer = pdu
            decoder._describe_answer(exchange, parsed, capture)
    return exchanges


@settings(max_examples=150, deadline=None)
@given(chosen=st.lists(st.integers(0, len(_ITEMS) - 1), min_size=1, max_size=5), answers=_ANSWERS)
def test_polled_reads_decode_as_the_general_path_does(chosen: list[int],
                                                      answers: list[list[tuple[bool, bool, bytes]]]) -> None:
    items = tuple(_ITEMS[i] for i in chosen)
    job = s7.build_read_var_request(s7.ReadVarRequest(items))
    pdus = []
    for reference, answer in enumerate(answers, start=1):
        pdus.append(TracePdu(2 * reference - 1, float(reference), 1, True, "s7",
                             s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, reference, job))))
        data_items = tuple(_answer_item(address, good, size_error, seed)
                           for address, (good, size_error, seed) in zip(items, answer, strict=False))
        parameter, data = s7.build_read_var_response(s7.ReadVarResponse(data_items))
        pdus.append(TracePdu(2 * reference, float(reference) + 0.5, 1, False, "s7",
                             s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, reference, parameter, data))))
    fast = decoder.decode(Capture("generated", list(pdus)))
    general = _reference(Capture("generated", list(pdus)))
    assert json.dumps([e.to_json() for e in fast]) == json.dumps([e.to_json() for e in general])


def _block(order: str, block_type: int, body: bytes) -> bytes:
    body += bytes(-len(body) % 4)
    length = 12 + len(body)
    return struct.pack(order + "II", block_type, length) + body + struct.pack(order + "I", length)


def _write_pcapng(path: Path, frames: list[tuple[int, int, bytes]], *, big_endian: bool, resolution: int | None,
                  offset_s: int | None, kinds: list[int]) -> None:
    """A pcapng file in either byte order, with or without a timestamp resolution and offset, its frames in
    enhanced (6) or obsolete (2) packet blocks with statistics blocks (5) between them."""
    order = ">" if big_endian else "<"
    options = b""
    if resolution is not None:
        options += struct.pack(order + "HH", 9, 1) + bytes([resolution, 0, 0, 0])
    if offset_s is not None:
        options += struct.pack(order + "HHq", 14, 8, offset_s)
    parts = [_block(order, 0x0A0D0D0A, struct.pack(order + "IHHq", 0x1A2B3C4D, 1, 0, -1)),
             _block(order, 1, struct.pack(order + "HHI", dpkt.pcap.DLT_EN10MB, 0, 65535) + options
                    + (struct.pack(order + "HH", 0, 0) if options else b""))]
    for (high, low, frame), kind in zip(frames, kinds, strict=False):
        if kind == 5:
            parts.append(_block(order, 5, struct.pack(order + "III", 0, high, low)))
        head = struct.pack(order + "HHIIII", 0, 0, high, low, len(frame), len(frame)) if kind == 2 \
            else struct.pack(order + "IIIII", 0, high, low, len(frame), len(frame))
        parts.append(_block(order, 2 if kind == 2 else 6, head + frame))
    path.write_bytes(b"".join(parts))


@settings(max_examples=80, deadline=None)
@given(frames=_FRAMES, big_endian=st.booleans(), resolution=st.sampled_from([None, 6, 9, 0x8A]),
       offset_s=st.sampled_from([None, 0, 1_700_000_000]), kinds=st.lists(st.sampled_from([6, 6, 2, 5]),
                                                                          min_size=12, max_size=12))
def test_mapped_pcapng_blocks_are_dpkts_records(tmp_path_factory: pytest.TempPathFactory,
                                                frames: list[tuple[int, int, bytes]], big_endian: bool,
                                                resolution: int | None, offset_s: int | None,
                                                kinds: list[int]) -> None:
    path = tmp_path_factory.mktemp("pcapng") / "f.pcapng"
    _write_pcapng(path, frames, big_endian=big_endian, resolution=resolution, offset_s=offset_s, kinds=kinds)
    ours, theirs, capture = _walk_both(path)
    assert [(n, frame) for n, _ts, frame in ours] == [(n, frame) for n, _ts, frame in theirs]
    assert [ts for _n, ts, _f in ours] == [ts for _n, ts, _f in theirs]
    assert capture.problems == []


@settings(max_examples=60, deadline=None)
@given(frames=_FRAMES.filter(bool), cut=st.integers(1, 10_000))
def test_a_cut_pcapng_gives_its_whole_blocks_and_says_where_it_breaks(
        tmp_path_factory: pytest.TempPathFactory, frames: list[tuple[int, int, bytes]], cut: int) -> None:
    path = tmp_path_factory.mktemp("pcapng") / "cut.pcapng"
    _write_pcapng(path, frames, big_endian=False, resolution=None, offset_s=None, kinds=[6] * len(frames))
    header = 28 + 20  # the section header and interface description blocks
    blocks = (32 + len(frame) + (-len(frame) % 4) for _h, _l, frame in frames)
    _check_cut(path, header, list(itertools.accumulate(blocks, initial=header))[1:], frames, cut, _walk_both)


def test_linux_cooked_captures_decode_as_ethernet_ones(tmp_path: Path) -> None:
    """tcpdump -i any writes Linux cooked (SLL) frames: the same traffic must decode the same."""
    ethernet = tmp_path / "ethernet.pcap"
    writer = CaptureWriter.open(ethernet)
    for reference in range(1, 6):
        job = s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, reference, s7.build_read_var_request(s7.ReadVarRequest(_ITEMS[:2]))))
        answer = s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, reference, *s7.build_read_var_response(s7.ReadVarResponse(
            (s7.DataItem(0xFF, 0x09, struct.pack("<d", reference / 10)), s7.DataItem(0xFF, 0x09, b"\x01"))))))
        writer.segment(1, True, cotp.build_data_frame(job))
        writer.segment(1, False, cotp.build_data_frame(answer))
    writer.close()
    cooked = tmp_path / "cooked.pcap"
    with ethernet.open("rb") as source, cooked.open("wb") as target:
        out = dpkt.pcap.Writer(target, linktype=dpkt.pcap.DLT_LINUX_SLL)
        for ts, frame in dpkt.pcap.Reader(source):
            # packet type 0 (to us), ARPHRD_ETHER, 6-byte address padded to 8, then the EtherType
            out.writepkt(struct.pack(">HHH8s", 0, 1, 6, frame[6:12]) + frame[12:], ts)
    expected = read_capture(ethernet)
    got = read_capture(cooked)
    assert [(p.frame, p.from_client, p.data) for p in got.pdus] == [(p.frame, p.from_client, p.data) for p in expected.pdus]
    assert [e.to_json() for e in decoder.decode(got)] == [e.to_json() for e in decoder.decode(expected)]
    assert len(expected.pdus) >= 10


def _small_capture(path: Path) -> bytes:
    writer = CaptureWriter.open(path)
    for reference in (1, 2, 3):
        job = s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, reference, s7.build_read_var_request(s7.ReadVarRequest(_ITEMS[:3]))))
        answer = s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, reference, *s7.build_read_var_response(s7.ReadVarResponse(
            (s7.DataItem(0xFF, 0x09, bytes(8)), s7.DataItem(0xFF, 0x09, b"\x01"), s7.DataItem(0x0A, 0, b""))))))
        writer.segment(1, True, cotp.build_data_frame(job))
        writer.segment(1, False, cotp.build_data_frame(answer))
    writer.close()
    return path.read_bytes()


@settings(max_examples=300, deadline=None)
@example(pcapng=False, flips=[(322, 0)], cut=0)  # a read job's item cut short: crashed the decoder once
@given(pcapng=st.booleans(), flips=st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 255)), min_size=1,
                                              max_size=8), cut=st.integers(0, 10_000))
def test_damaged_captures_give_a_message_never_a_crash(tmp_path_factory: pytest.TempPathFactory, pcapng: bool,
                                                       flips: list[tuple[int, int]], cut: int) -> None:
    """Any byte of a capture changed, and the file cut anywhere: the reader and decoder report what they
    cannot read (a message naming the file when nothing is left), they never raise anything else."""
    folder = tmp_path_factory.mktemp("damaged")
    data = bytearray(_small_capture(folder / ("good.pcapng" if pcapng else "good.pcap")))
    for position, value in flips:
        data[position % len(data)] = value
    damaged = folder / ("damaged.pcapng" if pcapng else "damaged.pcap")
    damaged.write_bytes(bytes(data[:len(data) - cut % len(data)]))
    try:
        capture = read_capture(damaged)
    except NckConfigError as exc:
        assert str(damaged) in str(exc)
        return
    for exchange in decoder.decode(capture):  # and what `trace show` prints of it
        decoder.format_exchange(exchange, 0.0)
        json.dumps(exchange.to_json())
