"""Positioning axes on the channel (issue 49): ``POS[U]=..`` moves U on its own at FA (or MD32060 without
FA) within its MD32000/MD32300, and the block changes when the path and U have arrived; ``POSA`` runs on
past the block until ``WAITP(U)``, a later block that needs U, or the program's end. Times by hand, each
block's time read from the offline block table; positions on S7 while the axis runs."""

from __future__ import annotations

import time

import pytest

from nckemu.catalogue.program_names import program_path
from nckemu.clients import NckClient
from nckemu.emulator.machine.clock import LiveClock, SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import parse_machine
from nckemu.emulator.machine.nck.program_run import BlockRecord
from nckemu.emulator.machine.offline import run_offline
from nckemu.emulator.machine.program.environment import ProgramEnvironment
from nckemu.emulator.machine.program.language import Interpreter
from nckemu.emulator.machine.program.motions import AxesWait, Positioning, ProgramAlarm
from nckemu.emulator.runner import EmulatorThread

# A grinder's X (path) at 6 m/min and 1 m/s², its infeed U at 3 m/min and 0.5 m/s², MD32060 of U 1200 mm/min.
GRINDER = """
name = "positioning test grinder"
channels = 1
[[axis]]
number = 1
name = "X1"
travel_mm = [-500.0, 500.0]
[[axis]]
number = 2
name = "Z1"
travel_mm = [-500.0, 500.0]
[[axis]]
number = 3
name = "U1"
travel_mm = [-100.0, 400.0]
[initial]
MD32000 = { 1 = 6000.0, 2 = 6000.0, 3 = 3000.0 }
MD32300 = { 1 = 1.0, 2 = 1.0, 3 = 0.5 }
MD32060 = { 3 = 1200.0 }
"""


def blocks_of(text: str) -> tuple[dict[str, BlockRecord], float]:
    """Run ``text`` offline: the block table by block number, and the program's run time."""
    emulator = Emulator(parse_machine(GRINDER, "test.toml"), clock=SimulatedClock())
    emulator.cycle_s = 0.1
    path = program_path("POS.MPF")
    emulator.nck.programs.write(path, text.encode())
    records: list[BlockRecord] = []
    result = run_offline(emulator, path, on_block=records.append)
    assert result.outcome == "ended", result.alarms
    return {record.number: record for record in records if record.number}, records[-1].end_s - records[0].start_s


def took_s(record: BlockRecord) -> float:
    return record.end_s - record.start_s


def trapezoid_s(length_mm: float, speed_mm_min: float, accel_m_s2: float) -> float:
    speed, accel = speed_mm_min / 60.0, accel_m_s2 * 1000.0
    return length_mm / speed + speed / accel  # long enough to reach full speed: two half ramps


def test_pos_at_fa_holds_the_block_until_the_axis_arrives() -> None:
    # U 100 mm at FA 500 mm/min: 12 s plus 8.33/500 s of ramps; X 10 mm at F1000 beside it takes 0.6 s
    table, _ = blocks_of("N10 G1 F1000 FA[U]=500\nN20 POS[U]=100 X10\nN30 X20\nM30\n")
    assert took_s(table["N20"]) == pytest.approx(trapezoid_s(100.0, 500.0, 0.5), rel=1e-9)
    assert table["N20"].positions_mm["U"] == pytest.approx(100.0)
    assert took_s(table["N30"]) == pytest.approx(trapezoid_s(10.0, 1000.0, 1.0), rel=1e-9)


def test_pos_without_fa_runs_at_md32060_and_fa_above_md32000_is_held_to_it() -> None:
    table, _ = blocks_of("N10 POS[U]=60\nN20 FA[U]=9000\nN30 POS[U]=0\nM30\n")
    assert took_s(table["N10"]) == pytest.approx(trapezoid_s(60.0, 1200.0, 0.5), rel=1e-9)  # 3.04 s
    assert took_s(table["N30"]) == pytest.approx(trapezoid_s(60.0, 3000.0, 0.5), rel=1e-9)  # MD32000: 1.3 s


def test_posa_runs_past_block_ends_until_waitp() -> None:
    # POSA U100 at 500 mm/min takes 12.0167 s; the X blocks after it run meanwhile (0.6 s each), and
    # WAITP(U) holds the program until U has arrived: the run takes U's time, not U's plus X's.
    u_s = trapezoid_s(100.0, 500.0, 0.5)
    x_s = trapezoid_s(10.0, 1000.0, 1.0)
    table, total = blocks_of("N10 G1 F1000 FA[U]=500\nN20 POSA[U]=100\nN30 X10\nN40 X20\nN50 WAITP(U)\n"
                             "N60 X30\nM30\n")
    assert took_s(table["N20"]) == pytest.approx(0.0, abs=1e-9)
    assert took_s(table["N30"]) == pytest.approx(x_s, rel=1e-9)
    assert took_s(table["N50"]) == pytest.approx(u_s - 2 * x_s, rel=1e-9)
    assert table["N50"].positions_mm["U"] == pytest.approx(100.0)
    assert total == pytest.approx(u_s + x_s, rel=1e-9)


def test_a_later_block_that_needs_the_posa_axis_waits_for_it_and_so_does_the_end() -> None:
    u_s = trapezoid_s(100.0, 500.0, 0.5)
    table, total = blocks_of("N10 FA[U]=500\nN20 POSA[U]=100\nN30 POS[U]=0\nM30\n")
    # N30 waits for U at 100, then brings it back: the same time again
    assert took_s(table["N30"]) == pytest.approx(2 * u_s, rel=1e-9)
    table, total = blocks_of("N10 FA[U]=500\nN20 POSA[U]=100\nN30 M30\n")
    assert total == pytest.approx(u_s, rel=1e-9)  # the part is done when U is


def test_positioning_in_the_work_system_and_incremental() -> None:
    # G91 (and IC) add to the last programmed position; the work offset of G54 shifts the end point
    table, _ = blocks_of("N10 FA[U]=3000\nN20 POS[U]=50\nN30 G91 POS[U]=20\nN40 G90 POS[U]=IC(-10)\nM30\n")
    assert table["N30"].positions_mm["U"] == pytest.approx(70.0)
    assert table["N40"].positions_mm["U"] == pytest.approx(60.0)


def test_the_interpreter_emits_positioning_and_the_wait() -> None:
    env = ProgramEnvironment(axes=("X", "Z", "U"))
    events = list(Interpreter(env, "/_N_MPF_DIR/_N_P_MPF",
                              "FA[U]=400\nPOS[U]=5 X1 G1 F100\nPOSA[U]=IC(2)\nWAITP(U)\nPOSP[U]=(20, 5, 0)\nM30").events())
    kinds = [event for event in events if event.__class__ in (Positioning, AxesWait)]
    assert kinds == [Positioning("U", 5.0, 400.0, 5.0), AxesWait(("U",)), Positioning("U", 7.0, 400.0, 7.0),
                     AxesWait(("U",)), Positioning("U", 20.0, 400.0, 20.0), AxesWait(("U",))]


@pytest.mark.parametrize(("block", "number"), [("POS[Q]=5", 12550), ("POS[U]", 12080), ("WAITP(Q)", 12550)])
def test_bad_positioning_words_are_alarms_with_their_line(block: str, number: int) -> None:
    env = ProgramEnvironment(axes=("X", "Z", "U"))
    with pytest.raises(ProgramAlarm) as raised:
        list(Interpreter(env, "/_N_MPF_DIR/_N_P_MPF", f"G0 X0\n{block}\nM30").events())
    assert (raised.value.number, raised.value.line) == (number, 2)


def test_positioning_beyond_the_travel_is_the_software_limit_alarm() -> None:
    emulator = Emulator(parse_machine(GRINDER, "test.toml"), clock=SimulatedClock())
    path = program_path("FAR.MPF")
    emulator.nck.programs.write(path, b"POS[U]=900\nM30\n")
    result = run_offline(emulator, path)
    assert result.outcome == "alarm" and "10720" in result.alarms[0] and "line 1" in result.alarms[0]


def test_a_posa_axis_moves_on_the_s7_face_while_it_runs() -> None:
    # U 50 mm at FA 300 mm/min: 10 s of simulated time, 1 s at 10x; seen over S7 on its way, not jumping
    emulator = Emulator(parse_machine(GRINDER, "test.toml"), clock=LiveClock(speed=10.0))
    path = program_path("POSA.MPF")
    with EmulatorThread(emulator=emulator) as emu:
        channel = emulator.nck.channels[1]
        emu.call(lambda: emulator.nck.programs.write(path, b"FA[U]=300\nPOSA[U]=50\nWAITP(U)\nM30\n"))
        emu.call(lambda: channel.select(path))
        seen: list[float] = []
        with NckClient("127.0.0.1", emu.port, slot=2) as plc, NckClient("127.0.0.1", emu.port) as nck:
            plc.db_write(21, 7, b"\x02")  # NC start
            deadline = time.monotonic() + 20.0
            while time.monotonic() < deadline:
                (position,) = nck.get("NCKEMU_ACTUAL_POS[AX3]")
                seen.append(float(position))
                if abs(seen[-1] - 50.0) < 1e-6:
                    break
                time.sleep(0.05)
    assert any(0.5 < value < 49.5 for value in seen), seen
    assert seen[-1] == pytest.approx(50.0)
