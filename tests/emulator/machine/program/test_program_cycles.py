"""Standard cycles as motions with their time: the drilling cycles' positions, feeds, retracts and
dwells; MCALL with the position patterns; CYCLE800 and CYCLE832; a cycle without a motion model is
counted apart, never silently 0 s; an unknown cycle is an alarm; a program's own cycle wins."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

from nckemu.cli import main
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import parse_machine
from nckemu.emulator.machine.nck.program_run import BlockRecord
from nckemu.emulator.machine.offline import run_offline
from nckemu.emulator.machine.program.language.cycles import ALARM_THREAD_PITCH
from nckemu.emulator.machine.program.motions import (
    ALARM_PROGRAM_NOT_FOUND,
    CycleCall,
    Dwell,
    MFunction,
    Move,
    SpindleCommand,
)
from tests.emulator.machine.nck.test_channel_programs import A_Z, MACHINE, V_Z
from tests.emulator.machine.program.support import MAIN, DictEnvironment, run


def z_moves(text: str, env: DictEnvironment | None = None) -> list[tuple[float, float | None]]:
    """(Z target, feed) of every move that names Z."""
    result = run(text, env)
    assert result.alarm is None, result.alarm
    return [(round(move.target_mm["Z"], 6), move.feed) for move in result.moves if "Z" in move.target_mm]


def test_cycle81_and_cycle82_positions_feeds_retracts_and_dwell() -> None:
    result = run("G0 X5 Y5 Z50 F200\nCYCLE82(10, 0, 2, -8, , 1.5)\nCYCLE81(10, 0, 2, , 3)\nM30")
    assert result.alarm is None, result.alarm
    moves = [(move.target_mm, move.feed) for move in result.moves][1:]
    assert moves == [({"Z": 2.0}, None), ({"Z": -8.0}, 200.0), ({"Z": 10.0}, None),   # CYCLE82
                     ({"Z": 2.0}, None), ({"Z": -3.0}, 200.0), ({"Z": 10.0}, None)]   # CYCLE81: DPR 3 below RFP
    assert result.of(Dwell) == [Dwell(seconds=1.5)]
    assert result.of(CycleCall) == [CycleCall("CYCLE82"), CycleCall("CYCLE81")]


def test_cycle83_chip_removal_strokes_shorten_by_the_degression() -> None:
    moves = z_moves("G0 Z50 F100\nCYCLE83(10, 0, 1, -20, , -5, , 5, 0, 0, 1, 1)\nM30")
    assert moves[1:] == [(1.0, None), (-5.0, 100.0), (1.0, None), (-4.4, None), (-10.0, 100.0), (1.0, None),
                         (-9.4, None), (-15.0, 100.0), (1.0, None), (-14.4, None), (-20.0, 100.0), (10.0, None)]


def test_cycle83_chip_breaking_backs_off_and_the_first_stroke_runs_at_frf() -> None:
    moves = z_moves("G0 Z50 F100\nCYCLE83(10, 0, 1, -12, , -6, , 0, 0, 0, 0.5, 0)\nM30")
    assert moves[1:] == [(1.0, None), (-6.0, 50.0), (-5.0, 100.0), (-12.0, 100.0), (10.0, None)]


def test_tapping_feeds_follow_the_pitch_and_the_spindle_turns_again() -> None:
    result = run("G0 Z50\nS400 M3\nCYCLE84(10, 0, 2, -10, , 0, 3, 10, , 0, 500, 800)\nM30")
    assert result.alarm is None, result.alarm
    feeds = [move.feed for move in result.moves if isinstance(move, Move)][1:]
    assert feeds == [None, 750.0, 1200.0, None]                        # M10: 1.5 mm pitch
    assert result.of(SpindleCommand)[-1] == SpindleCommand(1, 400.0, "M3")
    assert run("G0 Z50\nCYCLE84(10, 0, 2, -10, , 0, 3, 0, 0, 0, 500)\nM30").alarm.number == ALARM_THREAD_PITCH  # type: ignore[union-attr]


def test_boring_cycles_stop_lift_and_retract_as_described() -> None:
    result = run("G0 X0 Y0 Z50 F100\nS100 M3\nCYCLE86(10, 0, 2, -5, , 1, 3, -1, 0, 0.5, 0)\nCYCLE87(10, 0, 2, -5, , 4)\n"
                 "CYCLE85(10, 0, 2, -5, , 0, 50, 300)\nM30")
    assert result.alarm is None, result.alarm
    targets = [move.target_mm for move in result.moves][1:]
    assert targets[:5] == [{"Z": 2.0}, {"Z": -5.0}, {"X": -1.0, "Y": 0.0, "Z": -4.5}, {"Z": 2.0}, {"X": 0.0, "Y": 0.0}]
    assert MFunction(0) in result.events                                    # CYCLE87 waits for NC start
    assert [move.feed for move in result.moves][-3:] == [50.0, 300.0, None]    # CYCLE85: FFR in, RFF out


def test_mcall_with_holes1_drills_each_hole_of_the_row() -> None:
    result = run("G0 X0 Y0 Z10 F200\nMCALL CYCLE81(10, 0, 1, -3)\nHOLES1(10, 20, 0, 5, 10, 3)\nMCALL\nG0 X0\nM30")
    assert result.alarm is None, result.alarm
    targets = [move.target_mm for move in result.moves][1:]
    expected = []
    for x in (15.0, 25.0, 35.0):
        expected += [{"X": x, "Y": 20.0}, {"Z": 1.0}, {"Z": -3.0}, {"Z": 10.0}]
    assert targets == [*expected, {"X": 0.0}]                                  # MCALL alone ends it


def test_holes2_and_cycle801_patterns() -> None:
    result = run("G0 X0 Y0\nHOLES2(0, 0, 10, 90, 0, 4)\nCYCLE801(0, 0, 0, 5, 8, 3, 2)\nM30")
    assert result.alarm is None, result.alarm
    points = [(round(m.target_mm["X"], 6) + 0.0, round(m.target_mm["Y"], 6) + 0.0) for m in result.moves[1:]]
    assert points[:4] == [(0.0, 10.0), (-10.0, 0.0), (0.0, -10.0), (10.0, 0.0)]
    assert points[4:] == [(0.0, 0.0), (5.0, 0.0), (10.0, 0.0), (10.0, 8.0), (5.0, 8.0), (0.0, 8.0)]


def test_mcall_of_a_drilling_cycle_after_each_motion_block() -> None:
    moves = z_moves("G0 X0 Y0 Z10 F100\nMCALL CYCLE82(10, 0, 1, -2, , 0)\nX10\nX20 Y5\nMCALL\nX30\nM30")
    assert moves[1:] == [(1.0, None), (-2.0, 100.0), (10.0, None)] * 2


def test_cycle800_positions_the_rotary_axis_and_sets_the_swivel_frame() -> None:
    result = run('G0 X0 Y0 Z0 B0\nCYCLE800(0,"TABLE",200000,57,0,0,0,0,30,0,0,0,0,-1,100,1)\nG0 X10\n'
                 'CYCLE800()\nG0 X10\nM30')
    assert result.alarm is None, result.alarm
    swivel, turned, plain = result.moves[1:]
    assert swivel.target_mm == {"B": 30.0}
    assert turned.target_mm == pytest.approx({"X": 10 * math.cos(math.radians(30)),
                                              "Z": -10 * math.sin(math.radians(30))})
    assert plain.target_mm == {"X": 10.0}          # deselected: B stays at 30


def test_cycle832_records_its_tolerance_and_switches_to_continuous_path() -> None:
    result = run("G0 X0 F100\nCYCLE832(0.02,_ROUGH,1)\nG1 X10\nM30")
    assert result.alarm is None, result.alarm
    assert result.of(CycleCall) == [CycleCall("CYCLE832", note="CYCLE832 tolerance 0.02 mm")]
    assert result.moves[-1].exact_stop is False


def test_an_unknown_cycle_is_an_alarm_with_program_and_line() -> None:
    result = run("G0 X0\nCYCLE999(1, 2)\nM30")
    assert result.alarm is not None
    assert (result.alarm.number, result.alarm.program, result.alarm.line) == (ALARM_PROGRAM_NOT_FOUND, MAIN, 2)
    assert "CYCLE999" in str(result.alarm)


def test_a_programs_own_cycle_overrides_the_built_in_one() -> None:
    own = "PROC CYCLE81(REAL _RTP, REAL _RFP, REAL _SDIS, REAL _DP, REAL _DPR)\nR1 = R1 + 1\nG0 Z=_RTP\nRET"
    env = DictEnvironment(programs={"CYCLE81.SPF": own})
    result = run("G0 Z50\nCYCLE81(10, 0, 2, -5)\nM30", env)
    assert result.alarm is None and env.r_parameter(1) == 1.0
    assert [move.target_mm for move in result.moves] == [{"Z": 50.0}, {"Z": 10.0}]
    assert result.of(CycleCall) == []


def offline(text: str) -> tuple[list[BlockRecord], object]:
    clock = SimulatedClock()
    emu = Emulator(parse_machine(MACHINE, "test.toml"), clock=clock)
    emu.nck.programs.write(MAIN, text.encode())
    blocks: list[BlockRecord] = []
    result = run_offline(emu, MAIN, on_block=blocks.append)
    assert result.outcome == "ended", result.alarms
    return blocks, result


def rapid_s(distance_mm: float) -> float:
    """A rapid of Z at 3000 mm/min, 0.5 m/s²: the trapezoid (long enough to reach full speed)."""
    assert distance_mm >= V_Z * V_Z / A_Z
    return distance_mm / V_Z + V_Z / A_Z


def test_a_drilling_cycle_takes_its_time_with_retracts_and_dwell() -> None:
    """CYCLE82(10, 0, 2, -5, , 1.5) from Z10 at F300 on the test mill (Z: 3000 mm/min, 0.5 m/s²):
    rapid 10 -> 2 (8 mm: 8/50 + 50/500 = 0.26 s), feed 2 -> -5 (7 mm at 5 mm/s: 1.4 + 0.01 s),
    dwell 1.5 s, rapid -5 -> 10 (15 mm: 0.3 + 0.1 s): 3.57 s, every move from and to standstill."""
    blocks, _ = offline("G0 X0 Y0 Z10\nF300\nCYCLE82(10, 0, 2, -5, , 1.5)\nM30")
    cycle = next(block for block in blocks if block.text.startswith("CYCLE82"))
    expected = rapid_s(8.0) + (7.0 / 5.0 + 5.0 / A_Z) + 1.5 + rapid_s(15.0)
    assert expected == pytest.approx(3.57)
    assert cycle.end_s - cycle.start_s == pytest.approx(expected, abs=1e-6)
    assert cycle.positions_mm["Z"] == pytest.approx(10.0)


def test_a_cycle_without_a_motion_model_is_counted_apart() -> None:
    blocks, result = offline("G0 X0 Y0 Z10\nCYCLE62(, 1, , )\nCYCLE62(, 1, , )\nPOCKET3(10, 0, 1, -5)\n"
                             "CYCLE62(, 1, , )\nM30")
    assert result.not_simulated == {"CYCLE62": 3, "POCKET3": 1}  # type: ignore[attr-defined]
    assert result.not_simulated_lines() == ["CYCLE62 not simulated: 0 s counted, 3 calls",  # type: ignore[attr-defined]
                                            "POCKET3 not simulated: 0 s counted, 1 call"]
    noted = [block for block in blocks if block.note]
    assert [block.note for block in noted] == ["CYCLE62 not simulated"] * 2 + ["POCKET3 not simulated",
                                                                              "CYCLE62 not simulated"]
    assert all(block.end_s == block.start_s for block in noted)


def test_program_run_names_the_cycles_it_did_not_simulate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The run summary and the block table of ``nckemu program run`` (default machine: Z travel -1000..0)."""
    program = tmp_path / "CAM.MPF"
    program.write_text("G54 G0 X10 Y10 Z-50 F200\nTRANS Z-100\nCYCLE62(, 1, , )\nCYCLE62(, 1, , )\nSLOT1(1)\n"
                       "CYCLE62(, 1, , )\nM30\n")
    blocks = tmp_path / "blocks.csv"
    assert main(["program", "run", str(program), "--blocks", str(blocks)]) == 0
    out = capsys.readouterr().out
    assert "CYCLE62 not simulated: 0 s counted, 3 calls" in out and "SLOT1 not simulated: 0 s counted, 1 call" in out
    rows = list(csv.DictReader(blocks.open()))
    assert [row["note"] for row in rows if row["note"]] == ["CYCLE62 not simulated"] * 2 + [
        "SLOT1 not simulated", "CYCLE62 not simulated"]
    assert main(["program", "run", str(program), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["not_simulated"] == {"CYCLE62": 3, "SLOT1": 1}
