"""Programs run on a served machine (issue 41): the SYIL 828D warm-up as sent, its time checked by
hand; python-snap7 and our client start, stop and reset through DB21; BTSS reads see the run; bad
programs end in the control's alarm while the server keeps serving."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import snap7

from nckemu.clients.sync import NckClient
from nckemu.emulator.machine.clock import LiveClock, SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import load_machine
from nckemu.emulator.machine.nck.channel import CHAN_ACTIVE, CHAN_INTERRUPTED, CHAN_RESET
from nckemu.emulator.machine.offline import run_offline
from nckemu.emulator.runner import EmulatorThread
from nckemu.errors import NckError
from tests.conftest import FIXTURES

SYIL_MACHINE = FIXTURES / "machines" / "syil_x7.toml"
DAILY = "/_N_MPF_DIR/_N_DAILY_MPF"
INCH_MM = 25.4


def _syil(shared_dir: Path) -> tuple[bytes, bytes]:
    folder = shared_dir / "programs" / "syil_828d_warmup"
    return (folder / "routines" / "DAILY.MPF").read_bytes(), (folder / "subroutines" / "WARMUP_CYCLE.SPF").read_bytes()


def _store_syil(emulator: Emulator, shared_dir: Path) -> None:
    daily, cycle = _syil(shared_dir)
    emulator.nck.programs.write(DAILY, daily)
    emulator.nck.programs.write("/_N_SPF_DIR/_N_WARMUP_CYCLE_SPF", cycle)


def syil_time_by_hand() -> tuple[float, float]:
    """One WARMUP_CYCLE loop and the whole DAILY.MPF, from the program text and syil_x7.toml.

    The loop's 13 G1 moves at F300 in/min (G700) from X0 Y0 Z0: Z4, X5, Y5, Z4, X5, Y5 in, then the
    diagonal X5 Y5, Z4, the diagonal back, Z4, Y5, the diagonal X5 Y5 again and X5: 28 in + 18 in +
    3 x 5*sqrt(2) in. Each block starts and ends at standstill (G60, exact stop): it takes its length at
    127 mm/s plus v/a for its two half ramps, a = MD32300 = 3 m/s² per axis, sqrt(2) times that along a
    45° diagonal (each axis carries 1/sqrt(2) of it). MD32000 (36 m/min) does not limit 7.62 m/min.
    CYCLES = 600 / 15 = 40 per call. Each M3 S=... ramps the spindle at 40 rev/s²: 3600 rpm in 1.5 s
    (from 0, then from 3600 to 7200), and the first G1 waits for it (MD35500-like). The G0 SUPA moves
    to machine zero start and end where the axes already are: no time.
    """
    v = 300.0 * INCH_MM / 60.0                      # 127 mm/s
    a = 3000.0                                      # mm/s²
    straight_in = 4 + 5 + 5 + 4 + 5 + 5 + 4 + 4 + 5 + 5
    diagonal_in = 3 * 5 * math.sqrt(2)
    path_s = (straight_in + diagonal_in) * INCH_MM / v
    ramps_s = 10 * v / a + 3 * v / (a * math.sqrt(2))
    cycle_s = path_s + ramps_s
    spindle_s = 2 * 3600.0 / 60.0 / 40.0
    return cycle_s, spindle_s + 80 * cycle_s


def test_syil_daily_warm_up_offline_takes_its_time(shared_dir: Path) -> None:
    cycle_s, total_s = syil_time_by_hand()
    assert 13.9 < cycle_s < 14.0            # the author's note: "approx 15 s at F300"
    emulator = Emulator(SYIL_MACHINE, clock=SimulatedClock())
    _store_syil(emulator, shared_dir)
    blocks = []
    samples: list[list[float]] = []
    result = run_offline(emulator, DAILY, on_block=blocks.append, on_sample=samples.append, sample_s=10.0)
    assert result.outcome == "ended", result.alarms
    assert result.net_time_s == pytest.approx(total_s, abs=1e-6)
    channel = emulator.nck.channels[1]
    assert channel.state.status == CHAN_RESET and channel.state.end_counter == 1 and channel.state.actual_parts == 1
    assert blocks[-1].text.startswith("M02") and 2 in blocks[-1].m_codes
    # one loop, block by block: the 13 moves of the first WARMUP_CYCLE loop end cycle_s after it began
    loop = [b for b in blocks if b.program.endswith("_N_WARMUP_CYCLE_SPF") and b.text.startswith("G1")][:13]
    assert loop[-1].end_s - loop[0].start_s == pytest.approx(cycle_s + 1.5, abs=1e-6)   # the first waits 1.5 s
    # the spindle is at 3600 rpm for the first ten minutes and at 7200 rpm for the next ones
    spindle = {round(row[0]): row[3] for row in samples}
    assert {spindle[t] for t in range(10, 550, 10)} == {3600.0}
    assert {spindle[t] for t in range(570, 1110, 10)} == {7200.0}
    # the heat: the spindle head has warmed, and its PIW word moved
    assert emulator.nck.sensor_temperature_C("spindle_head") > 22.0 + 4.0
    assert emulator.plc.read(0x81, 0, 256, 2) != int(round(22.0 * 276.48)).to_bytes(2, "big")


@pytest.fixture
def served() -> Iterator[EmulatorThread]:
    emulator = Emulator(SYIL_MACHINE, clock=LiveClock(speed=600.0))
    with EmulatorThread(emulator=emulator) as emu:
        yield emu


@pytest.fixture
def snap7_plc(served: EmulatorThread) -> Iterator[snap7.Client]:
    logging.getLogger("snap7").setLevel(logging.WARNING)
    client = snap7.Client()
    client.connect("127.0.0.1", 0, 2, served.port)
    yield client
    client.disconnect()


def _wait(predicate, timeout_s: float = 20.0) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("timed out")
        time.sleep(0.02)


def test_syil_served_at_600x_seen_over_s7(served: EmulatorThread, snap7_plc: snap7.Client, shared_dir: Path) -> None:
    """Selected with PI _N_SELECT, started with DB21.DBX7.1 from python-snap7; our client watches the
    run over BTSS: program status, the block, the spindle, the positions, the counters."""
    served.call(lambda: _store_syil(served.emulator, shared_dir))
    seen: dict[str, set[object]] = {"status": set(), "block": set(), "speed": set(), "z": set(), "db35": set()}
    with NckClient("127.0.0.1", served.port) as nck:
        nck.pi_service("_N_SELECT", "201", DAILY)
        assert nck.get("/Channel/ProgramInfo/selectedWorkPProg[u1]")[0] == DAILY
        snap7_plc.db_write(21, 7, bytearray(b"\x02"))                        # NC start
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            status, block, speed, z, ended = nck.get("progStatus[C1]", "actBlock[C1]", "actSpeed[C1]",
                                                     "NCKEMU_ACTUAL_POS[AX3]", "ncProgEndCounter[C1]")
            seen["status"].add(status)
            seen["block"].add(block)
            seen["speed"].add(round(speed))
            seen["z"].add(round(z, 1))
            seen["db35"].add(snap7_plc.db_read(21, 35, 1)[0])
            if ended:
                break
            time.sleep(0.01)
        net_s, parts, starts, chan = nck.get("oldProgNetTime[C1]", "actParts[C1]", "ncStartCounter[C1]",
                                             "chanStatus[C1]")
    assert ended == 1 and chan == 0 and parts == 1.0 and starts == 1
    assert net_s == pytest.approx(syil_time_by_hand()[1], abs=1e-6)   # 1x, 600x or offline: the same time
    assert 3 in seen["status"]                                          # running
    assert {3600, 7200} <= seen["speed"]
    assert any(value < -50.0 for value in seen["z"])                     # Z went 4 in down
    assert any(text.startswith("G1 SUPA") for text in seen["block"])
    assert 0x21 in seen["db35"]                                          # channel active, program running


def test_snap7_and_our_client_start_stop_reset_through_db21(served: EmulatorThread, snap7_plc: snap7.Client,
                                                            shared_dir: Path) -> None:
    served.call(lambda: _store_syil(served.emulator, shared_dir))
    channel = served.emulator.nck.channels[1]
    served.call(lambda: channel.select(DAILY))
    snap7_plc.db_write(21, 7, bytearray(b"\x02"))
    _wait(lambda: channel.state.status == CHAN_ACTIVE)
    snap7_plc.db_write(21, 7, bytearray(b"\x08"))                             # stop (start released)
    _wait(lambda: channel.state.status == CHAN_INTERRUPTED)
    assert snap7_plc.db_read(21, 35, 1)[0] == 0x44
    with NckClient("127.0.0.1", served.port, slot=2) as plc:
        plc.db_write(21, 7, b"\x02")                                          # our client: start again
        _wait(lambda: channel.state.status == CHAN_ACTIVE)
        plc.db_write(21, 7, b"\x80")                                          # reset
        _wait(lambda: channel.state.status == CHAN_RESET)
        assert plc.db_read(21, 35, 1) == b"\x90"
    assert (channel.state.start_counter, channel.state.reset_counter) == (2, 1)


@pytest.mark.parametrize(("text", "number"), [
    ("G1 X=)\nM30\n", 12080),
    ("EXTERN NOSUB(REAL)\nNOSUB(1)\nM30\n", 14011),
    ("GOTOF NOWHERE\nM30\n", 14080),
    ("R1=0\nR2=5/R1\nM30\n", None),
])
def test_bad_programs_alarm_and_the_server_serves_on(served: EmulatorThread, snap7_plc: snap7.Client, text: str,
                                                     number: int | None) -> None:
    served.call(lambda: served.emulator.nck.programs.write("/_N_MPF_DIR/_N_BAD_MPF", text.encode()))
    with NckClient("127.0.0.1", served.port) as nck:
        nck.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_BAD_MPF")
        snap7_plc.db_write(21, 7, bytearray(b"\x02"))
        _wait(lambda: nck.get("numAlarms")[0] == 1)
        alarm, status = nck.get("alarmNo", "chanStatus[C1]")
        if number is not None:
            assert alarm == number
        assert status == CHAN_INTERRUPTED
        with pytest.raises(NckError):                                           # select while not in reset
            nck.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_BAD_MPF")
        snap7_plc.db_write(21, 7, bytearray(b"\x80"))                            # reset clears it
        _wait(lambda: nck.get("numAlarms", "chanStatus[C1]") == [0, 0])


def test_an_endless_loop_keeps_the_faces_served_and_reset_stops_it(served: EmulatorThread,
                                                                    snap7_plc: snap7.Client) -> None:
    served.call(lambda: served.emulator.nck.programs.write("/_N_MPF_DIR/_N_LOOP_MPF",
                                                           b"L1:\nR1=R1+1\nGOTOB L1\n"))
    with NckClient("127.0.0.1", served.port) as nck:
        nck.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_LOOP_MPF")
        snap7_plc.db_write(21, 7, bytearray(b"\x02"))
        latencies = []
        for _ in range(30):
            started = time.perf_counter()
            (r1,) = nck.get("R1[C1]")
            latencies.append(time.perf_counter() - started)
        assert r1 > 1000 and max(latencies) < 1.0            # the loop runs, the clients are answered
        snap7_plc.db_write(21, 7, bytearray(b"\x80"))
        _wait(lambda: nck.get("chanStatus[C1]")[0] == CHAN_RESET)
        (r_after,) = nck.get("R1[C1]")
        time.sleep(0.2)
        assert nck.get("R1[C1]")[0] == r_after              # stopped


def test_nc_start_in_jog_or_without_a_program_is_refused(served: EmulatorThread, snap7_plc: snap7.Client) -> None:
    with NckClient("127.0.0.1", served.port) as nck:
        snap7_plc.db_write(21, 7, bytearray(b"\x02"))                           # nothing selected
        _wait(lambda: nck.get("numAlarms")[0] == 1)
        assert nck.get("alarmNo", "chanStatus[C1]") == [16912, CHAN_RESET]
        snap7_plc.db_write(21, 7, bytearray(b"\x80"))
        snap7_plc.db_write(11, 0, bytearray(b"\x04"))                           # JOG
        _wait(lambda: nck.get("opMode")[0] == 0)
        assert snap7_plc.db_read(11, 6, 1) == bytearray(b"\x04")
        nck.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_TEST_MPF")
        snap7_plc.db_write(21, 7, bytearray(b"\x02"))
        _wait(lambda: nck.get("numAlarms")[0] == 1)
        assert nck.get("chanStatus[C1]") == [CHAN_RESET]


def test_syil_machine_file_loads() -> None:
    machine = load_machine(SYIL_MACHINE)
    assert machine.program.spindle_accel_rev_s2 == 40.0 and [s.name for s in machine.sensors] == ["spindle_head",
                                                                                                 "column"]
