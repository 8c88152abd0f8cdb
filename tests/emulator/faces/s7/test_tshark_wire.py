"""tshark decodes every answer of the emulator without "malformed" over a capture (the server's
--record) that exercises the wire details of issue 14 part 2: userdata groups served and not served,
unsupported job functions, a PDU size below 240, the SZLs python-snap7 and C snap7 read, _N_CONFIG
and the tool-management PI services, CHAR/DINT reads, empty DTs after jobs, COTP segmentation, and
the 840C channel with P0 = 0 and tan beta = -1."""

from __future__ import annotations

import socket
import struct
import subprocess
from pathlib import Path

import snap7
from snap7.type import Parameter

from nckemu.emulator.runner import EmulatorThread
from tests.support.tshark_tools import TSHARK, requires_tshark, tshark_fields

CR_TPDU_128 = bytes.fromhex("0300001611E00000000100C00107C1020100C2020102")  # TPDU 2^7, rack 0 slot 2
EMPTY_DT = bytes.fromhex("0300000702f000")
EMPTY_DT_EOT = bytes.fromhex("0300000702f080")


def _dt(pdu: bytes) -> bytes:
    return struct.pack(">BBH", 3, 0, 7 + len(pdu)) + b"\x02\xF0\x80" + pdu


def _job(ref: int, parameter: bytes, data: bytes = b"", rosctr: int = 1) -> bytes:
    return _dt(struct.pack(">BBHHHH", 0x32, rosctr, 0, ref, len(parameter), len(data)) + parameter + data)


def _pi(ref: int, service: str, *arguments: str) -> bytes:
    block = b"".join(bytes([len(a)]) + a.encode() + (b"\x00" if len(a) % 2 == 0 else b"") for a in arguments)
    return _job(ref, bytes.fromhex("28000000000000FD") + struct.pack(">H", len(block)) + block
                + bytes([len(service)]) + service.encode())


def _recv_frame(sock: socket.socket) -> bytes:
    head = b""
    while len(head) < 4:
        chunk = sock.recv(4 - len(head))
        assert chunk, "connection closed"
        head += chunk
    length = struct.unpack(">H", head[2:4])[0]
    body = b""
    while len(body) < length - 4:
        chunk = sock.recv(length - 4 - len(body))
        assert chunk, "connection closed"
        body += chunk
    return head + body


def _answer(sock: socket.socket) -> bytes:
    """One S7 answer, reassembled from as many DTs as it came in."""
    payload = b""
    while True:
        frame = _recv_frame(sock)
        payload += frame[7:]
        if frame[6] & 0x80:
            return payload


def _raw_session(port: int) -> list[bytes]:
    answers: list[bytes] = []
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(CR_TPDU_128)
        assert _recv_frame(sock)[5] == 0xD0
        sock.sendall(_job(1, bytes.fromhex("F000000800080000")))  # PDU size 0: granted 240
        answers.append(_answer(sock))
        jobs = [
            _job(2, bytes.fromhex("0401120A100200C8006484000000")),  # 200 bytes of DB100: two DTs
            _job(3, bytes.fromhex("0402120A10030004006484000000120A10070001006484000004")),  # CHAR x4, DINT
            _job(4, bytes.fromhex("1A00000000000000")),                   # request download
            _job(5, bytes.fromhex("1D00000000000000095F30413030303031") + b"P"),  # start upload
            _job(6, bytes.fromhex("1E00000000000000")),                   # upload
            _job(7, bytes.fromhex("1F00000000000000")),                   # end upload
            _job(8, bytes.fromhex("0001120411470100"), bytes.fromhex("0A000000"), rosctr=7),  # read clock
            _job(9, bytes.fromhex("0001120411470200"), bytes.fromhex("0A000000"), rosctr=7),  # set clock
            _job(10, bytes.fromhex("0001120411430100"), bytes.fromhex("0A000000"), rosctr=7),  # list blocks
            _job(11, bytes.fromhex("0001120411430200"), bytes.fromhex("FF0900023041"), rosctr=7),  # of type
            _job(12, bytes.fromhex("0001120411410100"), bytes.fromhex("0A000000"), rosctr=7),  # programmer
            _job(13, bytes.fromhex("0001120411440100"), bytes.fromhex("FF09000409990000"), rosctr=7),
            _job(14, bytes.fromhex("0001120411440100"), bytes.fromhex("FF09000401310007"), rosctr=7),
            _job(15, bytes.fromhex("0001120411440100"), bytes.fromhex("FF09000404240000"), rosctr=7),
            _job(16, bytes.fromhex("0001120411440100"), bytes.fromhex("FF09000401310001"), rosctr=7),
            _job(17, bytes.fromhex("0001120411440100"), bytes.fromhex("FF09000402320004"), rosctr=7),
            _pi(18, "_N_CONFIG", "201", "1"),
            _pi(19, "_N_TMFPBP", "201", *(["1"] * 12)),
            _pi(20, "_N_TMPOSM", "201", *(["1"] * 7)),
            _pi(21, "_N_TSEARC", "201", *(["1"] * 8)),
        ]
        for job in jobs:
            sock.sendall(job + EMPTY_DT)  # the 828D collector's extra empty DT after every job (LSC)
            answers.append(_answer(sock))
        sock.sendall(EMPTY_DT_EOT)
        # 840C channel: user DB in DB100 (axis 4, U and A, K = 300, tan beta 0x80000000, P0 = 0), then DB41
        user_db = struct.pack(">HHiii", 7, 0xC004, 300, -(2**31), 0)
        write = bytes.fromhex("0501120A10020010006484000000")
        sock.sendall(_job(22, write, b"\x00\x04" + struct.pack(">H", 8 * len(user_db)) + user_db))
        answers.append(_answer(sock))
        request = bytes([9, 1, 0, 100, 0, 0, 0, 0])
        sock.sendall(_job(23, bytes.fromhex("0501120A10020008002984000000"), b"\x00\x04\x00\x40" + request))
        answers.append(_answer(sock))
        sock.sendall(_job(24, bytes.fromhex("0401120A10020008002984000000")))
        answers.append(_answer(sock))
    return answers


def _python_snap7_session(port: int) -> None:
    client = snap7.Client()
    client.connect("127.0.0.1", 0, 2, port)
    try:
        client.get_cp_info()
        client.get_protection()
        client.list_blocks()
        client.get_plc_datetime()
    finally:
        client.disconnect()
    small = snap7.Client()  # PDU 240: SZL 0x001C comes in parts, asked for one by one
    small.set_param(Parameter.PDURequest, 240)
    small.connect("127.0.0.1", 0, 2, port)
    try:
        small.read_szl(0x001C, 0)
    finally:
        small.disconnect()


@requires_tshark
def test_every_answer_decodes_without_malformed(tmp_path: Path) -> None:
    capture = tmp_path / "wire.pcapng"
    with EmulatorThread(record_path=capture) as emu:
        answers = _raw_session(emu.port)
        _python_snap7_session(emu.port)
    channel = answers[-1]
    assert channel[-8:][1] == 0x02 and channel[-8:][6:8] == b"\x00\x00"  # DB41: done, no error
    assert TSHARK is not None
    malformed = subprocess.run([TSHARK, "-r", str(capture), "-Y", "tcp.srcport == 102 && (_ws.malformed || _ws.expert.severity >= 6291456)"],
                               capture_output=True, text=True, timeout=120, check=True)
    assert malformed.stdout.strip() == ""
    fields = ["tcp.srcport", "s7comm.header.rosctr", "s7comm.header.errcls", "s7comm.header.errcod",
              "s7comm.param.func", "s7comm.param.userdata.funcgroup", "s7comm.param.userdata.subfunc",
              "s7comm.param.errcod", "s7comm.param.pistart.servicename", "s7comm.param.pdu_length",
              "s7comm.data.returncode", "s7comm.data.transportsize", "s7comm.param.userdata.lastdataunit"]
    rows = tshark_fields(capture, fields)
    answers_rows = [r for r in rows if r["tcp.srcport"] == "102"]
    # every answer is seen by tshark as an S7 answer (ack, ack_data or userdata)
    assert len(answers_rows) >= len(answers) + 4
    assert all(r["s7comm.header.rosctr"] in ("2", "3", "7") for r in answers_rows)
    assert any(r["s7comm.param.pdu_length"] == "240" for r in answers_rows)
    acks = [r for r in answers_rows if r["s7comm.header.rosctr"] == "2"]
    assert len(acks) == 4 and all(r["s7comm.header.errcls"] == "0x81" for r in acks)
    userdata = [(r["s7comm.param.userdata.funcgroup"], r["s7comm.param.userdata.subfunc"], r["s7comm.param.errcod"])
                for r in answers_rows if r["s7comm.header.rosctr"] == "7"]
    assert ("7", "1", "0x0000") in userdata and ("7", "2", "0x8104") in userdata
    assert ("3", "1", "0x0000") in userdata and ("3", "2", "0x8104") in userdata
    assert ("1", "1", "0x8104") in userdata
    assert ("4", "1", "0xd401") in userdata and ("4", "1", "0xd402") in userdata
    reads = [r for r in answers_rows if r["s7comm.param.func"] == "0x04" and r["s7comm.data.transportsize"]]
    assert any(r["s7comm.data.transportsize"] == "0x09,0x05" for r in reads)
    last_units = [r["s7comm.param.userdata.lastdataunit"] for r in answers_rows if r["s7comm.header.rosctr"] == "7"]
    assert "0x01" in last_units  # an answer in parts ("last data unit: no")
    services = {r["s7comm.param.pistart.servicename"] for r in rows if r["s7comm.param.pistart.servicename"]}
    assert {"_N_CONFIG", "_N_TMFPBP", "_N_TMPOSM", "_N_TSEARC"} <= services
