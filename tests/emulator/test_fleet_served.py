"""``nckemu fleet``: many machines in one process, each its own state, real clients on 127.0.0.1."""

from __future__ import annotations

import asyncio
import json
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest
import snap7

from nckemu.clients import AsyncNckClient, NckClient
from nckemu.emulator.fleet import Fleet, FleetMachine, FleetSpec

REPO = Path(__file__).resolve().parents[2]


def _spec(count: int) -> FleetSpec:
    return FleetSpec("test", tuple(FleetMachine(f"m{i}", "127.0.0.1", 0) for i in range(1, count + 1)))


def _free_ports(count: int) -> list[int]:
    sockets = [socket.socket() for _ in range(count)]
    try:
        for sock in sockets:
            sock.bind(("127.0.0.1", 0))
        return [int(sock.getsockname()[1]) for sock in sockets]
    finally:
        for sock in sockets:
            sock.close()


def _consecutive_free(count: int, avoid: range = range(0)) -> int:
    """A first port of ``count`` consecutive free ports (outside ``avoid``)."""
    for _ in range(100):
        base = _free_ports(1)[0]
        if base + count > 65535 or base in avoid or base + count - 1 in avoid:
            continue
        sockets = [socket.socket() for _ in range(count)]
        try:
            for offset, sock in enumerate(sockets):
                sock.bind(("127.0.0.1", base + offset))
            return base
        except OSError:
            continue
        finally:
            for sock in sockets:
                sock.close()
    raise RuntimeError(f"no {count} consecutive free ports")


async def test_a_write_on_one_machine_is_never_seen_on_another() -> None:
    fleet = await Fleet(_spec(3)).start()
    try:
        ports = [machine.port for machine in fleet.machines]
        assert len(set(ports)) == 3
        async with AsyncNckClient("127.0.0.1", ports[0]) as first:
            await first.put({"SD43900[AX4]": 0.3, "R7": 7.5})
        for port in ports[1:]:
            async with AsyncNckClient("127.0.0.1", port) as other:
                assert await other.get("SD43900[AX4]", "R7") == [0.0, 0.0]
        async with AsyncNckClient("127.0.0.1", ports[0]) as first:
            assert await first.get("SD43900[AX4]", "R7") == [0.3, 7.5]
        # PLC memory likewise (python-snap7, its own thread: the fleet's loop keeps serving)
        def plc() -> tuple[bytes, bytes]:
            clients = []
            for port in ports[:2]:
                client = snap7.Client()
                client.connect("127.0.0.1", 0, 2, port)
                clients.append(client)
            clients[0].db_write(100, 0, b"\x12\x34")
            result = bytes(clients[0].db_read(100, 0, 2)), bytes(clients[1].db_read(100, 0, 2))
            for client in clients:
                client.disconnect()
            return result
        assert await asyncio.to_thread(plc) == (b"\x12\x34", b"\x00\x00")
    finally:
        await fleet.stop()


async def test_a_fault_on_one_machine_leaves_the_others_serving(tmp_path: Path) -> None:
    fleet = await Fleet(_spec(3), state_dir=tmp_path).start()
    try:
        # m2 cannot write its retained data (a directory where its temporary file goes)
        (tmp_path / ".m2.json.tmp").mkdir()
        ports = [machine.port for machine in fleet.machines]
        async with AsyncNckClient("127.0.0.1", ports[1]) as broken:
            await broken.put({"SD43900[AX4]": 0.1})  # served; the machine raises its alarm
        assert fleet["m2"].emulator.persist_alarm is not None
        # and a client throws garbage at m2 mid-frame
        reader, writer = await asyncio.open_connection("127.0.0.1", ports[1])
        writer.write(b"\x03\x00\x00\x1f\x02\xf0\x80" + bytes(range(24)))
        await writer.drain()
        for port, value in ((ports[0], 0.2), (ports[2], 0.4)):
            async with AsyncNckClient("127.0.0.1", port) as other:
                await other.put({"SD43900[AX4]": value})
                assert await other.get("SD43900[AX4]") == [value]
        writer.close()
        assert json.loads((tmp_path / "m1.json").read_text())  # the others keep their retained data
        assert json.loads((tmp_path / "m3.json").read_text())
        assert not (tmp_path / "m2.json").exists()
    finally:
        await fleet.stop()


def _fleet(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "nckemu", "fleet", *args], cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def test_cli_one_line_per_machine_then_state_survives_a_restart(tmp_path: Path) -> None:
    base = _free_ports(1)[0]
    while base > 65000:
        base = _free_ports(1)[0]
    args = ("--count", "3", "--base-port", str(base), "--state", str(tmp_path))
    process = _fleet(*args)
    try:
        assert process.stdout is not None
        lines = [process.stdout.readline() for _ in range(4)]
        assert [line.split()[:2] for line in lines[:3]] == [
            [f"m00{i}", f"127.0.0.1:{base + i - 1}"] for i in (1, 2, 3)]
        assert "3 machine(s) serving" in lines[3]
        with NckClient("127.0.0.1", base + 1) as client:
            client.put({"SD43900[AX4]": 0.25})
    finally:
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=20) == 0
    process = _fleet(*args, "--json")
    try:
        assert process.stdout is not None
        ready = json.loads(process.stdout.readline())
        assert [(m["name"], m["port"]) for m in ready["machines"]] == [
            ("m001", base), ("m002", base + 1), ("m003", base + 2)]
        with NckClient("127.0.0.1", base + 1) as client:
            assert client.get("SD43900[AX4]") == [0.25]
        with NckClient("127.0.0.1", base) as client:
            assert client.get("SD43900[AX4]") == [0.0]
    finally:
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=20) == 0


async def test_each_machine_has_its_own_opcua_face_over_its_own_model() -> None:
    """An S7 write on one machine is read over that machine's OPC UA face and not over another's."""
    from asyncua import Client, ua

    spec = FleetSpec("test", tuple(FleetMachine(f"m{i}", "127.0.0.1", 0, opcua=0) for i in (1, 2)))
    fleet = await Fleet(spec).start()
    try:
        first, second = fleet.machines
        assert first.ready()["opcua"] != second.ready()["opcua"]
        async with AsyncNckClient("127.0.0.1", first.port) as client:
            await client.put({"SD43900[AX4]": 0.3})
        values = []
        for machine in (first, second):
            async with Client(machine.ready()["opcua"], timeout=10) as ua_client:
                ns = await ua_client.get_namespace_index("SinumerikVarProvider")
                node = ua_client.get_node(ua.NodeId("/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]", ns))
                values.append(await node.read_value())
        assert values == [0.3, 0.0]
    finally:
        await fleet.stop()


def test_cli_opcua_faces_one_line_each_and_a_taken_port_named(tmp_path: Path) -> None:
    s7 = _consecutive_free(2)
    opcua = _consecutive_free(2, avoid=range(s7 - 1, s7 + 3))
    process = _fleet("--count", "2", "--base-port", str(s7), "--opcua-base-port", str(opcua), "--json")
    try:
        assert process.stdout is not None
        ready = json.loads(process.stdout.readline())
        assert [m["opcua"] for m in ready["machines"]] == [f"opc.tcp://127.0.0.1:{p}/" for p in (opcua, opcua + 1)]
    finally:
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 0
    with socket.socket() as taken:
        taken.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        fleet = tmp_path / "fleet.toml"
        fleet.write_text(f'[[machine]]\nname = "ua"\nport = {_free_ports(1)[0]}\nopcua = {port}\n', encoding="utf-8")
        process = _fleet(str(fleet))
        out, err = process.communicate(timeout=60)
    assert process.returncode == 1, (out, err)
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"line 1, field 'opcua': machine 'ua': OPC UA face cannot bind 127.0.0.1:{port}: already in use" in err


def test_cli_port_in_use_is_one_line_naming_the_machine(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        free = _free_ports(1)[0]
        fleet = tmp_path / "fleet.toml"
        fleet.write_text(f'[[machine]]\nname = "ok"\nport = {free}\n\n[[machine]]\nname = "busy"\nport = {port}\n',
                         encoding="utf-8")
        process = _fleet(str(fleet))
        out, err = process.communicate(timeout=30)
    assert process.returncode == 1, (out, err)
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"{fleet}, line 5, field 'port': machine 'busy': cannot bind 127.0.0.1:{port}: already in use" in err


@pytest.mark.skipif(sys.platform != "linux", reason="Linux serves all of 127.0.0.0/8 on lo")
async def test_machines_on_loopback_addresses_share_one_port() -> None:
    port = _free_ports(1)[0]
    spec = FleetSpec("test", (FleetMachine("a", "127.0.0.11", port), FleetMachine("b", "127.0.0.12", port)))
    fleet = await Fleet(spec).start()
    try:
        async with AsyncNckClient("127.0.0.11", port) as a:
            await a.put({"R1": 1.0})
        async with AsyncNckClient("127.0.0.12", port) as b:
            assert await b.get("R1") == [0.0]
    finally:
        await fleet.stop()


async def test_a_living_machine_runs_its_program_beside_a_plain_one(tmp_path: Path) -> None:
    from nckemu.plcsim.fleet_live import living_machine
    from tests.support.live_tools import MACHINE, PROGRAM, write_recording

    recording = write_recording(tmp_path / "rec.csv", hours=3.0)
    spec = FleetSpec("test", (
        FleetMachine("alive", "127.0.0.1", 0, machine=str(MACHINE), inputs=str(recording), plc=str(PROGRAM),
                     speed="600x"),
        FleetMachine("plain", "127.0.0.1", 0, machine=str(MACHINE)),
    ))
    fleet = await Fleet(spec, living=living_machine).start()
    try:
        assert [m.ready()["living"] for m in fleet.machines] == [True, False]
        alive, plain = (machine.port for machine in fleet.machines)
        # tc_z.awl writes K0 = 0.3 mm per 10 K of bed above 30 degC once a simulated minute; the
        # recording's bed passes 30 degC after 45 simulated minutes (4.5 s at 600x)
        deadline = asyncio.get_running_loop().time() + 60
        value = 0.0
        async with AsyncNckClient("127.0.0.1", alive) as client:
            while value <= 0.0 and asyncio.get_running_loop().time() < deadline:
                await asyncio.sleep(0.2)
                (value,) = await client.get("SD43900[AX4]")
        assert value > 0.0
        async with AsyncNckClient("127.0.0.1", plain) as client:
            assert await client.get("SD43900[AX4]") == [0.0]
    finally:
        await fleet.stop()


def test_cli_living_keys_are_checked_with_the_fleet_file_line(tmp_path: Path) -> None:
    from nckemu.cli import main
    from tests.support.live_tools import write_recording

    write_recording(tmp_path / "rec.csv", hours=1.0)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[[machine]]\nname = "a"\nport = 2001\n\n[[machine]]\nname = "b"\nport = 2002\n'
                     'inputs = "rec.csv"\nspeed = "fast"\n', encoding="utf-8")
    process = subprocess.run([sys.executable, "-m", "nckemu", "fleet", str(fleet)], cwd=REPO, text=True,
                             capture_output=True, timeout=60)
    assert process.returncode == 1
    assert process.stderr.count("\n") == 1
    assert f"{fleet}, line 5, field 'speed': machine 'b': --speed 'fast'" in process.stderr
    assert main is not None
