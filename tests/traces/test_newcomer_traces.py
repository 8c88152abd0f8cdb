"""Traces as a newcomer reads them next to tshark (issue 37): the PLC clock's year, PLC items named as S7
tools write them with their values, and a capture that starts mid-connection replayed without header
errors. The same cases on the public captures themselves, where they are present."""

from __future__ import annotations

import json
import re
import struct
from datetime import datetime
from pathlib import Path

import pytest

from nckemu.capture import CaptureWriter
from nckemu.cli import main
from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol import cotp, s7, szl
from nckemu.protocol.addresses import S7AnyAddress
from nckemu.traces.decode import decode, s7any_name
from nckemu.traces.reader import read_capture
from nckemu.traces.replay import replay
from tests.conftest import SHARED

PCAPS = SHARED / "field" / "pcaps"


def _clock_answer(century: int, year: int) -> bytes:
    """FF 09 00 0A, reserved, century and year as sent, 20 Aug 11:59:43.912, Wednesday."""
    return bytes([0xFF, 0x09, 0x00, 0x0A, 0x00, century, year, 0x08, 0x20, 0x11, 0x59, 0x43, 0x91, 0x24])


@pytest.mark.parametrize(("century", "year", "expected"), [
    (0x19, 0x14, 2014),   # an S7-300 in 2014 (iti/s7comm_reading_setting_plc_time.pcap): 1914 before
    (0x19, 0x16, 2016),   # iti/snap7_s300_everything.pcapng: 1916 before
    (0x20, 0x26, 2026),   # what the emulator sends
    (0x19, 0x99, 1999),
    (0x00, 0x89, 2089),   # the last year of DATE_AND_TIME
])
def test_the_clock_year_is_the_year_byte(century: int, year: int, expected: int) -> None:
    assert szl.parse_clock(_clock_answer(century, year)) == datetime(expected, 8, 20, 11, 59, 43, 912000)


def test_the_emulators_clock_reads_back() -> None:
    moment = datetime(2026, 11, 23, 7, 5, 9, 250000)
    assert szl.parse_clock(szl.build_clock(moment)) == moment


@pytest.mark.parametrize(("address", "name"), [
    (S7AnyAddress(0x01, 1, 0, 0x83, 102, 3), "M102.3"),       # tshark: M 102.3 BIT 1 (was "MB102 x1 (ts 1)")
    (S7AnyAddress(0x01, 1, 5, 0x84, 0, 1), "DB5.DBX0.1"),
    (S7AnyAddress(0x02, 1, 0, 0x83, 100), "MB100"),
    (S7AnyAddress(0x02, 20, 130, 0x84, 0), "DB130.DBB0 x20"),
    (S7AnyAddress(0x04, 1, 0, 0x81, 4), "IW4"),
    (S7AnyAddress(0x05, 2, 0, 0x82, 10), "QW10 INT x2"),
    (S7AnyAddress(0x06, 1, 130, 0x84, 0), "DB130.DBD0"),
    (S7AnyAddress(0x08, 1, 0, 0x83, 300), "MD300 REAL"),
    (S7AnyAddress(0x07, 1, 3, 0x84, 4), "DB3.DBD4 DINT"),
    (S7AnyAddress(0x04, 1, 0, 0x80, 420), "PIW420"),
    (S7AnyAddress(0x1C, 1, 0, 0x1C, 0, 5), "C5"),
    (S7AnyAddress(0x1D, 3, 0, 0x1D, 1, 2), "T10 x3"),
    (S7AnyAddress(0x03, 4, 2, 0x85, 6), "DI2.DIB6 CHAR x4"),
])
def test_plc_items_are_named_as_s7_tools_write_them(address: S7AnyAddress, name: str) -> None:
    assert s7any_name(address) == name


def _write(path: Path, with_setup: bool) -> None:
    """An HMI polling M102.3 and MD300 REAL; with or without the connect and setup before it."""
    writer = CaptureWriter.open(path)
    if with_setup:
        writer.segment(1, True, cotp.build_frame(cotp.ConnectRequest(src_ref=1, calling_tsap=b"\x01\x00",
                                                                     called_tsap=b"\x01\x02", tpdu_size=1024)))
        writer.segment(1, False, cotp.build_frame(cotp.ConnectConfirm(dst_ref=1, src_ref=1, calling_tsap=b"\x01\x00",
                                                                      called_tsap=b"\x01\x02", tpdu_size=1024)))
        setup = s7.build_setup_communication(s7.SetupCommunication(1, 1, 480))
        writer.segment(1, True, cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, 1, setup))))
        writer.segment(1, False, cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, 1, setup))))
    items = (S7AnyAddress(0x01, 1, 0, 0x83, 102, 3), S7AnyAddress(0x08, 1, 0, 0x83, 300))
    for reference in range(2, 5):
        job = s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, reference, s7.build_read_var_request(s7.ReadVarRequest(items))))
        answer = s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, reference, *s7.build_read_var_response(s7.ReadVarResponse((
            s7.DataItem(0xFF, 0x03, b"\x00"), s7.DataItem(0xFF, 0x07, struct.pack(">f", 0.0)))))))
        writer.segment(1, True, cotp.build_data_frame(job))
        writer.segment(1, False, cotp.build_data_frame(answer))
    writer.close()


def test_show_names_bits_and_decodes_values(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "hmi.pcapng"
    _write(path, with_setup=False)
    assert main(["trace", "show", str(path)]) == 0
    out = capsys.readouterr().out
    assert "    M102.3 = 0\n" in out and "    MD300 REAL = 0.000000\n" in out and "(ts " not in out
    assert main(["trace", "show", "--json", str(path)]) == 0
    items = json.loads(capsys.readouterr().out)["exchanges"][0]["items"]
    assert [(i["name"], i["byte"], i["bit"], i["transport_size"], i["value"], i["data_transport_size"])
            for i in items] == [("M102.3", 102, 3, 1, 0, 3), ("MD300 REAL", 300, 0, 8, 0.0, 7)]


def test_replay_sets_up_a_connection_the_capture_starts_in(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """Before, each job was refused with header error 0x8401 (a job before setup communication) and
    nothing said why."""
    path = tmp_path / "hmi.pcapng"
    _write(path, with_setup=False)
    with EmulatorThread() as emu:
        report = replay(read_capture(path), "127.0.0.1", emu.port)
    assert report.jobs == 3 and report.differing_errors == 0 and report.all_match, report.differences
    (note,) = report.notes
    assert "starts in the capture after its setup" in note and "setup communication itself" in note
    assert main(["trace", "replay", str(path)]) == 0
    out = capsys.readouterr().out
    assert re.match(r"note: connection c1 starts in the capture after its setup \(first frame #\d+ is a job\)", out)
    assert "0 header errors differ" in out


def test_replay_of_a_whole_connection_sets_nothing_up_itself(tmp_path: Path) -> None:
    path = tmp_path / "whole.pcapng"
    _write(path, with_setup=True)
    with EmulatorThread() as emu:
        report = replay(read_capture(path), "127.0.0.1", emu.port)
    assert report.all_match and report.notes == [] and report.jobs == 4


# ---------------------------------------------------------------- the public captures named in the issue
def _field(name: str) -> Path:
    path = PCAPS / name
    if not path.is_file():
        pytest.skip(f"{path} is absent (../shared/field/pcaps)")
    return path


@pytest.mark.parametrize(("name", "year"), [("iti/s7comm_reading_setting_plc_time.pcap", "2014-08-20"),
                                            ("iti/snap7_s300_everything.pcapng", "2016-02-08")])
def test_field_clocks_read_as_tshark_reads_them(name: str, year: str) -> None:
    details = [e.detail for e in decode(read_capture(_field(name))) if "clock" in e.service_name.lower()]
    assert details and all(year in detail and "19" + year[2:4] + "-" not in detail for detail in details)


def test_field_bit_items_and_mid_connection_replay(capsys: pytest.CaptureFixture[str]) -> None:
    path = _field("qut/ChangeUpperThreshold.hmi.pcap")
    first = decode(read_capture(path))[0]
    assert [i.name for i in first.items[:3]] == ["M102.3", "M102.2", "M102.5"]   # as tshark
    assert main(["trace", "replay", str(path)]) == 1   # the machine is not that PLC: values differ
    out = capsys.readouterr().out
    assert "note: connection c1 starts in the capture after its setup" in out
    assert "0 header errors differ" in out and "0x8401" not in out
