"""Faults inside the machine: a PLC program that loops, divides by zero or writes garbage; a recording
with a broken row; a full disk under --state; a fleet machine whose face is flooded while the others go
on (per-machine fairness measured). Every face keeps serving through each."""

from __future__ import annotations

import asyncio
import multiprocessing as mp
import os
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest
from asyncua import ua

from nckemu.cli import main
from nckemu.clients import NckClient
from nckemu.clients.async_client import AsyncNckClient
from nckemu.emulator.fleet import Fleet, FleetMachine, FleetSpec
from tests.plcsim.test_live import _live
from tests.support.flooding import flood
from tests.support.opcua_tools import connect, two_faces

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(300)

LOOPS = """\
ORGANIZATION_BLOCK OB 1
BEGIN
loop: JU loop
END_ORGANIZATION_BLOCK
"""
DIVIDES = """\
ORGANIZATION_BLOCK OB 1
BEGIN
  L 7
  L 0
  /I
  T MW 20
  L 7.0
  L 0.0
  /R
  T MD 24
  L L#7
  L L#0
  MOD
  T MD 28
END_ORGANIZATION_BLOCK
"""
GARBAGE = """\
ORGANIZATION_BLOCK OB 1
BEGIN
  L DW#16#7FC00000
  T PQD 0
  T MD 40
  L DW#16#FFFFFFFF
  T MD 44
  OPN DB 100
  T DBD 0
  T DBD 300
END_ORGANIZATION_BLOCK
"""


@pytest.mark.parametrize(("name", "text", "stops"), [("loops", LOOPS, True), ("divides", DIVIDES, False),
                                                      ("garbage", GARBAGE, True)])
async def test_a_faulty_plc_program_never_stops_the_machine(tmp_path: Path, name: str, text: str, stops: bool) -> None:
    program = tmp_path / f"{name}.awl"
    program.write_text(text)
    live, sd, temperatures = await _live(tmp_path, program, 600.0, 2.0)
    snapshot = live.snapshot()
    assert snapshot["plc"] == ("STOP" if stops else "RUN"), snapshot
    assert (snapshot["fault"] is not None) == stops
    assert len(sd) >= 15, "the S7 face served a read every 0.1 s throughout"
    assert temperatures[-1] != temperatures[0], "the recording drives the machine on"


@pytest.mark.parametrize(("row", "said"), [("0,abc", "2 cells, the header has 6"),
                                           ("60,nan,20.0,0,-29.29,", "not a finite number: 'nan'"),
                                           ("120,20.0,inf,0,-29.29,", "not a finite number: 'inf'"),
                                           ("180,20.0,20.0,x,-29.29,", "spindle_rpm")])
def test_a_recording_with_a_broken_row_is_refused_in_one_line(tmp_path: Path, row: str, said: str,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    lines = (REPO / "fixtures/thermal/loop_bed_program_spindle_lag.csv").read_text().splitlines()
    middle = len(lines) // 2
    lines[middle] = f"{lines[middle].split(',')[0]},{row.split(',', 1)[1]}"
    recording = tmp_path / "broken.csv"
    recording.write_text("\n".join(lines) + "\n")
    code = main(["serve", "--port", "0", "--machine", str(REPO / "fixtures/machines/loop_mill.toml"),
                 "--inputs", str(recording), "--speed", "600x"])
    err = capsys.readouterr().err.strip()
    assert code != 0 and len(err.splitlines()) == 1 and f"line {middle + 1}" in err and said in err, err


@pytest.fixture
def tiny_disk(tmp_path: Path) -> Any:
    """A 64 KiB tmpfs (root only); skipped where it cannot be mounted."""
    mount = tmp_path / "disk"
    mount.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


def test_a_full_disk_under_state_raises_the_alarm_and_both_faces_serve_on(tiny_disk: Path) -> None:
    """A program too big for the disk: every save fails (ENOSPC), the alarm is up, S7 and OPC UA serve;
    the program deleted (PI _N_F_DELE), the next write saves again and the alarm goes."""
    state = tiny_disk / "state.json"
    with two_faces(state_path=state) as (emulator, face):
        with NckClient("127.0.0.1", emulator.port) as nck:
            nck.put({"R1": 1.0})
            assert emulator.emulator.persist_alarm is None and state.exists()

            async def copy() -> Any:
                client = await connect(face, "nckemu", "SUNRISE")
                try:
                    methods = await client.nodes.objects.get_child(["2:Sinumerik", "2:Methods"])
                    return await methods.call_method("2:CopyFileToServer", ua.Variant(
                        "Sinumerik/FileSystem/Part Program/BIG.MPF"), ua.Variant(os.urandom(200_000),
                                                                                 ua.VariantType.ByteString),
                        ua.Variant(True))
                finally:
                    await client.disconnect()

            copied = asyncio.run(copy())
            assert emulator.emulator.persist_alarm is not None, (copied, state.stat().st_size)
            assert emulator.emulator.persist_alarm is not None and "No space left" in emulator.emulator.persist_alarm
            nck.put({"R2": 2.0})  # served, not saved: the alarm stays
            assert nck.get("R1", "R2") == [1.0, 2.0] and emulator.emulator.persist_alarm is not None
            assert nck.get("numAlarms")[0] >= 1
            nck.pi_service("_N_F_DELE", "/NC", "/_N_MPF_DIR/_N_BIG_MPF")
            nck.put({"R3": 3.0})
            assert emulator.emulator.persist_alarm is None
    assert '"R' in state.read_text() or state.stat().st_size > 0


async def _polite(port: int, seconds: float) -> tuple[int, float]:
    latencies = []
    async with AsyncNckClient("127.0.0.1", port) as client:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            started = time.perf_counter()
            await client.get("SD43900[AX4]")
            latencies.append(time.perf_counter() - started)
            await asyncio.sleep(0.01)
    latencies.sort()
    return len(latencies), latencies[int(0.99 * (len(latencies) - 1))]


async def test_a_flooded_fleet_machine_leaves_the_others_their_share() -> None:
    """Four S7 clients flood m1 without a pause; a polite client on m2 and on m3 (a read every 10 ms)
    is served throughout, its p99 and read count printed against the same alone."""
    fleet = await Fleet(FleetSpec("fair", tuple(FleetMachine(f"m{i}", "127.0.0.1", 0) for i in (1, 2, 3)))).start()
    try:
        ports = [machine.port for machine in fleet.machines]
        alone = await asyncio.gather(_polite(ports[1], 2.0), _polite(ports[2], 2.0))
        ctx = mp.get_context("spawn")
        out, flooding, stop = ctx.Queue(), ctx.Queue(), ctx.Event()
        flooders = [ctx.Process(target=flood, args=(ports[0], 60.0, out, flooding, stop)) for _ in range(4)]
        for flooder in flooders:
            flooder.start()
        loop = asyncio.get_running_loop()
        for _ in flooders:  # the flood under way (spawned processes take a moment), every flooder in it
            await loop.run_in_executor(None, flooding.get, True, 60)
        flooded = await asyncio.gather(_polite(ports[1], 3.0), _polite(ports[2], 3.0))
        stop.set()
        floods = [await loop.run_in_executor(None, out.get, True, 60) for _ in flooders]
        for flooder in flooders:
            await loop.run_in_executor(None, flooder.join, 30)
    finally:
        await fleet.stop()
    print(f"fairness: m1 flooded with {sum(floods)} jobs; m2/m3 polite reads alone "
          f"{[n for n, _ in alone]} in 2 s (p99 {[round(p * 1000, 1) for _, p in alone]} ms), during the flood "
          f"{[n for n, _ in flooded]} in 3 s (p99 {[round(p * 1000, 1) for _, p in flooded]} ms)")
    assert sum(floods) > 1000, "the flood ran"
    for count, p99 in flooded:
        assert count >= 30 and p99 < 1.0  # served throughout: under 1 s even on a loaded 2-core machine
