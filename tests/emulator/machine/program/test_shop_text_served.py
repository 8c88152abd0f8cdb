"""A shop's program text on the real server (issue 49): S7 string reads of non-Latin-1 MSG and block
texts answer what a control shows (our client and python-snap7), ``program get`` to stdout gives the
stored bytes, and a subprogram the run is in cannot be replaced over the wire."""

from __future__ import annotations

import logging
import struct
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import snap7

from nckemu.cli import main
from nckemu.clients import NckClient
from nckemu.clients import programs as P
from nckemu.emulator.machine.clock import LiveClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.runner import EmulatorThread
from nckemu.errors import NckServiceError
from nckemu.protocol import ncprog

MAIN = "/_N_MPF_DIR/_N_WARM_MPF"
LONG_BLOCK = "R1=" + "+".join(["1"] * 40)            # 82 characters: longer than actBlock's 66


@pytest.fixture
def served() -> Iterator[EmulatorThread]:
    with EmulatorThread(emulator=Emulator(None, clock=LiveClock(speed=600.0))) as emu:
        yield emu


@pytest.fixture
def snap7_client(served: EmulatorThread) -> Iterator[snap7.Client]:
    logging.getLogger("snap7").setLevel(logging.WARNING)
    client = snap7.Client()
    client.connect("127.0.0.1", 0, 4, served.port)
    yield client
    client.disconnect()


def _snap7_read(client: snap7.Client, module: int, column: int) -> tuple[int, bytes]:
    """One channel-1 (area C, unit 1) NC item, as a field collector reads it through python-snap7."""
    item = bytes([0x12, 0x08, 0x82, 0x41]) + struct.pack(">HHBB", column, 1, module, 1)
    parameter = bytes([0x04, 1]) + item
    answer = bytes(client.iso_exchange_buffer(bytearray(
        struct.pack(">BBHHHH", 0x32, 1, 0, 0x0100, len(parameter), 0) + parameter)))
    length = struct.unpack(">H", answer[16:18])[0]
    return answer[14], answer[18:18 + length]


def _wait(predicate, timeout_s: float = 20.0) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def test_non_latin1_message_and_long_blocks_read_as_a_control_shows_them(served: EmulatorThread,
                                                                          snap7_client: snap7.Client) -> None:
    text = f'\ufeffMSG("Warmlauf 20 → 25 °C")\r\n{LONG_BLOCK}\r\nG4 F1200 ; 2 s at 600x\r\nM30\r\n'.encode()
    served.call(lambda: served.emulator.nck.programs.write(MAIN, text))
    with NckClient("127.0.0.1", served.port) as nck:
        nck.pi_service("_N_SELECT", "201", MAIN)
        snap7_client.db_write(21, 7, bytearray(b"\x02"))
        _wait(lambda: nck.get("actBlock[C1]")[0].startswith("G4"))
        message, block = nck.get("msg[C1]", "actBlock[C1]")
        assert message == "Warmlauf 20 ? 25 °C"                      # '→' is not in Latin-1: '?'
        assert block == "G4 F1200"
        rc, raw = _snap7_read(snap7_client, 0x7D, 1)
        assert rc == 0xFF and raw == b"Warmlauf 20 ? 25 \xb0C".ljust(128, b"\x00")
        snap7_client.db_write(21, 7, bytearray(b"\x80"))               # reset; then a block longer than 66
        _wait(lambda: nck.get("chanStatus[C1]")[0] == 0)
        long_block = f"{LONG_BLOCK} G4 F1200"
        served.call(lambda: served.emulator.nck.programs.write(MAIN, f"{long_block}\nM30\n".encode()))
        snap7_client.db_write(21, 7, bytearray(b"\x02"))
        _wait(lambda: nck.get("actBlock[C1]")[0].startswith("R1="))
        assert nck.get("actBlock[C1]") == [long_block[:66]]           # cut at the field's end, no error
        rc, raw = _snap7_read(snap7_client, 0x7D, 31)
        assert rc == 0xFF and raw == long_block[:66].encode()
    assert served.call(lambda: served.emulator.nck.channels[1].state.block_text) == long_block  # whole elsewhere


@pytest.mark.parametrize("data", [
    'MSG("Warmlauf 20 → 25 °C")\r\nG4 F1\r\nM30\r\n'.encode(),
    'MSG("Warmlauf 20 °C")\r\nM30'.encode("latin-1"),
    b"\xef\xbb\xbfG0 X0\nM30\n",
])
def test_program_get_to_stdout_writes_the_stored_bytes(served: EmulatorThread, tmp_path: Path, data: bytes,
                                                       capsysbinary: pytest.CaptureFixture[bytes]) -> None:
    source = tmp_path / "WARM.MPF"
    source.write_bytes(data)
    port = ["--port", str(served.port)]
    assert main(["program", "put", str(source), *port]) == 0
    capsysbinary.readouterr()
    assert main(["program", "get", "WARM.MPF", *port]) == 0
    assert capsysbinary.readouterr().out == data
    assert main(["program", "get", "WARM.MPF", "--out", str(tmp_path / "back.MPF"), *port]) == 0
    assert (tmp_path / "back.MPF").read_bytes() == data


def test_the_subprogram_a_run_is_in_is_not_replaced_over_the_wire(served: EmulatorThread,
                                                                  snap7_client: snap7.Client) -> None:
    sub_text = b"G4 F6000\nRET\n"                                       # 10 s at 600x
    with NckClient("127.0.0.1", served.port) as nck:
        P.put_program_sync(nck, "MAIN.MPF", b"WAIT\nM30\n")
        P.put_program_sync(nck, "WAIT.SPF", sub_text)
        nck.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_MAIN_MPF")
        snap7_client.db_write(21, 7, bytearray(b"\x02"))
        _wait(lambda: nck.get("actBlock[C1]")[0] == "G4 F6000")
        with pytest.raises(NckServiceError) as refused:
            P.put_program_sync(nck, "WAIT.SPF", b"M17\n")
        assert refused.value.header_error == ncprog.ERROR_IN_USE    # as for the main program
        assert P.get_program_sync(nck, "WAIT.SPF") == sub_text
        snap7_client.db_write(21, 7, bytearray(b"\x80"))
        _wait(lambda: nck.get("chanStatus[C1]")[0] == 0)
        P.put_program_sync(nck, "WAIT.SPF", b"M17\n")                   # after the run: accepted
        assert P.get_program_sync(nck, "WAIT.SPF") == b"M17\n"
