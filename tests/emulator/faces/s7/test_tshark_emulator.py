"""What the emulator puts on the wire, decoded by tshark: a live loopback capture and --record."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest
import snap7
from snap7.type import Area

from nckemu.clients import NckClient
from nckemu.emulator.runner import EmulatorThread
from tests.support.tshark_tools import TSHARK, assert_fields_as_tshark, requires_tshark, tshark_fields

NCK_FIELDS = ["frame.number", "s7comm.header.rosctr", "s7comm.param.func", "s7comm.param.item.syntaxid",
              "s7comm.param.item.nck.area", "s7comm.param.item.nck.unit", "s7comm.param.item.nck.column",
              "s7comm.param.item.nck.line", "s7comm.param.item.nck.module", "s7comm.param.item.nck.linecount",
              "s7comm.data.returncode", "s7comm.param.pistart.servicename"]


def _session(port: int) -> None:
    with NckClient("127.0.0.1", port) as client:
        client.put({"SD43900[AX4]": 0.3, "SD43910[AX4]": 0.000012, "SD43920[AX4]": -1000.0})
        client.get("SD43900[AX4]", "R5", "actToolBasePos[C1,l2,x3]")
        client.get_items("SD43900[AX9]")
        client.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_TEST_MPF")
    plc = snap7.Client()  # PLC items: bits, bytes, words and a REAL, and the PLC's clock
    plc.connect("127.0.0.1", 0, 2, port)
    try:
        plc.write_area(Area.MK, 0, 5, b"\x21")
        plc.read_area(Area.MK, 0, 5, 4)
        plc.read_area(Area.DB, 130, 0, 8)
        plc.read_area(Area.PE, 0, 420, 2)
        plc.get_plc_datetime()
    finally:
        plc.disconnect()


def _nck_rows(rows: list[dict[str, str]]) -> list[tuple[str, ...]]:
    keys = NCK_FIELDS[1:-1]
    return [tuple(row.get(k, "") for k in keys) for row in rows]


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@requires_tshark
def test_record_file_decodes_in_tshark(tmp_path: Path) -> None:
    capture = tmp_path / "record.pcapng"
    with EmulatorThread(record_path=capture) as emu:
        _session(emu.port)
    assert_fields_as_tshark(capture)  # every item and data item field as tshark decodes it
    rows = tshark_fields(capture, NCK_FIELDS)
    jobs = [r for r in rows if r["s7comm.header.rosctr"] == "1" and r["s7comm.param.func"] == "0x05"]
    assert jobs[0]["s7comm.param.item.nck.column"] == "43900,43910,43920"
    assert jobs[0]["s7comm.param.item.nck.area"] == "3,3,3"
    assert jobs[0]["s7comm.param.item.nck.unit"] == "4,4,4"
    assert jobs[0]["s7comm.param.item.nck.module"] == "0x16,0x16,0x16"
    reads = [r for r in rows if r["s7comm.param.func"] == "0x04" and r["s7comm.header.rosctr"] == "1"]
    assert reads[0]["s7comm.param.item.nck.linecount"] == "1,1,3"
    answers = [r["s7comm.data.returncode"] for r in rows if r["s7comm.header.rosctr"] == "3"
               and r["s7comm.data.returncode"]]
    assert "0xff,0xff,0xff" in answers and "0x0a" in answers
    assert any(r["s7comm.param.pistart.servicename"] == "_N_SELECT" for r in rows)


@requires_tshark
@pytest.mark.skipif(os.geteuid() != 0, reason="a live capture on loopback needs root")
def test_live_capture_matches_the_record_file(tmp_path: Path) -> None:
    port = _free_port()
    live = tmp_path / "live.pcapng"
    recorded = tmp_path / "record.pcapng"
    assert TSHARK is not None
    capture = subprocess.Popen([TSHARK, "-i", "lo", "-f", f"tcp port {port}", "-w", str(live), "-q"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 20
        assert capture.stderr is not None
        # "Capturing on" comes before the capture is live; "Capture started" once it is.
        while "Capture started" not in capture.stderr.readline():
            if time.monotonic() > deadline or capture.poll() is not None:
                pytest.skip("tshark could not capture on loopback here")
        time.sleep(0.5)
        with EmulatorThread(port=port, record_path=recorded):
            _session(port)
        time.sleep(1.0)
    finally:
        capture.send_signal(signal.SIGINT)
        capture.wait(timeout=20)
    live_rows = _nck_rows(tshark_fields(live, NCK_FIELDS, port=port))
    record_rows = _nck_rows(tshark_fields(recorded, NCK_FIELDS))
    assert live_rows and live_rows == record_rows
