"""The living machine in process: the recording's inputs per cycle, the PLC on the server's clock,
a run-time fault that stops the PLC but not the machine, the minute lines, and bad input."""

from __future__ import annotations

import asyncio
import socket
from pathlib import Path

import numpy as np
import pytest

from nckemu.clients.async_client import AsyncNckClient
from nckemu.emulator.faces.s7.server import EmulatorServer
from nckemu.emulator.machine.clock import LiveClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import load_machine
from nckemu.errors import NckConfigError
from nckemu.plcsim.drive import RecordingDrive
from nckemu.plcsim.live import LiveMachine, parse_speed
from nckemu.thermal.recordings.recording import load_recording
from tests.support.live_tools import MACHINE, PROGRAM, write_recording

FAULT_PROGRAM = """\
ORGANIZATION_BLOCK OB 1
BEGIN
  L MW 10
  L 1
  +I
  T MW 10
  L MW 10
  L 30
  <I
  JC ok
  OPN DB 99
  L DBW 0
ok: NOP 0
END_ORGANIZATION_BLOCK
"""


def test_drive_interpolates_holds_the_end_and_loops(tmp_path: Path) -> None:
    recording = load_recording(write_recording(tmp_path / "rec.csv", hours=0.5))
    machine = load_machine(MACHINE)
    drive = RecordingDrive(machine, recording, 1.0, warmup_s=120.0)
    assert drive.t0_s == -120.0 and drive.cycles == 1800 + 120 + 1
    bed = recording.temperatures_C["temp_bed_C"]
    for k in (0, 119, 120, 121, 777, drive.cycles - 1):
        inputs = drive.inputs(k)
        assert inputs.t_rec_s == -120.0 + k
        assert dict(inputs.sensors_C)["bed"] == pytest.approx(float(np.interp(-120.0 + k, recording.t_s, bed)))
    end = drive.inputs(drive.cycles + 50)
    assert end.t_rec_s == 1800.0 and dict(end.sensors_C)["bed"] == pytest.approx(float(bed[-1]))
    looping = RecordingDrive(machine, recording, 1.0, warmup_s=120.0, loop=True)
    again = looping.inputs(looping.cycles)
    assert again.t_rec_s == 0.0 and again.recording_pass == 2
    assert dict(again.sensors_C)["bed"] == pytest.approx(float(bed[0]))
    assert looping.inputs(looping.cycles + looping.pass_cycles).recording_pass == 3


@pytest.mark.parametrize("text, speed", [("60x", 60.0), ("60", 60.0), ("1X", 1.0), ("0.5x", 0.5)])
def test_speed_forms(text: str, speed: float) -> None:
    assert parse_speed(text) == speed


@pytest.mark.parametrize("text", ["0", "0x", "-5x", "fast", "nan", "inf"])
def test_speed_refused(text: str) -> None:
    with pytest.raises(NckConfigError, match="--speed"):
        parse_speed(text)


async def _live(tmp_path: Path, program: Path, speed: float, wall_s: float,
                lines: list[str] | None = None) -> tuple[LiveMachine, list[float], list[float]]:
    """Serve a live machine for ``wall_s``; a client reads SD43900 and the bed sensor meanwhile."""
    recording = write_recording(tmp_path / "rec.csv", hours=4.0)
    emulator = Emulator(MACHINE, clock=LiveClock())
    server = EmulatorServer(emulator, port=0)
    await server.start()
    live = LiveMachine(emulator, inputs=recording, plc=program, speed=speed, server=server,
                       on_minute=lines.append if lines is not None else None)
    sd, temperatures = [], []
    speeds: set[int] = set()
    try:
        await live.start()
        async with AsyncNckClient("127.0.0.1", server.port) as client:
            for _ in range(int(wall_s / 0.1)):
                await asyncio.sleep(0.1)
                value, temperature, rpm = await client.get("SD43900[AX4]", "NCKEMU_SENSOR_TEMP[0]", "actSpeed[C1]")
                sd.append(value)
                temperatures.append(temperature)
                speeds.add(round(rpm))
    finally:
        await live.stop()
        await server.stop()
    if wall_s * speed > 3 * 2400:  # long enough for a spindle start and stop: actSpeed follows spindle_rpm
        assert {0, 6000} <= speeds, speeds
    return live, sd, temperatures


async def test_program_runs_on_the_server_clock(tmp_path: Path) -> None:
    lines: list[str] = []
    live, sd, temperatures = await _live(tmp_path, PROGRAM, 3000.0, 3.0, lines)
    snapshot = live.snapshot()
    assert snapshot["plc"] == "RUN" and snapshot["fault"] is None
    assert snapshot["cycles"] > 3000, snapshot            # an hour and more of simulated time
    assert snapshot["jobs"]["PUT"] >= snapshot["cycles"] // 65  # once a minute (the timer and Done take a cycle or two)
    assert max(sd) > 0.0, "the program's writes reach the model the clients read"
    assert temperatures[-1] > temperatures[0]
    # One line per simulated minute, at most two a wall second: 3000x gives one every 50 minutes.
    assert 1 <= len(lines) <= 7, lines
    assert all(line.startswith("live: t ") and "PLC RUN" in line for line in lines)


async def test_a_fault_stops_the_plc_not_the_machine(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    program = tmp_path / "fault.awl"
    program.write_text(FAULT_PROGRAM)
    live, sd, temperatures = await _live(tmp_path, program, 600.0, 2.0)
    snapshot = live.snapshot()
    assert snapshot["plc"] == "STOP"
    assert snapshot["fault"] is not None and "fault.awl line 11: OPN DB 99" in snapshot["fault"]
    assert snapshot["cycles"] > 300, "the recording drives the machine on"
    assert len(sd) >= 15 and temperatures[-1] != temperatures[0], "the S7 face serves on, the bed moves on"
    faults = [r for r in caplog.records if "faulted" in r.getMessage()]
    assert len(faults) == 1 and "\n" not in faults[0].getMessage()


def test_live_machine_needs_a_live_clock_and_a_server(tmp_path: Path) -> None:
    with pytest.raises(NckConfigError, match="LiveClock"):
        LiveMachine(Emulator(MACHINE), inputs=write_recording(tmp_path / "r.csv", hours=0.2))
    with pytest.raises(NckConfigError, match="server="):
        LiveMachine(Emulator(MACHINE, clock=LiveClock()), plc=PROGRAM)


def test_inputs_to_play_back_need_no_gauge_column(tmp_path: Path) -> None:
    """A recording of sensors, speed and positions only (no err_ column: nothing was gauged) drives a
    living machine; the thermal commands still ask for the gauge column."""
    full = write_recording(tmp_path / "full.csv", hours=0.2)
    lines = full.read_text(encoding="utf-8").splitlines()
    inputs_only = tmp_path / "inputs.csv"
    inputs_only.write_text("\n".join(line.rsplit(",", 1)[0] for line in lines) + "\n", encoding="utf-8")
    with pytest.raises(NckConfigError, match="no err_"):
        load_recording(inputs_only)
    live = LiveMachine(Emulator(MACHINE, clock=LiveClock()), inputs=inputs_only)
    assert live.drive is not None
    assert dict(live.drive.inputs(0).sensors_C)["bed"] == pytest.approx(25.0, abs=0.01)


# ---------------------------------------------------------------------- bad input: one line, exit 1
@pytest.mark.parametrize("case", ["missing_column", "speed_0", "no_ob1", "loop_alone", "http_in_use", "bad_awl"])
def test_serve_bad_input_one_line(case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from nckemu.cli import main

    recording = write_recording(tmp_path / "rec.csv", hours=0.2)
    arguments = ["serve", "--port", "0", "--machine", str(MACHINE), "--inputs", str(recording)]
    holder = None
    if case == "missing_column":
        rows = [line.split(",") for line in recording.read_text().splitlines()]
        recording.write_text("\n".join(",".join(r[:1] + r[2:]) for r in rows) + "\n")
        expected = "has no column 'temp_bed_C', which sensor 'bed' (PIW420)"
    elif case == "speed_0":
        arguments += ["--speed", "0"]
        expected = "--speed 0: simulated time must run forward"
    elif case == "no_ob1":
        program = tmp_path / "no_ob1.awl"
        program.write_text("FUNCTION FC 1 : VOID\nBEGIN\nEND_FUNCTION\n")
        arguments += ["--plc", str(program)]
        expected = "no ORGANIZATION_BLOCK OB 1"
    elif case == "bad_awl":
        program = tmp_path / "bad.awl"
        program.write_text("ORGANIZATION_BLOCK OB 1\nBEGIN\n  FROB 1\nEND_ORGANIZATION_BLOCK\n")
        arguments += ["--plc", str(program)]
        expected = "bad.awl"
    elif case == "loop_alone":
        arguments = ["serve", "--port", "0", "--loop"]
        expected = "--loop starts a recording over: it needs --inputs"
    else:
        holder = socket.socket()
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        arguments += ["--http", str(holder.getsockname()[1])]
        expected = "--http: 127.0.0.1:"
    try:
        assert main(arguments) == 1
    finally:
        if holder is not None:
            holder.close()
    err = capsys.readouterr().err.strip().splitlines()
    lines = [line for line in err if not line.startswith("20")]  # the server's own log lines have a date
    assert len(lines) == 1 and expected in lines[0], err
    assert "Traceback" not in "\n".join(err)


async def test_channel_times_and_parts_run_on_the_live_clock(tmp_path: Path) -> None:
    """No recording, no program: --speed alone. The channel's net time runs at the speed; a part
    counted at a simulated time is counted for every client."""
    emulator = Emulator(MACHINE, clock=LiveClock())
    server = EmulatorServer(emulator, port=0)
    await server.start()
    live = LiveMachine(emulator, speed=600.0, server=server)
    try:
        await live.start()
        async with AsyncNckClient("127.0.0.1", server.port) as client:
            before_s = (await client.get("sysTimeUdword"))[0] / 1000.0
            await client.put({"NCKEMU_CHAN_COMMAND[C1]": 1})        # start
            start_s = (await client.get("sysTimeUdword"))[0] / 1000.0   # at 600x a job takes simulated seconds
            await asyncio.sleep(1.0)
            net_s, now_ms = await client.get("actProgNetTime[C1]", "sysTimeUdword")
            await client.put({"NCKEMU_CHAN_COMMAND[C1]": 3})        # end of program: a part
            parts = (await client.get("actParts[C1]"))[0]
    finally:
        await live.stop()
        await server.stop()
    assert 400.0 < now_ms / 1000.0 - start_s < 800.0, "one wall second is ten simulated minutes"
    assert now_ms / 1000.0 - start_s - 1.0 <= net_s <= now_ms / 1000.0 - before_s + 1.0
    assert parts == 1.0


async def test_the_job_log_stays_bounded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import nckemu.plcsim.live as live_module

    monkeypatch.setattr(live_module, "LOG_KEEP", 5)
    live, _sd, _t = await _live(tmp_path, PROGRAM, 6000.0, 1.5)
    snapshot = live.snapshot()
    assert live.runner is not None and len(live.runner.log.jobs) <= 10
    assert snapshot["jobs"]["PUT"] >= snapshot["cycles"] // 65 > 20, "the folded jobs are still counted"


async def test_the_programs_connection_is_never_idle(tmp_path: Path) -> None:
    """A program that writes rarely keeps its connection; an outside client idle as long is closed."""
    from nckemu.emulator.faces.s7.server import ServerLimits

    emulator = Emulator(MACHINE, clock=LiveClock())
    server = EmulatorServer(emulator, port=0, limits=ServerLimits(idle_timeout_s=0.5))
    await server.start()
    live = LiveMachine(emulator, plc=PROGRAM, speed=10.0, server=server)  # a cycle every 0.1 s
    try:
        await live.start()
        idle = AsyncNckClient("127.0.0.1", server.port)
        await idle.connect()
        await asyncio.sleep(1.6)   # no job of the program yet (its first is six wall seconds away)
        peers = {c.peer for c in server.connections}
        await idle.disconnect()
    finally:
        await live.stop()
        await server.stop()
    assert live.plc_peer in peers and len(peers) == 1, peers


def test_a_turning_spindle_runs_a_program_and_a_long_stop_ends_it(tmp_path: Path) -> None:
    """Channel 1 said reset, program aborted, net time 00:00:00 while the recording turned the spindle at
    6000 rpm (issue 37): the recording's spindle drives the channel as an HMI would see it."""
    from nckemu.emulator.machine.clock import SimulatedClock
    from nckemu.emulator.machine.status import machine_status
    from nckemu.plcsim.drive import PROGRAM_END_IDLE_S

    recording = load_recording(write_recording(tmp_path / "rec.csv", hours=2.0, step_s=10.0))
    clock = SimulatedClock(0.0)
    emulator = Emulator(load_machine(MACHINE), clock=clock)
    drive = RecordingDrive(emulator.machine, recording, 1.0, warmup_s=120.0)
    seen = {}
    for k in range(drive.cycles):
        clock.set(float(k))
        inputs = drive.apply(emulator.nck, k)
        t_rec = inputs.t_rec_s
        if t_rec in (600.0, 1500.0, 2390.0, 2400.0 + PROGRAM_END_IDLE_S - 60, 2400.0 + PROGRAM_END_IDLE_S + 60,
                     3700.0):
            seen[t_rec] = machine_status(emulator)["channel"] | {"rpm": inputs.spindle_rpm,
                                                                 "turn": emulator.nck.channels[1].spindle(1).direction}
    # the live_tools recording: 20 minutes at rest, 20 at 6000 rpm, ...
    assert seen[600.0]["status"] == "reset" and seen[600.0]["rpm"] == 0.0 and seen[600.0]["actual_parts"] == 0
    running = seen[1500.0]
    assert running["rpm"] == 6000.0 and running["turn"] == 1
    assert (running["mode"], running["status"], running["program"]) == ("AUTOMATIC", "active", "running")
    # turning since 1200 s (from 1191 s: the rows 10 s apart are interpolated)
    assert running["net_time_s"] == pytest.approx(300.0, abs=10.0)
    assert seen[2390.0]["net_time_s"] == pytest.approx(1190.0, abs=10.0)
    short_stop = seen[2400.0 + PROGRAM_END_IDLE_S - 60]       # a stop shorter than PROGRAM_END_IDLE_S
    assert short_stop["status"] == "active" and short_stop["turn"] == 0 and short_stop["actual_parts"] == 0
    ended = seen[2400.0 + PROGRAM_END_IDLE_S + 60]            # stood long: M30, a part
    # a normal end is "ended" on the status (issue 49: it said "aborted", as after a reset); BTSS still says 5
    assert (ended["status"], ended["program"], ended["actual_parts"]) == ("reset", "ended", 1.0)
    assert seen[3700.0]["status"] == "active" and seen[3700.0]["net_time_s"] == pytest.approx(100.0, abs=10.0)
