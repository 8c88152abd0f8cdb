"""Drives and 828D tool data over the wire (issue 32): python-snap7 sends LSC's items as raw PDUs, our
client reads them by name, ``trace show`` names the recorded items and ``nckemu vars`` lists them.
The request bytes are LSC's (tests/emulator/faces/s7/test_drives_tools_828d.py names the facts)."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest
import snap7

from nckemu.catalogue.names import Variable
from nckemu.clients.sync import NckClient
from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol.addresses import NckAddress, NckType

# r0037 index 20 as a collector sends it (area V, unit 1, column 37, line 21, motor module): past the
# last index, so the grammar refuses the name; sent raw, the controller answers 0x05.
PAST_R0037 = Variable(NckAddress(area=5, unit=1, column=37, line=21, module=0x82, line_count=1), NckType.REAL4,
                      None, "r0037 line 21")
LATHE = Path(__file__).resolve().parents[4] / "fixtures" / "machines" / "lathe_828d.toml"


def item(au: int, column: int, line: int, module: int, count: int = 1) -> bytes:
    return bytes([0x12, 0x08, 0x82, au]) + struct.pack(">HHBB", column, line, module, count)


# The twelve reads the 828D collector made that nckemu refused before issue 32 (drive 1 = unit 1).
LSC_ITEMS = {
    "r0026": item(0xA1, 26, 1, 0x82), "r0030": item(0xA1, 30, 1, 0x82), "r0032": item(0xA1, 32, 1, 0x82),
    "r0035": item(0xA1, 35, 1, 0x82), "r0037[1]": item(0xA1, 37, 2, 0x82),
    "CU p0115": item(0xA1, 115, 1, 0x80), "infeed r0032": item(0xA1, 32, 1, 0x81),
    "H number": item(0x41, 0x1B6, 1, 0x7F), "tool X": item(0x41, 0x71, 1, 0x7F), "tool Z": item(0x41, 0x73, 1, 0x7F),
    "T1 H": item(0x81, 1, 26, 0x14), "T1 teeth": item(0x81, 1, 34, 0x14),
}
SIZES = {"H number": 4, "tool X": 8, "tool Z": 8, "T1 H": 8, "T1 teeth": 8}


def read(client: snap7.Client, *items: bytes) -> list[tuple[int, bytes]]:
    parameter = bytes([0x04, len(items)]) + b"".join(items)
    answer = bytes(client.iso_exchange_buffer(bytearray(
        struct.pack(">BBHHHH", 0x32, 1, 0, 0x0014, len(parameter), 0) + parameter)))
    assert answer[1] == 3 and answer[10:12] == b"\x00\x00"
    offset, out = 14, []
    for index in range(len(items)):
        rc, length = answer[offset], struct.unpack(">H", answer[offset + 2:offset + 4])[0]
        out.append((rc, answer[offset + 4:offset + 4 + length]))
        offset += 4 + length + (length % 2 if index < len(items) - 1 else 0)
    return out


def snap7_client(port: int) -> snap7.Client:
    client = snap7.Client()
    client.local_tsap = 0x0400
    client.connection_type = 0x0D
    client.connect("127.0.0.1", 0, 4, port)
    return client


@pytest.mark.parametrize("machine", [None, LATHE], ids=["default", "828d"])
def test_every_refused_read_is_answered_typed(machine: Path | None) -> None:
    with EmulatorThread(machine) as emu:
        client = snap7_client(emu.port)
        try:
            answers = dict(zip(LSC_ITEMS, read(client, *LSC_ITEMS.values()), strict=True))
        finally:
            client.disconnect()
    for name, (rc, data) in answers.items():
        assert rc == 0xFF and len(data) == SIZES.get(name, 4), name
        if SIZES.get(name, 4) == 4 and name != "H number":
            value = struct.unpack(">f", data)[0]   # drive values: big-endian REAL4
            assert -300.0 < value < 1000.0, (name, value)


def test_our_client_names_recorded_items_and_trace_show_names_them(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    from nckemu.cli import main

    capture = tmp_path / "drives.pcapng"
    with EmulatorThread(LATHE, record_path=capture) as emu, NckClient("127.0.0.1", emu.port) as nck:
        emu.call(lambda: emu.nck.set_sensor_temperature("spindle_motor", 55.25))
        assert nck.get("/DriveVsa/Drive/r0035[u1]") == [55.25]
        assert nck.get("/DriveVsa/DC/R0026[u1]") == [540.0]
        # r0037 index 4 (interior): BTSS line 5 (docs/addresses.md: NC indices from 0, BTSS lines from 1)
        assert nck.get("DRV_r0037[u2,5]") == [pytest.approx(24.0 + 30.0 * 0.4 * 0.02)]
        assert nck.get("actHNumberFanuc32") == [1]
        assert nck.get("actOriToolLength1", "actOriToolLength3") == [pytest.approx(32.51), pytest.approx(47.98)]
        # bad input: no drive 9, r0037 index 20, a write to r0035 (each its return code), and on we read
        results = nck.get_items("/DriveVsa/Drive/r0035[u9]", PAST_R0037)
        assert [r.return_code for r in results] == [0x0A, 0x05]
        (written,) = nck.put_items({"/DriveVsa/Drive/r0035[u1]": 1.0})
        assert written.return_code == 0x03
        assert nck.get("/DriveVsa/Drive/r0035[u1]") == [55.25]
    assert main(["trace", "show", str(capture)]) == 0
    shown = capsys.readouterr().out
    for name in ("DRV_r0035[V1]", "DRV_r0026[V1]", "DRV_r0037[4,V2]", "actHNumberFanuc32[C1]",
                 "actOriToolLength1[C1]"):
        assert name in shown, name


def test_nckemu_vars_lists_the_drive_parameters(capsys: pytest.CaptureFixture[str]) -> None:
    from nckemu.cli import main

    assert main(["vars", "/DriveVsa/Drive/r0035[u3]", "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert (row["name"], row["number"], row["areas"], row["module"], row["column"], row["type"]) == \
        ("DRV_r0035", "r0035", ["V"], 0x82, 35, "REAL4")
    assert main(["vars", "r0032"]) == 0
    out = capsys.readouterr().out
    assert "DRV_r0032" in out and "INF_r0032" in out and "V 0x81 col 32" in out


def test_tshark_decodes_the_drive_items_and_their_answers(tmp_path: Path) -> None:
    """The recorded job and answer of LSC's drive reads, as tshark (an independent decoder) reads them."""
    from tests.support.tshark_tools import TSHARK, tshark_fields

    if TSHARK is None:
        pytest.skip("tshark is not installed")
    capture = tmp_path / "drives.pcapng"
    with EmulatorThread(LATHE, record_path=capture) as emu:
        client = snap7_client(emu.port)
        try:
            read(client, LSC_ITEMS["r0035"], LSC_ITEMS["CU p0115"], item(0xA8, 35, 1, 0x82))
        finally:
            client.disconnect()
    rows = tshark_fields(capture, ["s7comm.header.rosctr", "s7comm.param.item.nck.area", "s7comm.param.item.nck.unit",
                                   "s7comm.param.item.nck.column", "s7comm.param.item.nck.module",
                                   "s7comm.data.returncode", "s7comm.data.length", "_ws.malformed"])
    (job,) = [r for r in rows if r["s7comm.header.rosctr"] == "1" and r["s7comm.param.item.nck.area"]]
    assert (job["s7comm.param.item.nck.area"], job["s7comm.param.item.nck.unit"],
            job["s7comm.param.item.nck.column"], job["s7comm.param.item.nck.module"]) == \
        ("5,5,5", "1,1,8", "35,115,35", "0x82,0x80,0x82")
    (answer,) = [r for r in rows if r["s7comm.header.rosctr"] == "3" and r["s7comm.data.returncode"]]
    assert answer["s7comm.data.returncode"] == "0xff,0xff,0x0a" and not answer["_ws.malformed"]
    assert answer["s7comm.data.length"].split(",")[:2] == ["4", "4"]
