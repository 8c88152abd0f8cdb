"""`nckemu trace show` of a recorded NC program download and upload equals tshark's decoding, field by
field: type, function group, subfunction, sequence, data unit reference, last data unit, window, file
name, and the reassembled content (length, time stamp, path, text)."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import pytest
import snap7

from nckemu.cli import main
from nckemu.clients import NckClient
from nckemu.clients import programs as P
from nckemu.emulator.faces.s7.session import SessionLimits
from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol import blocks, s7
from nckemu.traces.decode import decode
from nckemu.traces.reader import read_capture
from tests.support.tshark_tools import requires_tshark, tshark_fields

pytestmark = pytest.mark.tshark

FIELDS = ["s7comm.param.userdata.type", "s7comm.param.userdata.funcgroup", "s7comm.param.userdata.subfunc",
          "s7comm.param.userdata.seq_num", "s7comm.param.userdata.dataunitref",
          "s7comm.param.userdata.lastdataunit", "s7comm.data.ncprg.unackcount", "s7comm.data.ncprg.filelength",
          "s7comm.data.ncprg.filetime", "s7comm.data.ncprg.filepath", "s7comm.data.ncprg.filedata",
          "s7comm.param.blockcontrol.filename"]
TEXT = b"".join(b"N%d G1 X%d.5 F300 ; line %d\n" % (i, i, i) for i in range(400)) + b"M30\n"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A download over many windows and an upload over many pushes, at PDU 240 (serve --record)."""
    path = tmp_path_factory.mktemp("nc") / "transfer.pcapng"
    with EmulatorThread(record_path=path, session_limits=SessionLimits(pdu_size_max=240)) as emu:
        with NckClient("127.0.0.1", emu.port) as nck:
            P.put_program_sync(nck, "DAILY.MPF", TEXT)
            assert P.get_program_sync(nck, "DAILY.MPF") == TEXT
            assert ("_N_DAILY_MPF", len(TEXT)) in P.list_directory_sync(nck, "MPF_DIR").entries
        # and libnodave's daveGetNCProgram: the PLC-block start upload naming the NC file
        client = snap7.Client()
        client.connect("127.0.0.1", 0, 4, emu.port)
        try:
            parameter = blocks.build_block_control(blocks.BlockControl(blocks.START_UPLOAD, 0, 0, 0, "_N_DAILY_MPF"))
            client.iso_exchange_buffer(bytearray(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, 7, parameter))))
        finally:
            client.disconnect()
    return path


def _ours(path: Path) -> dict[int, dict[str, list[str]]]:
    """Our decoding by frame and tshark field, in the order the PDUs crossed the wire."""
    capture = read_capture(path)
    order = {id(pdu): index for index, pdu in enumerate(capture.pdus)}
    telegrams = []
    for exchange in decode(capture):
        telegrams.append((order[id(exchange.job)], exchange.job.frame, exchange.nc))
        if exchange.answer is not None:
            telegrams.append((order[id(exchange.answer)], exchange.answer.frame, exchange.nc_answer))
    by_frame: dict[int, dict[str, list[str]]] = defaultdict(lambda: defaultdict(list))
    for _index, frame, fields in sorted(telegrams, key=lambda telegram: telegram[0]):
        for name, value in fields.items():
            if name not in FIELDS:
                continue
            if name == "s7comm.param.userdata.lastdataunit":
                value = f"0x{value:02x}"
            by_frame[frame][name].append(str(value).replace("\n", "\\n"))
    return by_frame


@requires_tshark
def test_nc_transfer_fields_equal_tsharks(recorded: Path) -> None:
    theirs = {int(row["frame.number"]): row for row in tshark_fields(recorded, ["frame.number", *FIELDS])}
    ours = _ours(recorded)
    nc_frames = {frame for frame, row in theirs.items() if any(row[name] for name in FIELDS)}
    assert nc_frames and set(ours) == nc_frames
    for frame in sorted(nc_frames):
        for name in FIELDS:
            assert ",".join(ours[frame].get(name, [])) == theirs[frame][name], (frame, name)
    # the transfer was long enough to need windows both ways
    subfunctions = ",".join(theirs[frame]["s7comm.param.userdata.subfunc"] for frame in sorted(nc_frames))
    assert "3" in subfunctions.split(",") and "8" in subfunctions.split(",")
    texts = [row["s7comm.data.ncprg.filedata"] for row in theirs.values() if row["s7comm.data.ncprg.filedata"]]
    assert texts[:2] == [TEXT.hex(), TEXT.hex()] and len(texts) == 3  # and the directory listing


def test_trace_show_names_the_transfer(recorded: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["trace", "show", str(recorded)]) == 0
    out = capsys.readouterr().out
    assert "NC programming -> Request download: file _N_DAILY_MPF -> sequence 1, window 8" in out
    assert "NC programming -> Continue download" in out and "NC programming -> Continue upload" in out
    assert out.count("/_N_MPF_DIR/_N_DAILY_MPF: length") == 2  # the download and the upload, reassembled
    assert "first: 'N0 G1 X0.5 F300 ; line 0'" in out
    assert "Download ended: sequence 1 -> stored" in out
    assert "; /_N_MPF_DIR: length blank (a directory)" in out
    assert "start upload NC file _N_DAILY_MPF -> upload id 1, block length 1" in out
