"""Issue 37, addresses and indices: each case a newcomer met, against a running emulator (its S7 face for
`nckemu get/put/vars` and our client, its OPC UA face for asyncua), and docs/addresses.md's names."""

from __future__ import annotations

import asyncio
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from asyncua import ua

from nckemu.catalogue.grammar import NcNodeName, parse_name
from nckemu.cli import main
from nckemu.clients import NckClient
from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.machine.nck.access import HIGHEST_LEVEL, AccessContext
from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol.addresses import S7Area
from tests.support.opcua_tools import connect, two_faces

pytestmark = pytest.mark.timeout(180)
DOC = Path(__file__).resolve().parents[2] / "docs" / "addresses.md"
HIGHEST = AccessContext(level=HIGHEST_LEVEL, client="test")


@pytest.fixture(scope="module")
def faces() -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    with two_faces() as pair:
        yield pair


def _ua_read(face: OpcUaFace, *ids: str) -> list[Any]:
    async def go() -> list[Any]:
        client = await connect(face)
        try:
            ns = await client.get_namespace_index("SinumerikVarProvider")
            return [await client.get_node(ua.NodeId(i, ns)).read_value() for i in ids]
        finally:
            await client.disconnect()
    return asyncio.run(go())


def _cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _get(capsys: pytest.CaptureFixture[str], port: int, *names: str) -> tuple[int, str, str]:
    return _cli(capsys, "get", "--port", str(port), *names)


def test_nc_syntax_btss_and_opcua_name_the_same_r_parameter(faces: tuple[EmulatorThread, OpcUaFace],
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    emulator, face = faces
    assert _cli(capsys, "put", "--port", str(emulator.port), "R3=3.5")[0] == 0
    outs = [_get(capsys, emulator.port, name) for name in
            ("R[u1,4]", "/Channel/Parameter/R[u1,4]", "ns=2;s=/Channel/Parameter/R[u1,4]",
             "/Channel/Parameter/rpa[u1,4]", "R3", "R[3]", "$R[3]", "R3[C1]")]
    assert {out for _, out, _ in outs} == {"R3[C1] = 3.500000\n"}, outs
    assert _ua_read(face, "/Channel/Parameter/R[u1,4]") == [3.5]


def test_a_btss_range_is_an_array_in_every_form(faces: tuple[EmulatorThread, OpcUaFace],
                                                capsys: pytest.CaptureFixture[str]) -> None:
    emulator, face = faces
    assert _cli(capsys, "put", "--port", str(emulator.port), "R[u1,1,#5]=0,1,2,3,4")[0] == 0
    expected = "R0[C1,x5] = [0.0, 1.0, 2.0, 3.0, 4.0]\n"
    for name in ("R[u1,1,5]", "R[u1,1,#5]", "/Channel/Parameter/R[u1,1,5]", "R[0,x5]"):
        assert _get(capsys, emulator.port, name)[1] == expected, name
    assert _ua_read(face, "/Channel/Parameter/R[u1,1,5]", "/Channel/Parameter/R[u1,1,#5]") == [[0.0, 1.0, 2.0, 3.0, 4.0]] * 2
    with NckClient("127.0.0.1", emulator.port) as nck:
        assert nck.get("R[u1,1,5]", "R4") == [[0.0, 1.0, 2.0, 3.0, 4.0], 4.0]


def test_spindle_lines_by_index_spindle_and_btss(faces: tuple[EmulatorThread, OpcUaFace],
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    emulator, _ = faces
    code, out, _ = _cli(capsys, "vars", "actSpeed")
    assert code == 0 and "actSpeed[SP1..SP8] = [0..7]" in out and "/Channel/Spindle/actSpeed[u1,1..8]" in out
    shown = {_get(capsys, emulator.port, name)[1] for name in
             ("actSpeed", "actSpeed[0]", "actSpeed[SP1]", "actSpeed[u1,1]", "/Channel/Spindle/actSpeed[u1,1]",
              "SSP2 actSpeed[SP1,C1]")}
    assert shown == {"SSP2 actSpeed[SP1,C1] = 0.000000 rpm\n"}
    code, out, err = _get(capsys, emulator.port, "actSpeed[1]")
    assert code == 1 and out == ""
    assert "actSpeed[SP2,C1]: not on this machine (BTSS /Channel/Spindle/actSpeed[u1,2])" in err
    assert "channel 1 has 1 spindle: SP1;" in err and "actSpeed[SP1..SP8] or actSpeed[0..7]" in err
    assert "invalid address (0x05)" in err


def test_machine_axis_lines_by_axis_and_index(faces: tuple[EmulatorThread, OpcUaFace],
                                              capsys: pytest.CaptureFixture[str]) -> None:
    emulator, _ = faces
    z1 = emulator.emulator.nck.read(parse_name("actToolBasePos[u1,4]").address, HIGHEST)[0]  # type: ignore[union-attr]
    shown = {_get(capsys, emulator.port, name)[1] for name in
             ("actToolBasePos[AX4]", "actToolBasePos[3]", "actToolBasePos[u1,4]", "actToolBasePos[C1,l4]")}
    assert shown == {f"SMA2 actToolBasePos[AX4,C1] = {z1:.6f} mm\n"}
    code, _, err = _get(capsys, emulator.port, "actToolBasePos[4]")
    assert code == 1 and "actToolBasePos[AX5,C1]: not on this machine" in err
    assert "its machine axes are AX1 X1, AX2 Y1, AX3 SP1, AX4 Z1" in err
    assert "actToolBasePos[AX1..AX31] or actToolBasePos[0..30] (NC, index from 0)" in err
    code, _, err = _get(capsys, emulator.port, "SD43900[AX9]")
    assert code == 1 and "its machine axes are AX1 X1, AX2 Y1, AX3 SP1, AX4 Z1" in err


def test_machine_data_index_counts_from_zero(faces: tuple[EmulatorThread, OpcUaFace],
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """NC syntax counts indices from 0; BTSS and every OPC UA node id (the /NC/ ones too) lines from 1."""
    emulator, face = faces
    for name in ("MD10000[1]", "$MN_AXCONF_MACHAX_NAME_TAB[1]", "MD10000[u1,2]",
                 "/NC/_N_NC_TEA_ACX/$MN_AXCONF_MACHAX_NAME_TAB[2]", "/NC/_N_NC_TEA_ACX/$MN_AXCONF_MACHAX_NAME_TAB[u1,2]"):
        assert _get(capsys, emulator.port, name)[1] == "MD10000 AXCONF_MACHAX_NAME_TAB[1,N1] = Y1\n", name
    assert _get(capsys, emulator.port, "MD10000[0]")[1].endswith("= X1\n")
    assert _ua_read(face, "/NC/_N_NC_TEA_ACX/$MN_AXCONF_MACHAX_NAME_TAB[2]") == ["Y1"]
    assert _ua_read(face, "/NC/_N_NC_TEA_ACX/$MN_AXCONF_MACHAX_NAME_TAB[u1,1]") == ["X1"]


@pytest.mark.parametrize(("name", "words"), [
    ("R[100]", ["index 100 outside R", "R0..R99 (NC, index from 0)", "/Channel/Parameter/R[u1,1..100] (BTSS"]),
    ("R[u1,101]", ["line 101 outside R", "R0..R99"]),
    ("R[u1,0]", ["BTSS lines count from 1", "R0..R99"]),
    ("MD10000[31]", ["index 31 outside", "MD10000[0..30]", "MD10000[u1,1..31]"]),
    ("actToolBasePos[AX32]", ["AX32 outside actToolBasePos", "actToolBasePos[AX1..AX31]"]),
    ("numAlarms[AX4]", ["numAlarms is not per axis", "/Nck/State/numAlarms[u1]"]),
    ("actSpeed[AX1]", ["actSpeed is not per axis", "actSpeed[SP1..SP8]"]),
    ("SD43900[AX40]", ["axes are AX1..AX31"]),
    ("MD10", ["no machine data MD10", "MD10:DWORD"]),
    ("R4[u1]", ["mixes NC syntax", "R[u1,5]"]),
    ("PI0.1", ["byte, word or double word"]),
])
def test_a_refused_name_names_the_valid_range(name: str, words: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = _cli(capsys, "get", "--port", "1", name)  # refused before any connection
    assert code == 1
    for word in words:
        assert word in err, err


def test_get_and_put_take_s7_addresses(faces: tuple[EmulatorThread, OpcUaFace],
                                       capsys: pytest.CaptureFixture[str]) -> None:
    emulator, face = faces
    plc = emulator.emulator.plc
    code, out, err = _cli(capsys, "put", "--port", str(emulator.port), "DB130.DBW0=4660", "MB10=7", "M5.0=1",
                          "DB130.DBD8:REAL=2.5", "DB130.DBW40:INT[3]=-1,2,3")
    assert code == 0, err
    assert plc.read(S7Area.DB, 130, 0, 2) == b"\x12\x34" and plc.read(S7Area.M, 0, 10, 1) == b"\x07"
    assert plc.read_bit(S7Area.M, 0, 5, 0)
    sensor = int.from_bytes(plc.read(S7Area.P, 0, 420, 2), "big", signed=True)
    code, out, err = _get(capsys, emulator.port, "/Plc/DB130.DBW0", "DB130.DBW0", "MB10", "M5.0", "PIW420",
                          "DB130.DBD8:REAL", "DB130.DBW40:INT[3]", "R3")
    assert code == 0, err
    lines = out.splitlines()
    assert lines[:4] == ["DB130.DBW0 = 4660", "DB130.DBW0 = 4660", "MB10 = 7", "M5.0 = True"]
    assert re.fullmatch(r"PIW420 = -?\d+", lines[4]) and abs(int(lines[4].split()[-1]) - sensor) < 50
    assert lines[5:7] == ["DB130.DBD8:REAL = 2.500000", "DB130.DBW40:INT[3] = [-1, 2, 3]"]
    assert _ua_read(face, "/Plc/DB130.DBW0", "/Plc/M5.0", "/Plc/DB130.DBD8:REAL") == [4660, True, 2.5]
    # the library takes them too, mixed with NCK variables in one job
    with NckClient("127.0.0.1", emulator.port) as nck:
        nck.put({"DB130.DBB20": 20, "SD43900[AX4]": 0.25})
        nck.put({"DB130.DBB20:STRING": "hello"})
        assert nck.get("DB130.DBB20:STRING", "SD43900[AX4]", "MW10") == ["hello", 0.25, 0x0700]
    code, _, err = _get(capsys, emulator.port, "DB999.DBD0:REAL")
    assert code == 1 and "DB999 does not exist on the controller" in err and "(0x0A)" in err
    code, _, err = _get(capsys, emulator.port, "DB130.DBW300")
    assert code == 1 and "bytes 300..301 lie beyond the end of DB130" in err
    code, _, err = _cli(capsys, "put", "--port", str(emulator.port), "DB130.DBW0=70000")
    assert code == 1 and "70000 is not a WORD (0..65535)" in err


def test_vars_filters_on_names_and_shows_both_ranges(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    code, out, _ = _cli(capsys, "vars", "--json", "NCKEMU")
    rows = json.loads(out)
    assert code == 0 and rows and all("NCKEMU" in row["name"] or "NCKEMU" in row["number"] for row in rows)
    assert len(rows) == 7
    code, out, _ = _cli(capsys, "vars", "--json", "R4")  # a whole name lists its row
    (row,) = json.loads(out)
    assert row["names"] == {"nc": "R0..R99", "nc_index": "R0..R99", "btss": "/Channel/Parameter/R[u1,1..100]",
                            "opcua": "/Channel/Parameter/R[u1,1..100]"}
    code, out, _ = _cli(capsys, "vars", "/Nckemu/")  # a path pattern matches node ids
    assert code == 0 and "NCKEMU_TC_VALUE" in out and "actToolBasePos" in out
    code, out, _ = _cli(capsys, "vars")
    header, *rows_text = out.splitlines()
    assert "NC (index from 0)" in header and "BTSS (line from 1)" in header
    assert any(line.split()[:4] == ["R", "R", "R0..R99", "/Channel/Parameter/R[u1,1..100]"] for line in rows_text)


def _doc_names() -> list[str]:
    """Every name in the Forms table of docs/addresses.md (its examples and same-address columns)."""
    table = DOC.read_text(encoding="utf-8").split("## Forms", 1)[1].split("\n\n", 2)[1]
    names: list[str] = []
    for line in table.splitlines()[2:]:
        cells = line.split("|")[3:5]
        names += [name for cell in cells for name in re.findall(r"`([^`]+)`", cell) if name != "ns=2;s="]
    return names


def test_every_name_in_docs_addresses_reads() -> None:
    names = _doc_names()
    assert len(names) > 40 and "R[u1,1,#5]" in names and "PIW420" in names
    for name in names:
        parsed = parse_name(name)
        if isinstance(parsed, NcNodeName):
            assert parse_name(str(parsed)).address == parsed.address
