"""What the emulator's userdata answers carry, as trace show names it and as tshark decodes the same
capture: python-snap7 reads the SZLs the emulator serves, the block list and the clock from a recording
emulator (``serve --record``)."""

from __future__ import annotations

import logging
import re
from pathlib import Path

import pytest
import snap7

from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol import szl
from nckemu.traces.decode import decode
from nckemu.traces.reader import read_capture
from tests.support.tshark_tools import requires_tshark, tshark_fields

READS = [(0x0011, 0x0000), (0x001C, 0x0000), (0x0424, 0x0000), (0x0131, 0x0001), (0x0232, 0x0004)]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("userdata") / "szl.pcapng"
    logging.getLogger("snap7").setLevel(logging.WARNING)
    with EmulatorThread(record_path=path) as emu:
        client = snap7.Client()
        client.connect("127.0.0.1", 0, 2, emu.port)
        try:
            for szl_id, index in READS:
                client.read_szl(szl_id, index)
            client.list_blocks()
            client.get_plc_datetime()
        finally:
            client.disconnect()
    return path


def _answers(path: Path) -> dict[str, str]:
    """Our answer text of each userdata exchange, by its request's text."""
    answers = {}
    for exchange in decode(read_capture(path)):
        if exchange.function == "userdata" and exchange.answer is not None:
            request, _, answer = (" " + exchange.detail).partition(" -> ")
            answers[f"{exchange.service_name}:{request}"] = answer
    return answers


def test_served_szls_are_named(recorded: Path) -> None:
    answers = "\n".join(_answers(recorded).values())
    for szl_id, index in READS:
        assert f"{szl.SZL_NAMES[szl_id]} (SZL 0x{szl_id:04X} index 0x{index:04X})" in answers
    assert "mode RUN" in answers and "max PDU" in answers and "protection key switch" in answers
    assert re.search(r"DB \d+", answers)  # the block list


@requires_tshark
def test_names_match_tshark(recorded: Path) -> None:
    answers = "\n".join(_answers(recorded).values())
    rows = tshark_fields(recorded, ["s7comm.szl.xy11.0001.anz", "s7comm.szl.001c.0001.name",
                                    "s7comm.szl.001c.0002.name", "s7comm.szl.0424.0000.bzu_id.req",
                                    "s7comm.szl.0131.0001.pdu", "s7comm.blockinfo.block_count"])
    order_numbers = {v.strip() for row in rows for v in row["s7comm.szl.xy11.0001.anz"].split(",") if v}
    assert order_numbers and all(f"'{order}'" in answers for order in order_numbers)
    names = {row[f].strip() for row in rows for f in ("s7comm.szl.001c.0001.name", "s7comm.szl.001c.0002.name")
             if row[f]}
    assert names and all(f"'{name}'" in answers for name in names)
    (mode,) = {int(row["s7comm.szl.0424.0000.bzu_id.req"], 0) for row in rows if row["s7comm.szl.0424.0000.bzu_id.req"]}
    assert f"mode {szl.CPU_MODES[mode]}" in answers
    (pdu,) = {row["s7comm.szl.0131.0001.pdu"] for row in rows if row["s7comm.szl.0131.0001.pdu"]}
    assert f"max PDU {pdu}," in answers
    (counts,) = [row["s7comm.blockinfo.block_count"] for row in rows if row["s7comm.blockinfo.block_count"]]
    ours = re.search(r"OB \d+(, \w+ \d+)+", answers)
    assert ours is not None and [int(n) for n in re.findall(r"\d+", ours.group())] == [int(c) for c in counts.split(",")]


def test_an_szl_in_several_parts_is_named_whole_at_its_last_part(tmp_path: Path) -> None:
    """python-snap7 with a 240-byte PDU gets SZL 0x001C (9 records, 314 bytes) in two parts: the first
    names its own records, the next-part answer names all nine."""
    path = tmp_path / "parts.pcapng"
    with EmulatorThread(record_path=path) as emu:
        client = snap7.Client()
        client.set_param(snap7.type.Parameter.PDURequest, 240)
        client.connect("127.0.0.1", 0, 2, emu.port)
        try:
            whole = client.read_szl(0x001C, 0)
        finally:
            client.disconnect()
    assert b"CPU 317-2 PN/DP (NCU PLC)" in bytes(whole.Data)  # record 7: python-snap7 fetched both parts
    details = [e.detail for e in decode(read_capture(path)) if e.function == "userdata"]
    assert "records in this part" in details[0] and "component identification" in details[0]
    assert details[1].startswith("next part of sequence")
    assert "-> last of 2 parts: component identification (SZL 0x001C index 0x0000): 9 records" in details[1]
    assert "index 10: " in details[1]  # the ninth record, carried by the second part only


@requires_tshark
def test_tshark_reads_the_machine_name_and_md18030_in_szl_001c(recorded: Path) -> None:
    """Index 1 (the automation system's name) and index 5 (the serial number) as Wireshark's dissector
    reads them: the machine's name and MD18030, the reserved bytes after them zero."""
    from nckemu.emulator.machine.core import serial_number
    from nckemu.emulator.machine.machine_file import load_machine

    fields = ["s7comm.szl.001c.0001.name", "s7comm.szl.001c.0005.serialn", "s7comm.szl.001c.000x.res"]
    rows = [row for row in tshark_fields(recorded, fields) if row["s7comm.szl.001c.0001.name"]]
    assert len(rows) == 1
    assert rows[0]["s7comm.szl.001c.0001.name"] == load_machine(None).name
    assert rows[0]["s7comm.szl.001c.0005.serialn"] == serial_number(1)
    reserved = rows[0]["s7comm.szl.001c.000x.res"].split(",")
    assert len(reserved) >= 4 and all(field and set(field) <= {"0"} for field in reserved)
