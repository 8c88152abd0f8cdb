"""Issue 14 part 2 with real clients: python-snap7 (sync and async), pys7 and node-snap7 against the
emulator on 127.0.0.1 read the communication and protection SZLs, list blocks and the PLC clock."""

from __future__ import annotations

import asyncio
import json
import logging
import os
import shutil
import subprocess
from datetime import datetime, timedelta
from pathlib import Path

import pytest
import snap7

from nckemu.emulator.runner import EmulatorThread


def _close_to_now(moment: datetime) -> bool:
    return abs(moment - datetime.now()) < timedelta(seconds=30)


def test_python_snap7_sync_reads_cp_info_protection_blocks_and_clock(emulator: EmulatorThread) -> None:
    logging.getLogger("snap7").setLevel(logging.WARNING)
    client = snap7.Client()
    client.connect("127.0.0.1", 0, 2, emulator.port)
    try:
        info = client.get_cp_info()
        assert (info.MaxPduLength, info.MaxConnections, info.MaxMpiRate, info.MaxBusRate) == (960, 16, 12, 12)
        protection = client.get_protection()
        assert (protection.sch_schal, protection.sch_par, protection.sch_rel, protection.bart_sch,
                protection.anl_sch) == (1, 0, 1, 2, 0)
        blocks = client.list_blocks()
        assert blocks.DBCount == len(emulator.plc.data_blocks) and blocks.OBCount == 0 and blocks.FBCount == 0
        assert _close_to_now(client.get_plc_datetime())
        # the connection is still good after all four
        assert client.get_cpu_info().ModuleTypeName
    finally:
        client.disconnect()


def test_python_snap7_async_reads_cp_info_protection_blocks_and_clock(emulator: EmulatorThread) -> None:
    from snap7.async_client import AsyncClient

    async def run() -> tuple[object, object, object, datetime]:
        client = AsyncClient()
        await client.connect("127.0.0.1", 0, 2, emulator.port)
        try:
            return (await client.get_cp_info(), await client.get_protection(), await client.list_blocks(),
                    await client.get_plc_datetime())
        finally:
            await client.disconnect()

    info, protection, blocks, moment = asyncio.run(run())
    assert info.MaxPduLength == 960  # type: ignore[attr-defined]
    assert protection.sch_rel == 1  # type: ignore[attr-defined]
    assert blocks.DBCount == len(emulator.plc.data_blocks)  # type: ignore[attr-defined]
    assert _close_to_now(moment)


def test_python_snap7_unserved_userdata_is_an_error_not_a_hangup(emulator: EmulatorThread) -> None:
    """list_blocks_of_type (group 3, subfunction 2) is not served: an error answer, the connection goes on."""
    client = snap7.Client()
    client.connect("127.0.0.1", 0, 2, emulator.port)
    try:
        with pytest.raises(Exception):  # noqa: B017 - python-snap7 raises its own error type
            client.list_blocks_of_type(snap7.Block.DB, 10)
        assert client.list_blocks().DBCount == len(emulator.plc.data_blocks)
    finally:
        client.disconnect()


def test_pys7_reads_char_and_dint_with_snap7s_transport_sizes(emulator: EmulatorThread) -> None:
    from pyS7 import S7Client

    client = S7Client(address="127.0.0.1", rack=0, slot=2, port=emulator.port)
    client.connect()
    try:
        client.write(["DB130,DI40", "DB130,C44"], [-123456, "Z"])
        assert client.read(["DB130,DI40", "DB130,C44", "DB130,I46"]) == [-123456, "Z", 0]
        assert client.get_cpu_status() == "RUN"
    finally:
        client.disconnect()


# ---------------------------------------------------------------- node-snap7 (C snap7 client, npm)
NODE_SNAP7_VERSION = "1.0.9"
NODE_SCRIPT = r"""
const s7lib = require('node-snap7');
const client = new s7lib.S7Client();
client.SetParam(client.RemotePort, Number(process.argv[process.argv.length - 1]));
if (!client.ConnectTo('127.0.0.1', 0, 2)) { console.log(JSON.stringify({error: client.ErrorText(client.LastError())})); process.exit(0); }
const out = {};
for (const name of ['GetCpInfo', 'GetProtection', 'ListBlocks', 'GetPlcDateTime']) {
  const result = client[name]();
  out[name] = result === false ? {error: client.ErrorText(client.LastError())} : result;
}
out.GetPlcDateTime = out.GetPlcDateTime instanceof Date ? out.GetPlcDateTime.getTime() : out.GetPlcDateTime;
client.Disconnect();
console.log(JSON.stringify(out));
"""


@pytest.fixture(scope="session")
def node_snap7_dir() -> Path:
    """node-snap7 from the npm registry, installed once into a cache directory (it builds C snap7)."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        pytest.skip("node-snap7 needs node and npm, which are not installed here")
    target = Path(os.environ.get("NCKEMU_NODE_CACHE", Path.home() / ".cache" / "nckemu" / "node"))
    module = target / "node_modules" / "node-snap7"
    if not (module / "build" / "Release" / "node_snap7.node").exists():
        target.mkdir(parents=True, exist_ok=True)
        result = subprocess.run([npm, "install", "--no-audit", "--no-fund", "--prefix", str(target),
                                 f"node-snap7@{NODE_SNAP7_VERSION}"], capture_output=True, text=True, timeout=900)
        if result.returncode != 0 or not (module / "build" / "Release" / "node_snap7.node").exists():
            pytest.skip(f"npm could not install and build node-snap7 {NODE_SNAP7_VERSION}: "
                        f"{(result.stderr or result.stdout).strip()[-300:]}")
    return target


def test_node_snap7_reads_cp_info_protection_blocks_and_clock(emulator: EmulatorThread, node_snap7_dir: Path) -> None:
    node = shutil.which("node")
    assert node is not None
    result = subprocess.run([node, "-e", NODE_SCRIPT, "--", str(emulator.port)], capture_output=True, text=True,
                            timeout=120, env={**os.environ, "NODE_PATH": str(node_snap7_dir / "node_modules")})
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout.strip().splitlines()[-1])
    assert "error" not in out, out
    # C snap7 reads SZL 0x0131 index 1 and 0x0232 index 4 in the CPU layout (LENTHDR, N_DR, record)
    assert out["GetCpInfo"] == {"MaxPduLength": 960, "MaxConnections": 16, "MaxMpiRate": 12_000_000,
                                "MaxBusRate": 187_500}
    assert out["GetProtection"] == {"sch_schal": 1, "sch_par": 0, "sch_rel": 1, "bart_sch": 2, "anl_sch": 0}
    assert out["ListBlocks"]["DBCount"] == len(emulator.plc.data_blocks) and out["ListBlocks"]["OBCount"] == 0
    # node-snap7 turns the clock into a Date through mktime on a `new tm` whose tm_isdst it never sets
    # (src/node_snap7_client.cpp, GetPlcDateTime), so the Date may be off by the one-hour DST shift.
    moment = datetime.fromtimestamp(out["GetPlcDateTime"] / 1000)
    assert any(_close_to_now(moment + timedelta(hours=shift)) for shift in (-1, 0, 1))


def test_python_snap7_at_pdu_240_reads_a_long_szl_in_parts(emulator: EmulatorThread) -> None:
    """Granted 240, SZL 0x001C (9 records of 34 bytes) does not fit one PDU: python-snap7 follows the
    parts with its next-part requests and gets the whole list."""
    from snap7.type import Parameter

    whole = snap7.Client()
    whole.connect("127.0.0.1", 0, 2, emulator.port)
    try:
        expected = whole.read_szl(0x001C, 0)
    finally:
        whole.disconnect()
    assert expected.Header.LengthDR > 240
    client = snap7.Client()
    client.set_param(Parameter.PDURequest, 240)
    client.connect("127.0.0.1", 0, 2, emulator.port)
    try:
        assert client.get_pdu_length() == 240
        szl = client.read_szl(0x001C, 0)
        assert szl.Header.LengthDR == expected.Header.LengthDR
        assert bytes(szl.Data[:szl.Header.LengthDR]) == bytes(expected.Data[:expected.Header.LengthDR])
        assert client.get_cpu_info().ModuleTypeName.rstrip(b"\x00") == b"CPU 317-2 PN/DP (NCU PLC)"
        assert client.list_blocks().DBCount == len(emulator.plc.data_blocks)
    finally:
        client.disconnect()
