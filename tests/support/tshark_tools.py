"""tshark as an independent decoder: run it on a capture file and read fields back."""

from __future__ import annotations

import collections
import os
import re
import shutil
import subprocess
from collections.abc import Sequence
from datetime import datetime
from pathlib import Path

import pytest

from nckemu.protocol.addresses import NckAddress, S7AnyAddress, UnsupportedAddress
from nckemu.traces.decode import PUSH, S7_TRANSPORT_SIZES, decode
from nckemu.traces.reader import read_capture

TSHARK = shutil.which("tshark")
requires_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (make test installs "
                                     "Debian's tshark when run as root)")


# What tshark printed, by capture (its path and mtime) and display: tshark's own start-up (~0.25 s, its
# dissectors registered) costs more than most of the captures it reads, so the tests that read several
# sets of fields of one capture ask for them all at once (``read_with``) and the later sets come from here.
_TABLES: dict[tuple[str, int, int, int, str], tuple[dict[str, int], list[list[str]]]] = {}


def tshark_fields(path: Path, fields: list[str], *, port: int = 102, display_filter: str = "s7comm",
                  read_with: Sequence[str] = ()) -> list[dict[str, str]]:
    """One dict per packet that passes the filter; multi-item values stay comma-joined as tshark prints.
    ``read_with`` names fields a later call will ask of the same capture: read in the same tshark run
    (one column each; a column never changes which packets or what the others print) and kept."""
    stat = path.stat()
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size, port, display_filter)
    held = _TABLES.get(key)
    if held is None or not set(fields) <= held[0].keys():
        wanted = list(dict.fromkeys([*fields, *read_with]))
        held = ({field: column for column, field in enumerate(wanted)},
                _run_tshark(path, wanted, port=port, display_filter=display_filter))
        _TABLES[key] = held
    columns, lines = held
    rows = [{field: line[columns[field]] for field in fields if columns[field] < len(line)} for line in lines]
    # tshark prints one line per packet, tab-separated: only a line of one field can be empty, and an
    # empty line is no row
    return [row for row in rows if len(fields) != 1 or row.get(fields[0])]


def _run_tshark(path: Path, fields: list[str], *, port: int, display_filter: str) -> list[list[str]]:
    assert TSHARK is not None
    command = [TSHARK, "-r", str(path), "-Y", display_filter, "-T", "fields", "-E", "separator=\t",
               "-E", "occurrence=a", "-E", "aggregator=,"]
    if port != 102:
        command += ["-d", f"tcp.port=={port},tpkt"]
    for field in fields:
        command += ["-e", field]
    # Times (S7 timestamps) printed in UTC whatever the machine's zone: they are compared as written.
    result = subprocess.run(command, capture_output=True, text=True, timeout=120, check=True,
                            env={**os.environ, "TZ": "UTC"})
    return [line.split("\t") for line in result.stdout.splitlines()]


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
# What assert_fields_as_tshark reads of every frame (a test reading more of the capture asks with these).
ITEM_FIELDS = ["frame.number", "s7comm.param.func", "s7comm.param.userdata.funcgroup", "s7comm.data.ts",
               *ADDRESS_FIELDS.values(), *DATA_FIELDS.values()]
TIMER_COUNTER_AREAS = (0x1C, 0x1D)
_TIMESTAMP = re.compile(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3}")


_S7_NAME = re.compile(r"(?:(?P<db_area>DB|DI)(?P<db>\d+)\.(?P=db_area)|(?P<area>PI|PQ|I|Q|M|C|T))"
                      r"(?P<width>[XBWD])?(?P<byte>\d+)(?:\.(?P<bit>\d))?(?: (?P<type>[A-Z][A-Z_ ]*?))?(?: x(?P<count>\d+))?")
_AREAS = {"DB": 0x84, "DI": 0x85, "PI": 0x80, "PQ": 0x80, "I": 0x81, "Q": 0x82, "M": 0x83, "C": 0x1C, "T": 0x1D}
_WIDTH_TYPES = {None: "BIT", "X": "BIT", "B": "BYTE", "W": "WORD", "D": "DWORD"}


def _fields_from_name(name: str) -> dict[str, int] | None:
    """What a person reads in an S7ANY item's name (``M102.3``, ``DB3.DBD4 REAL``, ``MW100 INT x2``):
    area, DB, byte, bit, type and count, as tshark's fields; None for a name that is not S7 syntax."""
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
    stamp = " ".join(text.split()[:4])
    moment = datetime.strptime(stamp[:stamp.index(".") + 7], "%b %d, %Y %H:%M:%S.%f")
    return moment.isoformat(sep=" ", timespec="milliseconds")


def _tshark_field_by_field(path: Path) -> tuple[dict[int, dict[str, list[object]]], dict[int, list[str]]]:
    """tshark's view of what ``_ours_field_by_field`` gives, per frame."""
    names = {**ADDRESS_FIELDS, **DATA_FIELDS}
    rows = tshark_fields(path, ITEM_FIELDS)
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


def assert_fields_as_tshark(path: Path) -> None:
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
