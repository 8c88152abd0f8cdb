"""What real S7 devices send (our own corpus, ``field_corpus.py``): every answer paired or shown as a push,
every frame's function named as tshark names it, and replay skipping what it cannot send."""

from __future__ import annotations

import asyncio
import json
import re
import struct
from pathlib import Path

import pytest

from nckemu.cli import main
from nckemu.clients.async_client import AsyncNckClient
from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol import s7
from nckemu.traces.decode import PUSH, S7COMM_PLUS, Exchange, decode
from nckemu.traces.reader import read_capture
from nckemu.traces.replay import replay
from tests.support.tshark_tools import requires_tshark, tshark_fields
from tests.traces.field_corpus import Expected, write_field_corpus


@pytest.fixture(scope="module")
def corpus(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Expected]:
    path = tmp_path_factory.mktemp("field") / "field.pcapng"
    return path, write_field_corpus(path)


def _decoded(path: Path) -> tuple[list[Exchange], list[str]]:
    capture = read_capture(path)
    return decode(capture), capture.problems


def test_every_answer_is_paired_and_every_push_shown(corpus: tuple[Path, Expected]) -> None:
    path, expected = corpus
    exchanges, problems = _decoded(path)
    assert problems == []
    pushes = [e for e in exchanges if e.function == PUSH]
    plus = [e for e in exchanges if e.function == S7COMM_PLUS]
    paired = [e for e in exchanges if e not in pushes and e not in plus]
    assert all(e.answer is not None for e in paired)
    assert len(paired) == expected.exchanges and len(pushes) == expected.pushes
    assert all(p.pdu_ref == 0 and not p.job.from_client and p.answer is None for p in pushes)
    assert {e.service for e in exchanges if e.function in ("userdata", PUSH)} == expected.userdata_services
    # The PLC's jobs in a download, answered by the programming device, with PDU references of their own.
    plc_jobs = [e for e in paired if not e.job.from_client]
    assert len(plc_jobs) == expected.plc_jobs
    assert [e.function for e in plc_jobs] == ["download block", "download ended"]
    assert all(e.answer is not None and e.answer.from_client for e in plc_jobs)
    assert plc_jobs[0].detail == "_0A00001P (DB 1, passive) -> 14 bytes"
    # One line per S7comm-plus connection, then the classic frames go on.
    assert [(e.connection, e.detail) for e in plus] == [
        (connection, f"protocol 0x72, not decoded ({count} frames)")
        for connection, count in expected.s7comm_plus_frames.items()]
    assert any(e.connection == 4 and e.function == "read" and e.answer for e in exchanges)


def test_error_items_with_a_length_carry_no_data(corpus: tuple[Path, Expected]) -> None:
    exchanges, _problems = _decoded(corpus[0])
    reads = [e for e in exchanges if e.function == "read"]
    missing = reads[0]
    assert [(i.return_code, i.raw, i.value) for i in missing.items] == [(0x0A, "", None)] * 5
    assert [(i.return_code, i.raw) for i in reads[1].items] == [(0x0A, ""), (0xFF, "1234"), (0x0A, "")]
    # The codec our clients read answers with (NckClient, the PLC clients) takes them the same way.
    answer = s7.parse_read_var_response(b"\x04\x05", b"\x0a\x00\x00\x04" * 5)
    assert answer.items == (s7.DataItem(0x0A, 0, b""),) * 5
    mixed = s7.parse_read_var_response(b"\x04\x03", b"\x0a\x00\x00\x04\xff\x04\x00\x08\x2a\x00\x05\x00\x00\x10")
    assert mixed.items == (s7.DataItem(0x0A, 0, b""), s7.DataItem(0xFF, 0x04, b"\x2a"), s7.DataItem(0x05, 0, b""))


def test_show_prints_no_warning(corpus: tuple[Path, Expected], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["trace", "show", str(corpus[0])]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert "answer without a job" not in out and "[no answer]" not in out
    assert "push     CPU functions -> ALARM_S indication" in out
    assert "_INSE(0A00001P = DB 1 passive)" in out and "_DELE(0A00002P = DB 2 passive, 0A00003P = DB 3 passive)" in out
    assert "download block _0A00001P (DB 1, passive) -> 14 bytes  (job from the PLC)" in out
    assert "S7comm-plus protocol 0x72, not decoded (6 frames)" in out
    assert main(["trace", "show", str(corpus[0]), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    services = {e["service"] for e in document["exchanges"]}
    assert {"Read Var", "Download block", "PI-Service", "CPU functions -> Read SZL"} <= services
    assert {e["sender"] for e in document["exchanges"] if e["function"] == "download ended"} == {"server"}


def _tshark_info(exchange: Exchange, answer: bool) -> str:
    """The part of tshark's Info column that names the frame's function, as we name it."""
    if exchange.function in ("userdata", PUSH):
        group, _, subfunction = exchange.service.partition(" -> ")
        names = f"[{group}]" + (f" -> [{subfunction}]" if subfunction else "")
        if answer:
            return f"ROSCTR:[Userdata] Function:[Response] -> {names}"
        if exchange.function == PUSH:
            return f"ROSCTR:[Userdata] Function:[Push-Res] -> {names}"
        kind = "Push-Req" if exchange.job.data[15] >> 4 == 0 else "Request"  # pyS7 sends its SZL reads as type 0
        return f"ROSCTR:[Userdata] Function:[{kind}] -> {names}"
    return f"ROSCTR:[{'Ack_Data' if answer else 'Job     '}] Function:[{exchange.service_name}]"


_BLOCK = re.compile(r"= (\w+) (\d+)")


def _tshark_pi(detail: str) -> str:
    """Our PI detail as tshark's Info shows it: ``_INSE(0A00001P = DB 1 passive)`` is ``_INSE(DB1)``."""
    service, _, arguments = detail.partition("(")
    if service in ("_INSE", "_DELE"):
        names = [f"{kind}{number}" for kind, number in _BLOCK.findall(arguments)]
        return f"{service}({', '.join(names)})"
    return detail


@requires_tshark
def test_each_frame_is_named_as_tshark_names_it(corpus: tuple[Path, Expected]) -> None:
    path, _expected = corpus
    exchanges, _problems = _decoded(path)
    info = {int(row["frame.number"]): row["_ws.col.Info"]
            for row in tshark_fields(path, ["frame.number", "_ws.col.Info"], display_filter="s7comm")}
    named = set()
    for exchange in exchanges:
        if exchange.function == S7COMM_PLUS:
            assert exchange.job.frame not in info  # tshark has no S7comm-plus dissector here: COTP data
            continue
        frames = [(exchange.job.frame, False)] + ([(exchange.answer.frame, True)] if exchange.answer else [])
        for frame, answer in frames:
            assert info[frame].startswith(_tshark_info(exchange, answer)), (frame, info[frame], exchange)
            named.add(frame)
        if exchange.function == "PI":
            assert info[exchange.job.frame].endswith(f" -> {_tshark_pi(exchange.detail)}")
    assert named == set(info)  # every S7comm frame tshark sees is one we paired or showed


def test_replay_skips_pushes_block_transfers_and_s7comm_plus(corpus: tuple[Path, Expected],
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    path, expected = corpus
    capture = read_capture(path)
    with EmulatorThread(None) as emulator:
        report = replay(capture, "127.0.0.1", emulator.port, timeout_s=2.0)
    assert report.skipped == {"pushes": expected.pushes, "block transfers": expected.block_transfers,
                              "S7comm-plus frames": expected.client_s7comm_plus_frames}
    assert report.jobs == expected.exchanges - expected.block_transfers
    assert main(["trace", "replay", str(path), "--spawn", "--quiet"]) in (0, 1)
    assert f"not replayed: {expected.pushes} pushes, {expected.block_transfers} block transfers, " \
           f"{expected.client_s7comm_plus_frames} S7comm-plus frames" in capsys.readouterr().out


def test_our_client_takes_error_items_with_a_length(monkeypatch: pytest.MonkeyPatch) -> None:
    """NckClient's GET against an answer as an S7-300 gives it: error items ``0A 00 00 04``, no data, and a
    good value after them."""
    async def answer(_self: AsyncNckClient, _what: str, _operation: object) -> bytes:
        data = b"\x0a\x00\x00\x04" * 2 + b"\xff\x09\x00\x08" + struct.pack("<d", 2.5)
        return s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, 1, b"\x04\x03", data))

    monkeypatch.setattr(AsyncNckClient, "_on_connection", answer)
    results = asyncio.run(AsyncNckClient("127.0.0.1").get_items("R1", "R2", "R3"))
    assert [(r.return_code, r.value) for r in results] == [(0x0A, None), (0x0A, None), (0xFF, 2.5)]
