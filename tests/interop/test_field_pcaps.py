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
from tests.interop.tshark_tools import requires_tshark, tshark_fields

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


def _tshark_view(path: Path) -> tuple[set[int], set[int]]:
    """The answers tshark can pair with a job (same TCP stream, the other side, same PDU reference; a job
    takes one answer) and the frames with a push (userdata type 0), by frame number."""
    fields = ["frame.number", "tcp.stream", "tcp.srcport", "tcp.dstport", "s7comm.header.rosctr",
              "s7comm.header.pduref", "s7comm.param.userdata.type"]
    jobs: set[tuple[str, str, str]] = set()
    paired: set[int] = set()
    pushes: set[int] = set()
    for row in tshark_fields(path, fields):
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
    fields = {"alarm": "s7comm.alarm.event_id", "diagnostic": "s7comm.cpu.diag_msg.eventid",
              "blocks": "s7comm.blockinfo.block_count", "szl": "s7comm.data.userdata.szl_id",
              "job": "_ws.col.Info"}
    ours = _ours_by_frame(path)
    rows = tshark_fields(path, ["frame.number", *fields.values()])
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


# ------------------------------------------------------------------ field by field (issue 37)
# What tshark decodes of every item, with the field names it gives them: the item's address (S7ANY:
# syntax ID, transport size, count, DB, area, byte and bit address or a timer/counter's number; NCK:
# area, unit, column, line, module, line count) at the job's frame; each data item's return code,
# transport size, length and bytes at the frame that carries it (write jobs, read answers, cyclic
# data); the S7 timestamps (clock, alarms, diagnostic messages) as dates and times.
ADDRESS_FIELDS = {
    "syntax": "s7comm.param.item.syntaxid", "transport_size": "s7comm.param.item.transp_size",
    "count": "s7comm.param.item.length", "db": "s7comm.param.item.db", "area": "s7comm.param.item.area",
    "byte": "s7comm.param.item.address.byte", "bit": "s7comm.param.item.address.bit",
    "number": "s7comm.param.item.address.number", "nck_area": "s7comm.param.item.nck.area",
    "nck_unit": "s7comm.param.item.nck.unit", "nck_column": "s7comm.param.item.nck.column",
    "nck_line": "s7comm.param.item.nck.line", "nck_module": "s7comm.param.item.nck.module",
    "nck_line_count": "s7comm.param.item.nck.linecount",
}
DATA_FIELDS = {"return_code": "s7comm.data.returncode", "data_transport_size": "s7comm.data.transportsize",
               "length": "s7comm.data.length", "data": "s7comm.resp.data"}
TIMER_COUNTER_AREAS = (0x1C, 0x1D)
_TIMESTAMP = re.compile(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3}")


_S7_NAME = re.compile(r"(?:(?P<db_area>DB|DI)(?P<db>\d+)\.(?P=db_area)|(?P<area>PI|PQ|I|Q|M|C|T))"
                      r"(?P<width>[XBWD])?(?P<byte>\d+)(?:\.(?P<bit>\d))?(?: (?P<type>[A-Z][A-Z_ ]*?))?(?: x(?P<count>\d+))?")
_AREAS = {"DB": 0x84, "DI": 0x85, "PI": 0x80, "PQ": 0x80, "I": 0x81, "Q": 0x82, "M": 0x83, "C": 0x1C, "T": 0x1D}
_WIDTH_TYPES = {None: "BIT", "X": "BIT", "B": "BYTE", "W": "WORD", "D": "DWORD"}


def _fields_from_name(name: str) -> dict[str, int] | None:
    """What a person reads in an S7ANY item's name (``M102.3``, ``DB3.DBD4 REAL``, ``MW100 INT x2``):
    area, DB, byte, bit, type and count, as tshark's fields; None for a name that is not S7 syntax."""
    from nckemu.traces.decode import S7_TRANSPORT_SIZES

    match = _S7_NAME.fullmatch(name)
    if match is None:
        return None
    area = _AREAS[match["db_area"] or match["area"]]
    sizes = {kind: code for code, (kind, _size, _width) in S7_TRANSPORT_SIZES.items()}
    if area in TIMER_COUNTER_AREAS:
        kind = match["type"] or ("COUNTER" if area == 0x1C else "TIMER")
    else:
        kind = match["type"] or _WIDTH_TYPES[match["width"]]
    fields = {"syntax": 0x10, "transport_size": sizes[kind], "count": int(match["count"] or 1),
              "db": int(match["db"] or 0), "area": area}
    if area in TIMER_COUNTER_AREAS:
        fields["number"] = int(match["byte"])
    else:
        fields.update(byte=int(match["byte"]), bit=int(match["bit"] or 0))
    return fields


def _address_fields(address: object, name: str = "") -> dict[str, int]:
    from nckemu.protocol.addresses import NckAddress, S7AnyAddress, UnsupportedAddress

    if isinstance(address, S7AnyAddress) and name and not name.startswith("area "):
        read = _fields_from_name(name)  # the name as printed must carry every field
        assert read is not None, f"{name!r} is not an S7 address"
        return read
    if isinstance(address, S7AnyAddress):
        fields = {"syntax": 0x10, "transport_size": address.transport_size, "count": address.count,
                  "db": address.db_number, "area": address.area}
        if address.area in TIMER_COUNTER_AREAS:
            fields["number"] = address.byte_address << 3 | address.bit_address
        else:
            fields.update(byte=address.byte_address, bit=address.bit_address)
        return fields
    if isinstance(address, NckAddress):
        return {"syntax": address.syntax_id, "nck_area": address.area, "nck_unit": address.unit,
                "nck_column": address.column, "nck_line": address.line, "nck_module": address.module,
                "nck_line_count": address.line_count}
    assert isinstance(address, UnsupportedAddress)
    return {"syntax": address.syntax_id}


def _data_fields(item: object) -> dict[str, object]:
    raw = bytes.fromhex(item.raw)  # type: ignore[attr-defined]
    code, size = item.return_code, item.data_transport_size  # type: ignore[attr-defined]
    fields: dict[str, object] = {"return_code": code, "data_transport_size": size}
    if code in (0x00, 0xFF):
        fields["length"] = len(raw)  # in bytes, as tshark gives it (the wire has bits for BYTE/WORD/INT)
        if raw:
            fields["data"] = raw.hex()
    else:
        fields["length"] = None  # an error item's length is not data's (0A 00 00 04 carries none)
    return fields


def _ours_field_by_field(path: Path) -> tuple[dict[int, dict[str, list[object]]], dict[int, list[str]]]:
    """Per frame, each field's values in the order the items come, and the timestamps the lines show."""
    fields: dict[int, dict[str, list[object]]] = collections.defaultdict(lambda: collections.defaultdict(list))
    times: dict[int, list[str]] = collections.defaultdict(list)
    for exchange in decode(read_capture(path)):
        if exchange.function in ("read", "write") or (exchange.function == "userdata" and exchange.items):
            for item in exchange.items:
                for name, value in _address_fields(item.target, item.name).items():
                    fields[exchange.job.frame][name].append(value)
        if exchange.function == "write":
            for item in exchange.items:
                job_item = {"return_code": 0x00, "data_transport_size": item.data_transport_size,
                            "raw": item.raw}
                for name, value in _data_fields(type("Data", (), job_item)).items():
                    fields[exchange.job.frame][name].append(value)
        carrier = exchange.job.frame if exchange.function == PUSH else \
            exchange.answer.frame if exchange.answer is not None else None
        if carrier is not None and (exchange.function in ("read", "write", PUSH) or exchange.items):
            for item in exchange.items:
                if item.return_code is None:
                    continue
                if exchange.function == "write":
                    fields[carrier]["return_code"].append(item.return_code)
                    continue
                for name, value in _data_fields(item).items():
                    fields[carrier][name].append(value)
        head, _, tail = (" " + exchange.detail).partition(" -> ")
        times[exchange.job.frame].extend(_TIMESTAMP.findall(head))
        if exchange.answer is not None:
            times[exchange.answer.frame].extend(_TIMESTAMP.findall(tail))
    return fields, times


def _tshark_time(text: str) -> str:
    """``Feb  8, 2016 14:51:37.916000000 UTC`` as ``2016-02-08 14:51:37.916``."""
    from datetime import datetime

    stamp = " ".join(text.split()[:4])
    moment = datetime.strptime(stamp[:stamp.index(".") + 7], "%b %d, %Y %H:%M:%S.%f")
    return moment.isoformat(sep=" ", timespec="milliseconds")


def _tshark_field_by_field(path: Path) -> tuple[dict[int, dict[str, list[object]]], dict[int, list[str]]]:
    """tshark's view of what ``_ours_field_by_field`` gives, per frame."""
    names = {**ADDRESS_FIELDS, **DATA_FIELDS}
    rows = tshark_fields(path, ["frame.number", "s7comm.param.func", "s7comm.param.userdata.funcgroup",
                                "s7comm.data.ts", *names.values()])
    fields: dict[int, dict[str, list[object]]] = {}
    times: dict[int, list[str]] = {}
    for row in rows:
        frame = int(row["frame.number"])
        stamps = [_tshark_time(v) for v in re.split(r",(?=[A-Z][a-z]{2} )", row["s7comm.data.ts"]) if v]
        if stamps:
            times[frame] = stamps
        functions = set(filter(None, row["s7comm.param.func"].split(",")))
        groups = set(filter(None, row["s7comm.param.userdata.funcgroup"].split(",")))
        # items of read/write jobs and answers and of cyclic services; other userdata (SZL, alarms, the
        # clock) reuse these fields for their own parts, compared by their contents above
        cyclic = groups == {"2"}
        if not (functions & {"0x04", "0x05"} or cyclic):
            continue
        values: dict[str, list[object]] = {name: [int(v, 0) if name != "data" else v for v in row[field].split(",") if v]
                                           for name, field in names.items()}
        if cyclic:  # the userdata's own data header comes before the items
            for name in ("return_code", "data_transport_size", "length"):
                values[name] = values[name][1:]
        if len(values["length"]) == len(values["return_code"]):
            values["length"] = [length if code in (0x00, 0xFF) else None
                                for length, code in zip(values["length"], values["return_code"], strict=True)]
        values = {name: found for name, found in values.items() if found}
        if values:
            fields[frame] = values
    return fields, times


@requires_tshark
@pytest.mark.parametrize("path", CAPTURES, ids=_ids)
def test_every_item_field_as_tshark_decodes_it(path: Path) -> None:
    """Frame by frame: each item's address, each data item's return code, transport size, length and
    bytes, and every S7 timestamp's date and time, as tshark decodes them. Where a capture holds a
    segment twice, tshark decodes the first copy and we the one that completes the PDU (a frame tshark
    marks as a retransmission): such a frame of ours is compared with the nearest earlier frame that
    tshark alone decoded; one tshark does not decode at all (a spurious retransmission of an answer
    whose first copy the capture lost) is ours alone."""
    ours, our_times = _ours_field_by_field(path)
    theirs, their_times = _tshark_field_by_field(path)
    for frame in sorted(set(our_times) | set(their_times)):
        assert sorted(our_times.get(frame, [])) == sorted(their_times.get(frame, [])), f"frame {frame}: times"
    ours = {frame: {name: v for name, v in fields.items() if v} for frame, fields in ours.items()}
    ours = {frame: fields for frame, fields in ours.items() if fields}
    retransmitted = {int(row["frame.number"]) for row in tshark_fields(
        path, ["frame.number"], display_filter="tcp.analysis.retransmission or tcp.analysis.spurious_retransmission")}
    only_ours = sorted(set(ours) - set(theirs))
    only_theirs = sorted(set(theirs) - set(ours))
    pairs = [(frame, frame) for frame in sorted(set(ours) & set(theirs))]
    for frame in only_ours:
        assert frame in retransmitted, f"frame {frame}: items tshark does not decode: {dict(ours[frame])}"
        earlier = [f for f in only_theirs if f < frame]
        if earlier:
            only_theirs.remove(earlier[-1])
            pairs.append((frame, earlier[-1]))
    assert not only_theirs, f"frames {only_theirs[:5]}: items we do not decode: {theirs[only_theirs[0]]}"
    for mine, their in pairs:
        assert dict(ours[mine]) == theirs[their], f"frame {their} (ours {mine}): {dict(ours[mine])} != {theirs[their]}"
