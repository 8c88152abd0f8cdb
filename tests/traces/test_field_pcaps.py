"""The public S7comm captures in ../shared/field/pcaps (40 files: STEP 7, TIA Portal, WinCC, snap7,
libnodave, HMIs and an attacker against S7-300/400/1200/1500; several with lost segments), read in
place, never copied: no traceback, no S7comm answer left undecoded, every answer tshark pairs with its
job paired by us too, and every push shown as a push. Skips when the captures are absent."""

from __future__ import annotations

import collections
import re
from collections import Counter
from pathlib import Path

import pytest

from nckemu.traces.decode import PUSH, decode
from nckemu.traces.reader import read_capture
from tests.conftest import SHARED
from tests.support.tshark_tools import ITEM_FIELDS, assert_fields_as_tshark, requires_tshark, tshark_fields

PCAPS = SHARED / "field" / "pcaps"
CAPTURES = sorted(p for p in PCAPS.glob("*/*") if p.suffix in (".pcap", ".pcapng")) if PCAPS.is_dir() else []
UNDECODED = ("not decoded", "not an S7 PDU")


def _ids(path: Path) -> str:
    return f"{path.parent.name}/{path.name}"


pytestmark = pytest.mark.skipif(not CAPTURES, reason=f"{PCAPS} is absent (../shared/field/pcaps)")


@pytest.mark.parametrize("path", CAPTURES, ids=_ids)
def test_decodes_without_undecoded_answers(path: Path) -> None:
    capture = read_capture(path)
    exchanges = decode(capture)
    assert exchanges
    answered_problems = [p for p in capture.problems if any(text in p for text in UNDECODED)]
    assert not answered_problems
    assert not [p for p in capture.problems if "answer without a job" in p]


PAIRING_FIELDS = ["frame.number", "tcp.stream", "tcp.srcport", "tcp.dstport", "s7comm.header.rosctr",
                  "s7comm.header.pduref", "s7comm.param.userdata.type"]
CONTENT_FIELDS = {"alarm": "s7comm.alarm.event_id", "diagnostic": "s7comm.cpu.diag_msg.eventid",
                  "blocks": "s7comm.blockinfo.block_count", "szl": "s7comm.data.userdata.szl_id",
                  "job": "_ws.col.Info"}
# The three tests read these of each capture; one tshark run reads them all (tshark's start-up is most of it).
EVERY_FIELD = [*PAIRING_FIELDS, *CONTENT_FIELDS.values(), *ITEM_FIELDS]


def _tshark_view(path: Path) -> tuple[set[int], set[int]]:
    """The answers tshark can pair with a job (same TCP stream, the other side, same PDU reference; a job
    takes one answer) and the frames with a push (userdata type 0), by frame number."""
    jobs: set[tuple[str, str, str]] = set()
    paired: set[int] = set()
    pushes: set[int] = set()
    for row in tshark_fields(path, PAIRING_FIELDS, read_with=EVERY_FIELD):
        rosctrs = row["s7comm.header.rosctr"].split(",")
        refs = row["s7comm.header.pduref"].split(",")
        types = collections.deque(row["s7comm.param.userdata.type"].split(","))
        frame = int(row["frame.number"])
        for rosctr, ref in zip(rosctrs, refs, strict=False):
            kind = types.popleft() if rosctr == "7" and types else ""
            if rosctr == "1" or (rosctr == "7" and kind == "4"):
                jobs.add((row["tcp.stream"], row["tcp.srcport"], ref))
            elif rosctr in ("2", "3") or (rosctr == "7" and kind == "8"):
                key = (row["tcp.stream"], row["tcp.dstport"], ref)
                if key in jobs:
                    jobs.discard(key)
                    paired.add(frame)
            elif rosctr == "7" and kind == "0":
                pushes.add(frame)
    return paired, pushes


@requires_tshark
@pytest.mark.parametrize("path", CAPTURES, ids=_ids)
def test_pairs_what_tshark_pairs_and_shows_pushes(path: Path) -> None:
    exchanges = decode(read_capture(path))
    answered = {e.answer.frame for e in exchanges if e.answer is not None}
    shown = {e.job.frame for e in exchanges if e.function == PUSH or e.answer is not None}
    paired, pushes = _tshark_view(path)
    assert paired <= answered, sorted(paired - answered)[:10]
    assert pushes <= shown, sorted(pushes - shown)[:10]


def _ours_by_frame(path: Path) -> dict[str, dict[int, list[str]]]:
    """Alarm event IDs, diagnostic event IDs and block counts as our lines name them, by frame (the
    request's part of an exchange's text at the job's frame, the answer's part at the answer's)."""
    found: dict[str, dict[int, list[str]]] = {"alarm": {}, "diagnostic": {}, "blocks": {}, "szl": {}, "job": {},
                                              "szl_first_part": {}}
    for exchange in decode(read_capture(path)):
        head, _, tail = (" " + exchange.detail).partition(" -> ")
        parts = [(exchange.job.frame, head)]
        if exchange.answer is not None:
            parts.append((exchange.answer.frame, tail))
        for frame, text in parts:
            alarm = re.findall(r"EventID=0x([0-9a-f]{8})", text)
            diagnostic = re.findall(r"EventID=0x([0-9a-f]{4}) OB", text)
            blocks = re.findall(r"(?:^|, )(?:OB|DB|SDB|FC|SFC|FB|SFB) (\d+)", text) if "List blocks" in \
                exchange.service_name and "of type" not in exchange.service_name else []
            szl_ids = re.findall(r"SZL 0x([0-9A-F]{4}) index", text)
            jobs = re.findall(r"JobID=(\d+)", text)
            szl_kind = "szl_first_part" if " in this part" in text else "szl"
            for kind, values in (("alarm", alarm), ("diagnostic", diagnostic), ("blocks", blocks), (szl_kind, szl_ids),
                                 ("job", jobs)):
                if values:
                    found[kind].setdefault(frame, []).extend(int(v) if kind in ("blocks", "job") else int(v, 16)
                                                             for v in values)
    return found


@requires_tshark
@pytest.mark.parametrize("path", CAPTURES, ids=_ids)
def test_contents_as_tshark_reads_them(path: Path) -> None:
    """Alarm event IDs, diagnostic event IDs, block counts and cyclic job IDs, frame by frame, and the
    SZL IDs of requests and answers, as tshark gives them."""
    fields = CONTENT_FIELDS
    ours = _ours_by_frame(path)
    rows = tshark_fields(path, ["frame.number", *fields.values()], read_with=EVERY_FIELD)
    for kind, name in fields.items():
        if kind == "job":  # tshark gives a cyclic job's ID in the Info column only (JobID=N)
            theirs = {int(row["frame.number"]): [int(v) for v in re.findall(r"JobID=(\d+)", row[name])]
                      for row in rows if "JobID=" in row[name]}
        else:
            theirs = {int(row["frame.number"]): [int(v, 0) for v in row[name].split(",")] for row in rows if row[name]}
        if kind == "szl":  # an answer in parts: tshark names the SZL at the last part, we there and at the first
            assert {f: sorted(v) for f, v in ours[kind].items()} == {f: sorted(v) for f, v in theirs.items()}, kind
            first_parts = Counter(v for values in ours["szl_first_part"].values() for v in values)
            assert not first_parts - Counter(v for values in theirs.values() for v in values), "a part without its end"
            continue
        assert {f: sorted(v) for f, v in ours[kind].items()} == {f: sorted(v) for f, v in theirs.items()}, kind


@requires_tshark
@pytest.mark.parametrize("path", CAPTURES, ids=_ids)
def test_every_item_field_as_tshark_decodes_it(path: Path) -> None:
    """Frame by frame: each item's address (its printed name read back), each data item's return
    code, transport size, length and bytes, and every S7 timestamp's date and time, as tshark decodes
    them (issue 37: the clock's year, bit addresses and transport sizes were shown otherwise)."""
    assert_fields_as_tshark(path)
