"""tshark as an independent oracle for every item kind our encoder builds (frames crafted by us)."""

from __future__ import annotations

import struct
from pathlib import Path

from nckemu.capture import write_capture
from nckemu.protocol import cotp, pi, s7, szl
from nckemu.protocol.addresses import NckAddress, S7AnyAddress
from tests.support.tshark_tools import assert_fields_as_tshark, requires_tshark, tshark_fields

ITEMS = (
    NckAddress(3, 4, 43900, 1, 0x16),                    # SD43900[AX4]
    NckAddress(2, 1, 2, 1, 0x74, 3),                     # multi-line state data
    NckAddress(3, 1, 0x4E70, 1, 0x1A, syntax_id=0x83),   # NCK_M
    NckAddress(5, 1, 0x25, 1, 0x82, syntax_id=0x84),     # NCK_I, feed drive
    S7AnyAddress(2, 4, 130, 0x84, 10, 0),                # DB130.DBB10, 4 bytes
    S7AnyAddress(1, 1, 0, 0x83, 12, 3),                  # M12.3
)


def frame(rosctr: int, ref: int, parameter: bytes, data: bytes = b"", error: tuple[int, int] = (0, 0)) -> bytes:
    return cotp.build_data_frame(s7.build_pdu(s7.S7Pdu(rosctr, ref, parameter, data, *error)))


@requires_tshark
def test_tshark_sees_what_we_encode(tmp_path: Path) -> None:
    read_job = frame(1, 1, s7.build_read_var_request(s7.ReadVarRequest(ITEMS)))
    read_answer = frame(3, 1, *s7.build_read_var_response(s7.ReadVarResponse((
        s7.DataItem(0xFF, 0x09, struct.pack("<d", 0.3)), s7.DataItem(0xFF, 0x09, bytes(24)),
        s7.DataItem(0x0A, 0, b""), s7.DataItem(0x05, 0, b""), s7.DataItem(0xFF, 0x04, b"\x01\x02\x03\x04"),
        s7.DataItem(0xFF, 0x03, b"\x01")))))
    write_job = frame(1, 2, *s7.build_write_var_request(s7.WriteVarRequest(
        ITEMS[:1], (s7.DataItem(0, 0x09, struct.pack("<d", 0.000012)),))))
    write_answer = frame(3, 2, *s7.build_write_var_response(s7.WriteVarResponse((0xFF,))))
    pi_job = frame(1, 3, pi.build_pi_request(pi.PiServiceRequest("_N_SELECT", ("201", "/_N_MPF_DIR/_N_TEST_MPF"))))
    pi_answer = frame(3, 3, pi.build_pi_response(pi.PiServiceResponse(0)), error=(0x85, 0x00))
    setup = frame(1, 4, s7.build_setup_communication(s7.SetupCommunication(8, 8, 960)))
    szl_job = frame(7, 5, *szl.build_szl_request(szl.SzlReadRequest(0x001C, 0)))
    connect = cotp.build_frame(cotp.ConnectRequest(src_ref=1, calling_tsap=b"\x01\x00", called_tsap=b"\x01\x04",
                                                   tpdu_size=1024))
    # the clock as an S7-300 sends it in 2014: century byte 0x19, year byte 0x14 (read as 1914 before)
    clock_job = frame(7, 6, bytes.fromhex("0001120411470100"), bytes.fromhex("0A000000"))
    clock_answer = frame(7, 6, bytes.fromhex("000112081287010100000000"),
                         bytes.fromhex("FF09000A") + bytes.fromhex("00191408201159439124"))
    path = tmp_path / "crafted.pcapng"
    write_capture(path, [(True, connect), (True, setup), (True, read_job), (False, read_answer), (True, write_job),
                         (False, write_answer), (True, pi_job), (False, pi_answer), (True, szl_job),
                         (True, clock_job), (False, clock_answer)])
    assert_fields_as_tshark(path)  # every item and data item field, the clock's date and time
    fields = ["s7comm.header.rosctr", "s7comm.param.func", "s7comm.param.item.syntaxid",
              "s7comm.param.item.nck.area", "s7comm.param.item.nck.unit", "s7comm.param.item.nck.column",
              "s7comm.param.item.nck.line", "s7comm.param.item.nck.module", "s7comm.param.item.nck.linecount",
              "s7comm.param.item.db", "s7comm.param.item.area", "s7comm.param.item.address.byte",
              "s7comm.data.returncode", "s7comm.data.length", "s7comm.param.pistart.servicename",
              "s7comm.param.pdu_length", "s7comm.header.errcls", "s7comm.data.userdata.szl_id"]
    rows = tshark_fields(path, fields)
    by_kind = {(r["s7comm.header.rosctr"], r["s7comm.param.func"]): r for r in rows}
    read = by_kind[("1", "0x04")]
    assert read["s7comm.param.item.syntaxid"] == "0x82,0x82,0x83,0x84,0x10,0x10"
    assert read["s7comm.param.item.nck.area"] == "3,2,3,5"
    assert read["s7comm.param.item.nck.unit"] == "4,1,1,1"
    assert read["s7comm.param.item.nck.column"] == "43900,2,20080,37"
    assert read["s7comm.param.item.nck.module"] == "0x16,0x74,0x1a,0x82"
    assert read["s7comm.param.item.nck.linecount"] == "1,3,1,1"
    assert read["s7comm.param.item.db"].split(",")[0] == "130"
    assert read["s7comm.param.item.address.byte"] == "10,12"
    answer = by_kind[("3", "0x04")]
    assert answer["s7comm.data.returncode"] == "0xff,0xff,0x0a,0x05,0xff,0xff"
    assert answer["s7comm.data.length"].split(",")[:2] == ["8", "24"]
    assert by_kind[("1", "0x05")]["s7comm.param.item.nck.column"] == "43900"
    assert by_kind[("3", "0x05")]["s7comm.data.returncode"] == "0xff"
    assert by_kind[("1", "0x28")]["s7comm.param.pistart.servicename"] == "_N_SELECT"
    assert by_kind[("3", "0x28")]["s7comm.header.errcls"] == "0x85"
    assert by_kind[("1", "0xf0")]["s7comm.param.pdu_length"] == "960"
    assert any(r["s7comm.data.userdata.szl_id"].startswith("0x001c") for r in rows if r["s7comm.header.rosctr"] == "7")
