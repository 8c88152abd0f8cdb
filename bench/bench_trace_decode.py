"""Trace decode rate: ``nckemu``'s reader and decoder against ``tshark -T fields`` on the same file.

A capture of N frames (request/answer pairs of NCK reads on one connection), as classic pcap and as
pcapng (what Wireshark writes), is generated from two packet templates with patched TCP sequence
numbers, PDU references and values, then both decoders read it; ours gives every item its name,
return code and value.

Usage: .venv/bin/python bench/bench_trace_decode.py [--frames 1000000] [--format pcap|pcapng|both]
       [--baseline DIR] [--lost-every N]

``--baseline DIR`` also times the reader and decoder of another nckemu tree on the same file (e.g. the
main branch: ``git archive main | tar -x -C DIR``), in a fresh interpreter: before/after in one run.
``--lost-every N`` leaves out every Nth answer segment, as a capture with lost segments does (each
loss a gap the reader resyncs after; the job stays unanswered).
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from nckemu.capture import write_capture  # noqa: E402
from nckemu.protocol import cotp, s7  # noqa: E402
from nckemu.protocol.addresses import NckAddress  # noqa: E402
from nckemu.traces.decode import decode  # noqa: E402
from nckemu.traces.reader import read_capture  # noqa: E402

_ITEMS = (NckAddress(3, 4, 43900, 1, 0x16), NckAddress(2, 1, 1, 1, 0x15))
REQUEST = cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(1, 1, s7.build_read_var_request(s7.ReadVarRequest(_ITEMS)))))
ANSWER = cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(3, 1, *s7.build_read_var_response(s7.ReadVarResponse((
    s7.DataItem(0xFF, 0x09, struct.pack("<d", 0.3)), s7.DataItem(0xFF, 0x09, struct.pack("<d", 0.1))))))))


S7_PDU_REF = 14 + 20 + 20 + 4 + 3 + 4      # Ethernet, IPv4, TCP, TPKT, COTP DT, then the S7 header's reference
FIRST_VALUE = 14 + 20 + 20 + 4 + 3 + 12 + 2 + 4   # ... the answer's header and parameter, the item's header


def _pcapng_head() -> bytes:
    """Section header and interface description (Ethernet, microseconds), as Wireshark writes them."""
    section = struct.pack("<IIIHHq", 0x0A0D0D0A, 28, 0x1A2B3C4D, 1, 0, -1) + struct.pack("<I", 28)
    interface = struct.pack("<IIHHI", 1, 20, 1, 0, 262144) + struct.pack("<I", 20)
    return section + interface


def write_big_capture(path: Path, frames: int, pcapng: bool = False) -> None:
    with tempfile.TemporaryDirectory() as scratch:
        template = Path(scratch) / "t.pcap"
        write_capture(template, [(True, REQUEST), (False, ANSWER)])
        data = template.read_bytes()
    header, records = data[:24], data[24:]
    packets = []
    offset = 0
    while offset < len(records):
        length = struct.unpack_from("<I", records, offset + 8)[0]
        packets.append(records[offset + 16:offset + 16 + length])
        offset += 16 + length
    request, answer = packets[3], packets[4]  # after the three-way handshake
    tcp_seq = 14 + 20 + 4  # Ethernet + IPv4 header, then the TCP sequence number
    with path.open("wb") as handle:
        handle.write(_pcapng_head() if pcapng else header)
        client_seq, server_seq = struct.unpack_from(">II", request, tcp_seq)
        record = struct.Struct("<IIII")
        for index in range(frames // 2):
            for packet, seq, ack in ((request, client_seq, server_seq), (answer, server_seq, client_seq)):
                patched = bytearray(packet)
                struct.pack_into(">II", patched, tcp_seq, seq & 0xFFFFFFFF, ack & 0xFFFFFFFF)
                # As from a real client: a new PDU reference per job; as from a real NCK: a new value.
                struct.pack_into(">H", patched, S7_PDU_REF, index % 0xFFFF + 1)
                if packet is answer:
                    struct.pack_into("<d", patched, FIRST_VALUE, 0.3 + index * 1e-6)
                seconds, microseconds = 1_700_000_000 + index // 1000, (index % 1000) * 1000
                if pcapng:  # an enhanced packet block
                    block_length = 32 + len(patched) + (-len(patched) % 4)
                    stamp = seconds * 1_000_000 + microseconds
                    handle.write(struct.pack("<IIIIIII", 6, block_length, 0, stamp >> 32, stamp & 0xFFFFFFFF,
                                             len(patched), len(patched)))
                    handle.write(patched + bytes(-len(patched) % 4) + struct.pack("<I", block_length))
                else:
                    handle.write(record.pack(seconds, microseconds, len(patched), len(patched)))
                    handle.write(patched)
            client_seq += len(REQUEST)
            server_seq += len(ANSWER)


_BASELINE_SCRIPT = """
import sys, time
sys.path.insert(0, sys.argv[1])
from nckemu.traces.decode import decode
from nckemu.traces.reader import read_capture
started = time.perf_counter()
capture = read_capture(sys.argv[2])
exchanges = decode(capture)
print(time.perf_counter() - started, len(exchanges), sum(e.answer is not None for e in exchanges))
"""


def _time_tree(tree: Path, path: Path, timeout_s: float) -> tuple[float, int, int] | None:
    """Seconds, exchanges and answered exchanges of one tree's reader and decoder on ``path``, in a fresh
    interpreter; None when it takes longer than ``timeout_s``."""
    try:
        result = subprocess.run([sys.executable, "-c", _BASELINE_SCRIPT, str(tree), str(path)],
                                capture_output=True, text=True, check=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return None
    seconds_text, exchanges, answered = result.stdout.split()
    return float(seconds_text), int(exchanges), int(answered)


def measure_baseline(baseline: Path, path: Path, frames: int, rounds: int, timeout_s: float = 300.0) -> None:
    """This tree and ``baseline`` on the same file, in turn (the machine's speed drifts: one after the
    other would put the drift into the ratio), ``rounds`` times each; medians."""
    here = Path(__file__).resolve().parent.parent
    times: dict[str, list[float]] = {"this tree": [], "baseline": []}
    counts: dict[str, tuple[int, int]] = {}
    for round_number in range(rounds):
        order = [("this tree", here), ("baseline", baseline)]
        for name, tree in order if round_number % 2 == 0 else order[::-1]:
            timed = _time_tree(tree, path, timeout_s)
            if timed is None:
                print(f"  {name}: more than {timeout_s:.0f} s, given up")
                return
            times[name].append(timed[0])
            counts[name] = timed[1:]
    for name, values in times.items():
        median = statistics.median(values)
        exchanges, answered = counts[name]
        print(f"  {name}{'' if name == 'this tree' else f' ({baseline})'}: {exchanges:,} exchanges, {answered:,} "
              f"answered, median {median:.2f} s of {rounds} (range {min(values):.2f}..{max(values):.2f}), "
              f"{frames / median:,.0f} frames/s")
    print(f"  this tree / baseline speed: {statistics.median(times['baseline']) / statistics.median(times['this tree']):.2f}x")


def drop_answers(path: Path, every: int) -> int:
    """Rewrite the (classic pcap) capture without every ``every``th answer; the number left out."""
    data = path.read_bytes()
    out = [data[:24]]
    offset, index, dropped = 24, 0, 0
    while offset < len(data):
        length = struct.unpack_from("<I", data, offset + 8)[0]
        end = offset + 16 + length
        if index % 2 and (index // 2) % every == every - 1:
            dropped += 1
        else:
            out.append(data[offset:end])
        offset, index = end, index + 1
    path.write_bytes(b"".join(out))
    return dropped


def measure(path: Path, frames: int) -> tuple[float, float | None]:
    """Seconds for ours and for tshark (None when tshark is not installed) on one file."""
    started = time.perf_counter()
    capture = read_capture(path)
    exchanges = decode(capture)
    ours_s = time.perf_counter() - started
    answered = sum(e.answer is not None for e in exchanges)
    print(f"  nckemu: {len(exchanges):,} exchanges, {answered:,} answered, {len(capture.problems)} problems, "
          f"{len(capture.gaps)} gaps, {ours_s:.1f} s, {frames / ours_s:,.0f} frames/s")
    tshark = shutil.which("tshark")
    if tshark is None:
        print("  tshark not installed: no comparison")
        return ours_s, None
    started = time.perf_counter()
    result = subprocess.run([tshark, "-r", str(path), "-T", "fields", "-e", "frame.number",
                             "-e", "s7comm.param.item.nck.column", "-e", "s7comm.data.returncode"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, check=True)
    tshark_s = time.perf_counter() - started
    lines = result.stdout.count(b"\n")
    print(f"  tshark: {lines:,} lines, {tshark_s:.1f} s, {frames / tshark_s:,.0f} frames/s")
    print(f"  ratio nckemu / tshark: {tshark_s / ours_s:.2f}x")
    return ours_s, tshark_s


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--format", choices=("pcap", "pcapng", "both"), default="both")
    parser.add_argument("--baseline", type=Path, metavar="DIR", help="another nckemu tree to time on the same files")
    parser.add_argument("--rounds", type=int, default=3, help="runs of each tree with --baseline (3)")
    parser.add_argument("--lost-every", type=int, default=0, metavar="N",
                        help="also a classic pcap without every Nth answer segment (lost segments)")
    args = parser.parse_args()
    formats = ("pcap", "pcapng") if args.format == "both" else (args.format,)
    with tempfile.TemporaryDirectory() as scratch:
        for kind in formats:
            path = Path(scratch) / f"big.{kind}"
            started = time.perf_counter()
            write_big_capture(path, args.frames, pcapng=kind == "pcapng")
            print(f"{kind}: generated {args.frames:,} frames ({path.stat().st_size / 1e6:.0f} MB) in "
                  f"{time.perf_counter() - started:.1f} s")
            measure(path, args.frames)
            if args.baseline is not None:
                measure_baseline(args.baseline, path, args.frames, args.rounds)
            path.unlink()
        if args.lost_every:
            path = Path(scratch) / "lost.pcap"
            write_big_capture(path, args.frames)
            dropped = drop_answers(path, args.lost_every)
            frames = args.frames - dropped
            print(f"pcap with lost segments: {dropped:,} of {args.frames // 2:,} answers not captured")
            measure(path, frames)
            if args.baseline is not None:
                measure_baseline(args.baseline, path, frames, args.rounds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
