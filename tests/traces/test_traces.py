"""Captures made with the real emulator and clients: decode, replay, tshark cross-check, bad input."""

from __future__ import annotations

import json
import random
import struct
from collections.abc import Callable
from pathlib import Path

import dpkt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.capture import CaptureWriter
from nckemu.cli import main
from nckemu.clients import NckClient
from nckemu.emulator.runner import EmulatorThread
from nckemu.traces.reader import read_capture
from tests.support.tshark_tools import requires_tshark, tshark_fields

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"


def record_session(path: Path, machine: str | None = None) -> None:
    """Two interleaved connections: writes, reads (one before any write), an item error, PI services."""
    with EmulatorThread(machine, record_path=path) as emu, \
            NckClient("127.0.0.1", emu.port) as first, NckClient("127.0.0.1", emu.port) as second:
        first.get("SD43900[AX4]", "R10")
        second.put({"SD43910[AX4]": 0.000012, "SD43920[AX4]": -1000.0})
        first.put({"R3": 3.5})
        second.get_items("SD43900[AX9]", "SD43910[AX4]", "R3")
        first.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_TEST_MPF")
        try:
            second.pi_service("_N_F_DELE", "201", "/_N_MPF_DIR/_N_NOPE_MPF")
        except Exception:  # noqa: BLE001 - the refusal is part of the capture
            pass
        first.get("actToolBasePos[C1,l1,x4]")


@pytest.fixture(scope="module")
def capture_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("traces") / "session.pcapng"
    record_session(path)
    return path


def show_json(path: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> dict:
    assert main(["trace", "show", str(path), "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_show_names_items_and_pairs_answers(capture_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    document = show_json(capture_path, capsys)
    assert len(document["connections"]) == 2
    names = [item["name"] for e in document["exchanges"] for item in e["items"]]
    assert "SD43910 TEMP_COMP_SLOPE[AX4]" in names and "R3[C1]" in names
    errors = [item["return_text"] for e in document["exchanges"] for item in e["items"]
              if item["name"].endswith("[AX9]")]
    assert errors == ["object does not exist"]
    pi = [e for e in document["exchanges"] if e["function"] == "PI"]
    assert pi[0]["detail"].startswith("_N_SELECT(") and pi[1]["header_error"]
    assert all(e["answer_frame"] for e in document["exchanges"])
    filtered = show_json(capture_path, capsys, "--var", "TEMP_COMP_SLOPE")
    assert all(any("TEMP_COMP_SLOPE" in i["name"] for i in e["items"]) for e in filtered["exchanges"])
    assert main(["trace", "show", str(capture_path), "--connection", "2"]) == 0
    assert "_N_F_DELE" in capsys.readouterr().out


def test_record_replays_with_zero_differences(capture_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["trace", "replay", str(capture_path), "--spawn", "--json", "--quiet"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["all_match"] and report["matching_items"] > 10 and report["jobs"] >= 9


def test_a_different_machine_shows_the_known_differences(capture_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    machine = str(FIXTURES / "machines" / "warm_z.toml")
    assert main(["trace", "replay", str(capture_path), "--spawn", "--machine", machine, "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    differing = {d["item"] for d in report["differences"]}
    assert "SD43900 TEMP_COMP_ABS_VALUE[AX4]" in differing and "R10[C1]" in differing
    # Seeding the state from the trace's first reads reproduces the field values.
    assert main(["trace", "replay", str(capture_path), "--spawn", "--machine", machine, "--seed-state",
                 "--json"]) == 0


def test_replay_against_a_running_emulator(capture_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with EmulatorThread() as emu:
        assert main(["trace", "replay", str(capture_path), "--emulator", f"127.0.0.1:{emu.port}", "--quiet"]) == 0
    assert "0 values differ" in capsys.readouterr().out


def _segments(path: Path) -> list[tuple[float, bytes]]:
    with path.open("rb") as handle:
        return [(ts, bytes(frame)) for ts, frame in dpkt.pcapng.Reader(handle)]


def _rewrite(path: Path, packets: list[tuple[float, bytes]]) -> None:
    with path.open("wb") as handle:
        writer = dpkt.pcap.Writer(handle)
        for ts, frame in packets:
            writer.writepkt(frame, ts=ts)


def _pdus(path: Path) -> dict[tuple[str, bool], list[bytes]]:
    """Per connection (by address: numbering follows first appearance) and direction."""
    capture = read_capture(path)
    streams: dict[tuple[str, bool], list[bytes]] = {}
    for pdu in capture.pdus:
        streams.setdefault((capture.connections[pdu.connection], pdu.from_client), []).append(pdu.data)
    return streams


@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_reordered_and_duplicated_segments_decode_the_same(capture_path: Path, tmp_path_factory:
                                                           pytest.TempPathFactory, data: st.DataObject) -> None:
    packets = _segments(capture_path)
    rng = random.Random(data.draw(st.integers(0, 2**32 - 1)))
    shuffled = list(packets)
    for _ in range(data.draw(st.integers(0, 10))):  # swap neighbours: out-of-order delivery
        i = rng.randrange(len(shuffled) - 1)
        shuffled[i], shuffled[i + 1] = shuffled[i + 1], shuffled[i]
    for _ in range(data.draw(st.integers(0, 5))):  # retransmissions, some time after the original
        original = rng.randrange(len(shuffled))
        shuffled.insert(rng.randrange(original + 1, len(shuffled) + 1), shuffled[original])
    path = tmp_path_factory.mktemp("mutated") / "m.pcap"
    _rewrite(path, shuffled)
    assert _pdus(path) == _pdus(capture_path)


def test_segmented_tpkt_frames(tmp_path: Path, capture_path: Path) -> None:
    """Every frame split into 3-byte TCP segments still decodes to the same PDUs."""
    path = tmp_path / "segmented.pcapng"
    _in_three_byte_segments(capture_path, path)
    assert [p.data for p in read_capture(path).pdus] == [p.data for p in read_capture(capture_path).pdus]


def test_bad_input(tmp_path: Path, capture_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty = tmp_path / "empty.pcapng"
    empty.write_bytes(b"")
    assert main(["trace", "show", str(empty)]) == 1
    assert "empty.pcapng" in capsys.readouterr().err
    truncated = tmp_path / "truncated.pcapng"
    truncated.write_bytes(capture_path.read_bytes()[:-37])
    assert main(["trace", "show", str(truncated)]) == 0  # what could be read is shown
    assert "damaged" in capsys.readouterr().err
    http = tmp_path / "http.pcapng"
    writer = CaptureWriter.open(http)
    writer.segment(1, True, b"GET / HTTP/1.1\r\nHost: plc\r\n\r\n")
    writer.segment(2, True, bytes(range(256)))
    writer.close()
    assert main(["trace", "show", str(http)]) == 1
    err = capsys.readouterr().err
    assert "not TPKT" in err and "no S7 traffic" in err


def _as_classic_pcap(source: Path, target: Path) -> None:
    _rewrite(target, _segments(source))


def _in_three_byte_segments(source: Path, target: Path) -> None:
    writer = CaptureWriter.open(target)
    for pdu in read_capture(source).pdus:
        frame = pdu.data if pdu.kind != "s7" else struct.pack(">BBH", 3, 0, 7 + len(pdu.data)) + b"\x02\xf0\x80" + pdu.data
        for start in range(0, len(frame), 3):
            writer.segment(pdu.connection, pdu.from_client, frame[start:start + 3])
    writer.close()


def _as_linux_cooked(source: Path, target: Path) -> None:
    with target.open("wb") as handle:
        writer = dpkt.pcap.Writer(handle, linktype=dpkt.pcap.DLT_LINUX_SLL)
        for ts, frame in _segments(source):
            writer.writepkt(struct.pack(">HHH8s", 0, 1, 6, frame[6:12]) + frame[12:], ts)


@requires_tshark
@pytest.mark.parametrize("variant", [None, _as_classic_pcap, _in_three_byte_segments, _as_linux_cooked],
                         ids=["recorded", "classic-pcap", "3-byte-segments", "linux-cooked"])
def test_items_match_tshark(capture_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                            variant: Callable[[Path, Path], None] | None) -> None:
    path = capture_path
    if variant is not None:
        path = tmp_path / f"variant.{'pcapng' if variant is _in_three_byte_segments else 'pcap'}"
        variant(capture_path, path)
    document = show_json(path, capsys)
    ours = {(e["frame"], i, item["area"], item["unit"], item["column"], item["line"], item["module"])
            for e in document["exchanges"] for i, item in enumerate(item for item in e["items"]
                                                                      if item["kind"] == "nck")}
    fields = ["frame.number", "s7comm.header.rosctr", "s7comm.param.item.nck.area", "s7comm.param.item.nck.unit",
              "s7comm.param.item.nck.column", "s7comm.param.item.nck.line", "s7comm.param.item.nck.module"]
    theirs = set()
    for row in tshark_fields(path, fields):
        if row["s7comm.header.rosctr"] != "1" or not row["s7comm.param.item.nck.area"]:
            continue
        columns = [row[f].split(",") for f in fields[2:]]
        for index, values in enumerate(zip(*columns, strict=True)):
            area, unit, column, line, module = values
            theirs.add((int(row["frame.number"]), index, int(area), int(unit), int(column), int(line),
                        int(module, 16)))
    assert ours and ours == theirs


def test_replay_gives_up_on_a_port_that_never_answers(capture_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A port that accepts TCP and stays silent: one line naming the address after the connection
    request goes unanswered (--connect-timeout), exit 1, instead of a job timeout per job."""
    import socket
    import time

    with socket.create_server(("127.0.0.1", 0)) as silent:
        port = silent.getsockname()[1]
        started = time.monotonic()
        assert main(["trace", "replay", str(capture_path), "--emulator", f"127.0.0.1:{port}",
                     "--connect-timeout", "0.3", "--timeout", "30", "--quiet"]) == 1
        elapsed_s = time.monotonic() - started
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"127.0.0.1:{port}" in err[0] and "connection request" in err[0]
    assert elapsed_s < 15.0  # one short wait for the connection confirm, not the 30 s job timeout
