"""Definition files sent to the real server as a DNC tool sends programs (`nckemu program put` over S7,
OPC UA CopyFileToServer is in test_opcua_programs' family): a GUD array the next program uses, and a
file with an error refused with its line while the old definitions stay."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from nckemu.cli import main
from nckemu.emulator.runner import EmulatorThread


@pytest.fixture
def emu() -> EmulatorThread:
    with EmulatorThread() as emulator:
        yield emulator


def _wait_ended(emu: EmulatorThread, timeout_s: float = 20.0) -> None:
    channel = emu.call(lambda: emu.nck.channels[1])
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if emu.call(lambda: channel.run is None and channel.state.actual_parts >= 1):
            return
        alarms = emu.call(lambda: channel.alarms)
        assert not alarms, alarms
        time.sleep(0.05)
    raise AssertionError("the program did not end")


def test_a_gud_file_put_over_s7_is_used_by_the_program_put_after_it(emu: EmulatorThread, tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    port = ["--port", str(emu.port)]
    gud = tmp_path / "MGUD.DEF"
    gud.write_bytes(b"DEF NCK REAL INI[100]\nDEF NCK INT RUNS\n")
    main_program = tmp_path / "GRIND.MPF"
    main_program.write_bytes(b"INI[53]=1500\nRUNS=RUNS+1\nR7=INI[53]\nM30\n")
    assert main(["program", "put", str(gud), *port]) == 0
    assert "/_N_DEF_DIR/_N_MGUD_DEF" in capsys.readouterr().out
    assert main(["program", "put", str(main_program), *port]) == 0
    assert main(["program", "select", "GRIND.MPF", *port]) == 0
    assert main(["program", "start", *port]) == 0
    _wait_ended(emu)
    variables = emu.call(lambda: emu.nck.programs.definitions.variables())
    assert variables["INI"].get((53,)) == 1500.0 and variables["RUNS"].value == 1
    assert main(["get", "R7", *port]) == 0 and "1500" in capsys.readouterr().out

    gud.write_bytes(b"DEF NCK REAL INI[100]\nDEF NCK INT RUNS\nDEF NCK REAL = 5\n")
    capsys.readouterr()
    assert main(["program", "put", str(gud), *port]) == 1
    assert "definition file with an error" in capsys.readouterr().err
    assert emu.call(lambda: emu.nck.programs.definitions.variables()["INI"].get((53,))) == 1500.0
    assert emu.call(lambda: emu.nck.programs.read("/_N_DEF_DIR/_N_MGUD_DEF")).count(b"\n") == 2
    # the refusal is on the NCK's alarm list with the file and the line, until a good version comes
    alarms = emu.call(lambda: emu.nck.alarm_list.active)
    assert any("/_N_DEF_DIR/_N_MGUD_DEF line 3" in text and "12080" in text for text in alarms), alarms
    gud.write_bytes(b"DEF NCK REAL INI[100]\nDEF NCK INT RUNS\nDEF NCK REAL NEW_ONE = 5\n")
    assert main(["program", "put", str(gud), *port]) == 0
    assert not any("MGUD" in text for text in emu.call(lambda: emu.nck.alarm_list.active))
    assert emu.call(lambda: emu.nck.programs.definitions.variables()["INI"].get((53,))) == 1500.0


def test_opc_ua_copy_file_to_server_activates_a_definition_file_or_refuses_it() -> None:
    import asyncio

    from asyncua import ua
    from asyncua.ua.uaerrors import UaStatusCodeError

    from tests.support.opcua_tools import NS_URI, connect, two_faces

    async def copy(face, name: str, data: bytes) -> object:
        client = await connect(face, "nckemu", "SUNRISE")
        try:
            ns = await client.get_namespace_index(NS_URI)
            methods = await client.nodes.objects.get_child([f"{ns}:Sinumerik", f"{ns}:Methods"])
            try:
                return await methods.call_method(f"{ns}:CopyFileToServer", ua.Variant(name),
                                                 ua.Variant(data, ua.VariantType.ByteString), ua.Variant(True))
            except UaStatusCodeError as exc:
                return type(exc).__name__
        finally:
            await client.disconnect()

    with two_faces() as (emulator, face):
        assert asyncio.run(copy(face, "UGUD.DEF", b"DEF NCK REAL OFFSETS[10]=REP(0.5)\n")) is None
        variables = emulator.call(lambda: emulator.emulator.nck.programs.definitions.variables())
        assert variables["OFFSETS"].get((9,)) == 0.5
        assert asyncio.run(copy(face, "UGUD.DEF", b"DEF NCK REAL OFFSETS[10]\nOFFSETS[1]=2\n")) == \
            "BadInvalidArgument"
        assert "OFFSETS" in emulator.call(lambda: emulator.emulator.nck.programs.definitions.variables())


def test_gud_values_put_over_s7_and_the_machine_files_plc_answers_the_served_program(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A grinder's day on the server: its definitions and the values an operator entered sent as a DNC
    tool sends them, then a program that waits for the guard its M48 closes (the machine file's PLC)."""
    from nckemu.emulator.machine.machine_file import machine_text

    machine = tmp_path / "grinder.toml"
    machine.write_text(machine_text(None)[0] + '\n[[nck_io.answer]]\nm = 48\nset = { "$A_IN[10]" = 1 }\n'
                                               'after_s = 0.5\n')
    (tmp_path / "MGUD.DEF").write_bytes(b"DEF NCK REAL INI[100]\n")
    (tmp_path / "WHEEL.GUD").write_bytes(b"CHANDATA(1)\nINI[5]=4 ; the pitch an operator entered\nM17\n")
    (tmp_path / "GRIND.MPF").write_bytes(b"M48\nWHILE $A_IN[10]==0\n  G4 F0.1\nENDWHILE\nR7=360/INI[5]\nM30\n")
    with EmulatorThread(machine) as emu:
        port = ["--port", str(emu.port)]
        for name in ("MGUD.DEF", "WHEEL.GUD", "GRIND.MPF"):
            assert main(["program", "put", str(tmp_path / name), *port]) == 0
        assert "/_N_DEF_DIR/_N_WHEEL_GUD" in capsys.readouterr().out
        assert main(["program", "select", "GRIND.MPF", *port]) == 0
        assert main(["program", "start", *port]) == 0
        _wait_ended(emu)
        assert main(["get", "R7", *port]) == 0 and "90" in capsys.readouterr().out
        (tmp_path / "WHEEL.GUD").write_bytes(b"INI[5]=4\nINI[500]=1\n")
        assert main(["program", "put", str(tmp_path / "WHEEL.GUD"), *port]) == 1
        assert emu.call(lambda: emu.nck.programs.definitions.variables()["INI"].get((5,))) == 4.0
        alarms = emu.call(lambda: emu.nck.alarm_list.active)
        assert any("/_N_DEF_DIR/_N_WHEEL_GUD line 2" in text for text in alarms), alarms
