"""Every variable of the catalogue, read over the wire and recorded: each answer item is a success with
the value bytes its type and length give, and tshark decodes every job and answer without "malformed",
naming the same area, unit, column, line and module we asked for."""

from __future__ import annotations

import subprocess
from pathlib import Path

from nckemu.catalogue import load_table
from nckemu.clients import NckClient
from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol.addresses import NckAddress, NckArea, NckType
from tests.support.tshark_tools import TSHARK, requires_tshark, tshark_fields

MAX_ITEMS = 8  # NumVar of FB2
# What the answer may hold: python-snap7's default PDU (480) less the headers (14) and 4 bytes per item.
ANSWER_VALUE_BYTES = 480 - 14 - 4 * MAX_ITEMS


def _batches() -> list[list[NckAddress]]:
    """Every variable at line 1 of its first unit in each of its areas (axis 4 = Z1 of the default
    machine), in jobs whose answers fit the PDU."""
    batches: list[list[NckAddress]] = [[]]
    size = 0
    for spec in load_table():
        value_bytes = spec.string_length or 0 if spec.nck_type == NckType.STRING else spec.nck_type.size_bytes
        for area in sorted(spec.areas):
            unit = 4 if area == NckArea.A else 1
            if len(batches[-1]) == MAX_ITEMS or size + value_bytes > ANSWER_VALUE_BYTES:
                batches.append([])
                size = 0
            batches[-1].append(NckAddress(area, unit, spec.column, 1, spec.module, 1))
            size += value_bytes
    return batches


@requires_tshark
def test_every_catalogue_variable_reads_and_tshark_agrees(tmp_path: Path) -> None:
    capture = tmp_path / "catalogue.pcapng"
    batches = _batches()
    addresses = [address for batch in batches for address in batch]
    failed = []
    with EmulatorThread(record_path=capture) as emu, NckClient("127.0.0.1", emu.port) as client:
        for batch in batches:
            for result in client.get_items(*batch):
                if result.return_code != 0xFF:
                    failed.append((str(result.variable), hex(result.return_code)))
                elif result.variable.nck_type == NckType.STRING:
                    assert isinstance(result.value, str)
    assert failed == []
    assert TSHARK is not None
    malformed = subprocess.run([TSHARK, "-r", str(capture), "-Y", "s7comm && (_ws.malformed || _ws.expert.severity >= 6291456)"],
                               capture_output=True, text=True, timeout=120, check=True)
    assert malformed.stdout.strip() == ""
    fields = ["s7comm.header.rosctr", "s7comm.param.item.nck.area", "s7comm.param.item.nck.unit",
              "s7comm.param.item.nck.column", "s7comm.param.item.nck.line", "s7comm.param.item.nck.module",
              "s7comm.data.returncode"]
    rows = tshark_fields(capture, fields)
    seen = set()
    for row in rows:
        if row["s7comm.header.rosctr"] == "1" and row["s7comm.param.item.nck.column"]:
            columns = zip(*(row[f"s7comm.param.item.nck.{key}"].split(",")
                            for key in ("area", "unit", "column", "line", "module")), strict=True)
            seen.update(tuple(int(value, 0) for value in item) for item in columns)
        if row["s7comm.header.rosctr"] == "3" and row["s7comm.data.returncode"]:
            assert set(row["s7comm.data.returncode"].split(",")) == {"0xff"}
    asked = {(a.area, a.unit, a.column, a.line, a.module) for a in addresses}
    assert asked <= seen
