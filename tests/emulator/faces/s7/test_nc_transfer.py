"""NC program transfers against the real server on 127.0.0.1: our client (put, get, list, select,
delete), python-snap7's raw frames (the byte vectors of ../shared/reference/programs.md §6), the
PLC-block upload path, retained programs, and the bad input a control answers without losing data."""

from __future__ import annotations

import dataclasses
import json
import socket
import struct
import threading
from pathlib import Path

import pytest
import snap7

from nckemu.cli import main
from nckemu.clients import NckClient
from nckemu.clients import programs as P
from nckemu.emulator.faces.s7.session import SessionLimits
from nckemu.emulator.machine.machine_file import load_machine
from nckemu.emulator.runner import EmulatorThread
from nckemu.errors import NckPiBadArguments, NckServiceError
from nckemu.protocol import ncprog, s7

CONTENT = b"00000029" b"240102030405    " b";$PATH=/_N_MPF_DIR\n" b"G0 X0\nM30\n"
REQUEST_DOWNLOAD = bytes.fromhex("3207000000010008000F00011204117F0100FF09000B") + b"_N_TEST_MPF"


def _program(lines: int) -> bytes:
    return b"".join(b"N%d G1 X%d.5 Y-%d F300 ; move %d\r\n" % (i, i, i, i) for i in range(lines)) + b"M30\r\n"


def _with_sequence(frame: bytes, sequence: int) -> bytes:
    """A §6 frame with the sequence number (parameter byte 7) our server assigned instead of 0x2A."""
    return frame[:17] + bytes([sequence]) + frame[18:]


@pytest.fixture
def emu() -> EmulatorThread:
    with EmulatorThread() as emulator:
        yield emulator


def test_put_get_list_select_delete(emu: EmulatorThread) -> None:
    text = _program(20)
    with NckClient("127.0.0.1", emu.port) as nck:
        assert P.put_program_sync(nck, "DAILY.MPF", text) == "/_N_MPF_DIR/_N_DAILY_MPF"
        assert P.put_program_sync(nck, "WARMUP_CYCLE.SPF", b"PROC WARMUP_CYCLE\nM17\n") == \
            "/_N_SPF_DIR/_N_WARMUP_CYCLE_SPF"
        assert P.get_program_sync(nck, "/_N_MPF_DIR/_N_DAILY_MPF") == text
        assert P.get_program_sync(nck, "_n_daily_mpf") == text  # the control ignores case
        content = P.get_file_sync(nck, "DAILY.MPF")
        assert content.path == "/_N_MPF_DIR" and len(content.stamp) == 16
        listing = P.list_directory_sync(nck, "MPF_DIR")
        assert ("_N_DAILY_MPF", len(text)) in listing.entries and listing.directory == "/_N_MPF_DIR"
        assert P.list_directory_sync(nck, "_N_SPF_DIR").entries == (("_N_WARMUP_CYCLE_SPF", 22),)
        assert P.select_program_sync(nck, "DAILY.MPF") == "/_N_MPF_DIR/_N_DAILY_MPF"
        assert emu.call(lambda: emu.nck.programs.selected) == "/_N_MPF_DIR/_N_DAILY_MPF"
        P.delete_program_sync(nck, "WARMUP_CYCLE.SPF")
        assert P.list_directory_sync(nck, "SPF_DIR").entries == ()
    assert emu.call(lambda: emu.nck.programs.read("/_N_MPF_DIR/_N_DAILY_MPF")) == text


@pytest.mark.parametrize("pdu_size", [240, 480, 960])
def test_a_big_program_crosses_many_blocks_and_windows_both_ways(pdu_size: int) -> None:
    text = _program(3000)  # ~110 kB: hundreds of blocks, dozens of windows, uploads beyond 20 pushes
    with EmulatorThread(session_limits=SessionLimits(pdu_size_max=pdu_size)) as emu, \
            NckClient("127.0.0.1", emu.port) as nck:
        P.put_program_sync(nck, "BIG.MPF", text)
        assert P.get_program_sync(nck, "BIG.MPF") == text
        assert len(text) // (min(pdu_size, 480) - 28) > 2 * ncprog.UPLOAD_WINDOW  # python-snap7 asks for 480


@pytest.mark.parametrize("window", [1, 3, 20])
def test_the_download_window_is_a_setting(window: int) -> None:
    machine = load_machine(None)
    machine = dataclasses.replace(machine, settings=dataclasses.replace(machine.settings, nc_download_window=window))
    text = _program(300)
    with EmulatorThread(machine) as emu, NckClient("127.0.0.1", emu.port) as nck:
        P.put_program_sync(nck, "WINDOW.MPF", text)
        assert P.get_program_sync(nck, "WINDOW.MPF") == text


def _snap7(port: int) -> snap7.Client:
    client = snap7.Client()
    client.connect("127.0.0.1", 0, 4, port)
    return client


def _exchange(client: snap7.Client, frame: bytes) -> bytes:
    return bytes(client.iso_exchange_buffer(bytearray(frame)))


def test_python_snap7_raw_frames_are_the_reference_vectors(emu: EmulatorThread) -> None:
    """Frames 1-7 of programs.md §6 sent as they are (but for the sequence number the NC gives)."""
    client = _snap7(emu.port)
    try:
        answer = _exchange(client, REQUEST_DOWNLOAD)
        sequence = answer[17]
        assert answer == _with_sequence(bytes.fromhex("32070000000100 0C0006 0001120812BF012A00000000"
                                                      "FF0900020800".replace(" ", "")), sequence)
        block = bytes.fromhex("320700000001000C003B00011208123F022A01000000FF09003700FB") + CONTENT
        client.connection.send_data(_with_sequence(block, sequence))  # a block waits for no answer
        ended = bytes.fromhex("3207000000010008000600011204117F042AFF0900020000")
        assert _exchange(client, _with_sequence(ended, sequence)) == _with_sequence(
            bytes.fromhex("320700000001000C00060001120812BF042A00000000FF0900020000"), sequence)
        assert emu.call(lambda: emu.nck.programs.read("/_N_MPF_DIR/_N_TEST_MPF")) == b"G0 X0\nM30\n"
        start_upload = bytes.fromhex("3207000000010008001100011204117F0600FF09000D1400") + b"_N_TEST_MPF"
        answer = _exchange(client, start_upload)
        pdu = s7.parse_pdu(answer)
        parameter = ncprog.parse_nc_parameter(pdu.parameter)
        assert (parameter.type, parameter.subfunction, parameter.error_code, parameter.is_last) == \
            (ncprog.NC_RESPONSE, ncprog.NcSubfunction.START_UPLOAD, 0, True)
        content = ncprog.parse_transfer_content(ncprog.parse_chunk(ncprog.parse_nc_data(pdu.data).payload))
        # the time stamp the download carried comes back with the program
        assert content == ncprog.TransferContent("/_N_MPF_DIR", b"G0 X0\nM30\n", "240102030405    ", 29)
        # frame 7 for a file that does not exist: the error in the parameter, data 0A 00 00 00 (frame 10)
        missing = _exchange(client, start_upload.replace(b"_N_TEST_MPF", b"_N_NONE_MPF"))
        error = ncprog.parse_nc_parameter(s7.parse_pdu(missing).parameter)
        assert error.error_code == ncprog.ERROR_NO_SUCH_FILE and s7.parse_pdu(missing).data == ncprog.ERROR_DATA
    finally:
        client.disconnect()


def test_python_snap7_raw_windows_are_frames_4_and_9(emu: EmulatorThread) -> None:
    """Eight blocks that are not the last: the NC pushes frame 4; an upload of many pieces: 20 pushes,
    then frame 9 from the client brings the rest."""
    client = _snap7(emu.port)
    try:
        sequence = _exchange(client, REQUEST_DOWNLOAD)[17]
        content = ncprog.build_transfer_content(ncprog.TransferContent("/_N_MPF_DIR", _program(300)))
        pieces = ncprog.split_content(content, client.get_pdu_length() - ncprog.BLOCK_OVERHEAD)
        assert len(pieces) > 16
        for index, piece in enumerate(pieces):
            last = index == len(pieces) - 1
            parameter = ncprog.build_nc_parameter(ncprog.NcParameter(
                ncprog.NC_PUSH, 2, sequence, True, (index + 1) & 0xFF, 0 if last else 1))
            frame = s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, 1, parameter,
                                          ncprog.build_nc_data(ncprog.NcData(ncprog.build_chunk(piece)))))
            client.connection.send_data(frame)
            if not last and (index + 1) % 8 == 0:
                assert bytes(client.connection.receive_data()) == _with_sequence(bytes.fromhex(
                    "320700000001000C000600011208123F032A00000000FF0900020800"), sequence)
        ended = bytes.fromhex("3207000000010008000600011204117F042AFF0900020000")
        assert ncprog.parse_nc_parameter(s7.parse_pdu(_exchange(client, _with_sequence(ended, sequence))).parameter
                                         ).error_code == 0
        start_upload = bytes.fromhex("3207000000010008001100011204117F0600FF09000D1400") + b"_N_TEST_MPF"
        first = s7.parse_pdu(_exchange(client, start_upload))
        upload_sequence = first.parameter[7]
        assert first.parameter[4:7] == bytes.fromhex("12BF06") and first.parameter[9] == 1  # more follow
        received = [ncprog.parse_chunk(ncprog.parse_nc_data(first.data).payload)]
        last = False
        while not last:
            for _ in range(ncprog.UPLOAD_WINDOW):
                push = s7.parse_pdu(bytes(client.connection.receive_data()))
                assert push.parameter[4:8] == bytes([0x12, 0x3F, 0x07, upload_sequence])
                received.append(ncprog.parse_chunk(ncprog.parse_nc_data(push.data).payload))
                last = push.parameter[9] == 0
                if last:
                    break
            if not last:
                client.connection.send_data(_with_sequence(bytes.fromhex(
                    "3207000000010008000600011204113F0833FF0900021400"), upload_sequence))
        assert b"".join(received) == content.replace(content[8:24], received[0][8:24])
    finally:
        client.disconnect()


def test_plc_block_upload_of_an_nc_file(emu: EmulatorThread) -> None:
    """libnodave's daveGetNCProgram: 0x1D with the file name, 0x1E until no more data, 0x1F."""
    text = _program(200)
    with NckClient("127.0.0.1", emu.port) as nck:
        P.put_program_sync(nck, "TEST.MPF", text)
    client = _snap7(emu.port)
    try:
        start = s7.parse_pdu(_exchange(client, bytes.fromhex("32010000000100140000 1D00000000000000 0B".replace(" ", ""))
                                       + b"_N_TEST_MPF"))
        upload_id = struct.unpack(">I", start.parameter[4:8])[0]
        length = int(start.parameter[9:].decode())
        received, more = b"", True
        while more:
            job = bytes.fromhex("32010000000200080000") + b"\x1E\x00\x00\x00" + struct.pack(">I", upload_id)
            answer = s7.parse_pdu(_exchange(client, job))
            more = answer.parameter[1] == 1
            received += ncprog.parse_upload_data(answer.data).content
        end = s7.parse_pdu(_exchange(client, bytes.fromhex("32010000000300080000") + b"\x1F\x00\x00\x00"
                                     + struct.pack(">I", upload_id)))
        assert end.parameter == b"\x1F" and not end.error_class
        assert len(received) == length
        assert ncprog.parse_transfer_content(received).text == text
    finally:
        client.disconnect()
    with NckClient("127.0.0.1", emu.port) as nck:  # our client's daveGetNCProgram, at PDU 480
        assert ncprog.parse_transfer_content(P.get_file_by_blocks_sync(nck, "TEST.MPF")).text == text
        assert nck.get("R5") == [0.0]


def test_a_download_cut_off_leaves_the_old_program_whole_and_others_are_served(emu: EmulatorThread) -> None:
    old = b"G0 X0\nM30\n"
    emu.call(lambda: emu.nck.programs.write("/_N_MPF_DIR/_N_TEST_MPF", old))
    client = _snap7(emu.port)
    sequence = _exchange(client, REQUEST_DOWNLOAD)[17]
    new = ncprog.build_transfer_content(ncprog.TransferContent("/_N_MPF_DIR", _program(400)))
    for index, piece in enumerate(ncprog.split_content(new, 200)[:3]):
        parameter = ncprog.build_nc_parameter(ncprog.NcParameter(
            ncprog.NC_PUSH, 2, sequence, True, index + 1, ncprog.MORE_DATA_UNITS))
        data = ncprog.build_nc_data(ncprog.NcData(ncprog.build_chunk(piece)))
        client.connection.send_data(s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, index + 2, parameter, data)))
    # meanwhile another client is served, and sees the old program
    with NckClient("127.0.0.1", emu.port) as other:
        assert P.get_program_sync(other, "TEST.MPF") == old
        assert other.get("R5") == [0.0]
    client.connection.socket.close() if hasattr(client.connection, "socket") else None
    client.disconnect()  # killed mid-transfer
    with NckClient("127.0.0.1", emu.port) as nck:
        assert P.get_program_sync(nck, "TEST.MPF") == old
    assert emu.call(lambda: emu.nck.programs.read("/_N_MPF_DIR/_N_TEST_MPF")) == old


def test_a_client_killed_mid_transfer_by_its_socket(emu: EmulatorThread) -> None:
    """A raw socket closed after three blocks: nothing of it becomes visible."""
    sock = socket.create_connection(("127.0.0.1", emu.port))
    try:
        sock.sendall(bytes.fromhex("0300001611E00000000100C0010AC1020100C2020104"))
        sock.recv(64)
        sock.sendall(bytes.fromhex("0300001902F08032010000000100080000F0000001000103C0"))
        sock.recv(64)

        def frame(pdu: bytes) -> bytes:
            return b"\x03\x00" + struct.pack(">H", len(pdu) + 7) + b"\x02\xF0\x80" + pdu

        request = REQUEST_DOWNLOAD.replace(b"_N_TEST_MPF", b"_N_HALF_MPF").replace(b"\x00\x0B_N", b"\x00\x0B_N")
        sock.sendall(frame(request))
        answer = sock.recv(256)
        sequence = answer[7 + 17]
        content = ncprog.build_transfer_content(ncprog.TransferContent("/_N_MPF_DIR", _program(300)))
        for index, piece in enumerate(ncprog.split_content(content, 900)[:3]):
            parameter = ncprog.build_nc_parameter(ncprog.NcParameter(
                ncprog.NC_PUSH, 2, sequence, True, index + 1, ncprog.MORE_DATA_UNITS))
            data = ncprog.build_nc_data(ncprog.NcData(ncprog.build_chunk(piece)))
            sock.sendall(frame(s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, 9, parameter, data))))
    finally:
        sock.close()
    with NckClient("127.0.0.1", emu.port) as nck:
        assert "_N_HALF_MPF" not in [name for name, _ in P.list_directory_sync(nck, "MPF_DIR").entries]
    assert not emu.call(lambda: emu.nck.programs.exists("/_N_MPF_DIR/_N_HALF_MPF"))


def test_a_name_with_dots_is_refused_by_the_control(emu: EmulatorThread) -> None:
    client = _snap7(emu.port)
    try:
        for name in (b"../_N_X_MPF", b"_N_A B_MPF", b"_N_..__MPF"):
            request = bytes.fromhex("3207000000010008") + struct.pack(">H", 4 + len(name)) \
                + bytes.fromhex("00011204117F0100FF09") + struct.pack(">H", len(name)) + name
            parameter = ncprog.parse_nc_parameter(s7.parse_pdu(_exchange(client, request)).parameter)
            assert parameter.error_code == ncprog.ERROR_NOT_A_FILE_NAME, name
    finally:
        client.disconnect()
    with NckClient("127.0.0.1", emu.port) as nck, pytest.raises(NckPiBadArguments):
        P.put_program_sync(nck, "../ETC.MPF", b"x")  # our client refuses it before sending


def test_upload_of_a_missing_file_answers_the_error(emu: EmulatorThread) -> None:
    with NckClient("127.0.0.1", emu.port) as nck:
        with pytest.raises(NckServiceError) as refused:
            P.get_file_sync(nck, "NOTHERE.MPF", mark=False)
        assert refused.value.header_error == ncprog.ERROR_NO_SUCH_FILE
        assert "no such file" in str(refused.value)
        assert nck.get("R5") == [0.0]  # the connection goes on


def test_the_running_program_is_not_replaced(emu: EmulatorThread) -> None:
    path = "/_N_MPF_DIR/_N_TEST_MPF"
    emu.call(lambda: emu.nck.programs.write(path, b"G4 F10\nM30\n"))
    emu.call(lambda: setattr(emu.nck.programs, "running", path))
    with NckClient("127.0.0.1", emu.port) as nck:
        with pytest.raises(NckServiceError) as refused:
            P.put_program_sync(nck, "TEST.MPF", b"M30\n")
        assert refused.value.header_error == ncprog.ERROR_IN_USE
        assert P.get_program_sync(nck, "TEST.MPF") == b"G4 F10\nM30\n"


def test_a_full_store_refuses_the_program(tmp_path: Path) -> None:
    machine = load_machine(None)
    small = dataclasses.replace(machine, settings=dataclasses.replace(machine.settings, program_store_bytes=5000))
    with EmulatorThread(small) as emu, NckClient("127.0.0.1", emu.port) as nck:
        P.put_program_sync(nck, "SMALL.MPF", _program(20))
        with pytest.raises(NckServiceError) as refused:
            P.put_program_sync(nck, "LARGE.MPF", _program(400))
        assert refused.value.header_error == ncprog.ERROR_STORE_FULL
        assert not emu.call(lambda: emu.nck.programs.exists("/_N_MPF_DIR/_N_LARGE_MPF"))
        assert P.get_program_sync(nck, "SMALL.MPF") == _program(20)


def test_programs_are_retained_with_state(tmp_path: Path) -> None:
    state = tmp_path / "state.json"
    text = _program(50)
    with EmulatorThread(state_path=state) as emu, NckClient("127.0.0.1", emu.port) as nck:
        P.put_program_sync(nck, "KEPT.MPF", text)
        # acknowledged only once saved: the state file holds it before the server stops
        assert "_N_KEPT_MPF" in state.read_text()
    with EmulatorThread(state_path=state) as emu, NckClient("127.0.0.1", emu.port) as nck:
        assert P.get_program_sync(nck, "KEPT.MPF") == text
        P.delete_program_sync(nck, "KEPT.MPF")
    with EmulatorThread(state_path=state) as emu:
        assert not emu.call(lambda: emu.nck.programs.exists("/_N_MPF_DIR/_N_KEPT_MPF"))


def test_transfers_of_two_clients_at_once(emu: EmulatorThread) -> None:
    texts = {f"PART{i}.MPF": _program(500 + i) for i in range(3)}
    errors: list[BaseException] = []

    def send(name: str) -> None:
        try:
            with NckClient("127.0.0.1", emu.port) as nck:
                P.put_program_sync(nck, name, texts[name])
                assert P.get_program_sync(nck, name) == texts[name]
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=send, args=(name,)) for name in texts]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    assert not errors


def test_program_commands(emu: EmulatorThread, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = tmp_path / "DAILY.MPF"
    source.write_bytes(_program(10))
    port = ["--port", str(emu.port), "--json"]
    assert main(["program", "put", str(source), *port]) == 0
    assert json.loads(capsys.readouterr().out) == {"path": "/_N_MPF_DIR/_N_DAILY_MPF", "name": "DAILY.MPF",
                                                   "bytes": len(_program(10))}
    assert main(["program", "get", "DAILY.MPF", *port]) == 0
    assert json.loads(capsys.readouterr().out)["text"].encode("latin-1") == _program(10)
    assert main(["program", "list", *port]) == 0
    entries = json.loads(capsys.readouterr().out)["entries"]
    assert {"name": "_N_DAILY_MPF", "user_name": "DAILY.MPF", "bytes": len(_program(10))} in entries
    assert main(["program", "select", "DAILY.MPF", *port]) == 0
    assert json.loads(capsys.readouterr().out) == {"selected": "/_N_MPF_DIR/_N_DAILY_MPF"}
    for signal, bit in (("start", 1), ("stop", 3), ("reset", 7)):
        assert main(["program", signal, *port]) == 0
        assert json.loads(capsys.readouterr().out)["address"] == f"DB21.DBX7.{bit}"
        assert emu.call(lambda bit=bit: emu.plc.read_bit(0x84, 21, 7, bit)) is False  # the edge ended at 0


@pytest.mark.parametrize(("argv", "line"), [
    (["program", "put", "{tmp}/missing.mpf"], "missing.mpf: cannot read"),
    (["program", "put", "{tmp}/A.MPF", "--name", "../A.MPF"], "is not an NC file name"),
    (["program", "get", "NOTHERE.MPF"], "/_N_MPF_DIR/_N_NOTHERE_MPF: _N_F_XFER refused"),
    (["program", "list", "NOPE"], "NOPE"),
    (["program", "start", "--channel", "0"], "channel 0: expected 1..10"),
])
def test_program_commands_refuse_bad_input_in_one_line(emu: EmulatorThread, tmp_path: Path, argv: list[str],
                                                        line: str, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "A.MPF").write_bytes(b"M30\n")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main([*argv, "--port", str(emu.port)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and line in err, err
