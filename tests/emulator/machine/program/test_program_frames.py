"""Frames with values: ROT/AROT (about an axis and in the plane), SCALE/ASCALE, MIRROR/AMIRROR in the
control's order of the frame chain; circles through a frame; the frame variables; a frame that scales
by 0 is an alarm with program and line."""

from __future__ import annotations

import math

import pytest

from nckemu.emulator.machine.frame_math import Frame, rotation_rpy, rpy_angles
from nckemu.emulator.machine.program.language.alarms import ALARM_FRAME
from nckemu.emulator.machine.program.motions import Arc, Move
from tests.emulator.machine.program.support import MAIN, DictEnvironment, run


def targets(text: str, env: DictEnvironment | None = None) -> list[dict[str, float]]:
    result = run(text, env)
    assert result.alarm is None, result.alarm
    return [{axis: round(value, 9) + 0.0 for axis, value in move.target_mm.items()} for move in result.moves]


def test_plane_rotation_turns_the_work_axes_and_arot_adds() -> None:
    moves = targets("G0 X10 Y0\nROT RPL=90\nG1 X10 F100\nX20 Y5\nAROT RPL=-90\nX3 Y4\nM30")
    # ROT RPL=90 in G17: the work X axis lies along machine +Y, Y kept in the work system (0)
    assert moves[1] == {"X": 0.0, "Y": 10.0}
    assert moves[2] == {"X": -5.0, "Y": 20.0}
    assert moves[3] == {"X": 3.0, "Y": 4.0}    # AROT RPL=-90 undoes it: no rotation left


def test_rotation_about_an_axis_and_rot_replaces_the_frame() -> None:
    moves = targets("TRANS X100\nROT Y-90\nG0 X1 Y2 Z3\nTRANS X100\nG0 X1 Y2 Z3\nM30")
    # ROT deletes the translation; about Y by -90: work X along machine +Z, work Z along machine -X
    assert moves[0] == {"X": -3.0, "Y": 2.0, "Z": 1.0}
    assert moves[1] == {"X": 101.0, "Y": 2.0, "Z": 3.0}


def test_atrans_after_a_rotation_goes_along_the_rotated_axes() -> None:
    moves = targets("ROT Z90\nATRANS X10\nG0 X0 Y0\nM30")
    assert moves[0] == {"X": 0.0, "Y": 10.0}


def test_scale_and_ascale_multiply_mirror_and_amirror_toggle() -> None:
    moves = targets("SCALE X2 Y3\nG0 X5 Y5\nASCALE X0.5\nX5\nMIRROR X0\nX5 Y5\nAMIRROR Y0\nY5\nAMIRROR X0\nX5\n"
                    "SCALE\nX7 Y7\nM30")
    assert moves == [{"X": 10.0, "Y": 15.0}, {"X": 5.0}, {"X": -5.0, "Y": 5.0}, {"Y": -5.0}, {"X": 5.0},
                     {"X": 7.0, "Y": 7.0}]


def test_the_chain_is_settable_frame_then_programmable_frame() -> None:
    env = DictEnvironment(offsets={"G54": {"X": 100.0, "Y": 50.0}})
    moves = targets("G54\nROT Z90\nSCALE X2\nG0 X5 Y0\nATRANS X1\nAROT Z90\nG0 X5 Y0\nM30", env)
    # SCALE replaced the rotation: G54 + (10, 0); then ATRANS X1 (scaled: 2) and a rotation by 90.
    # The components act in their order (scale inside rotation): X5 is 10 along the turned X axis.
    assert moves[0] == {"X": 110.0, "Y": 50.0}
    assert moves[1] == {"X": 102.0, "Y": 60.0}


def test_incremental_moves_through_a_rotation() -> None:
    moves = targets("G0 X0 Y0\nROT Z30\nG91 G1 X10 F100\nX10\nM30")
    step = (10 * math.cos(math.radians(30)), 10 * math.sin(math.radians(30)))
    assert moves[1] == pytest.approx({"X": step[0], "Y": step[1]})
    assert moves[2] == pytest.approx({"X": 2 * step[0], "Y": 2 * step[1]})


def test_a_circle_through_a_mirror_turns_the_other_way_and_through_rot_y_lies_in_another_plane() -> None:
    result = run("G0 X10 Y0 Z0\nMIRROR X0\nG0 X10 Y0\nG2 X0 Y10 CR=10 F100\nROT Y-90\nG0 X0 Y0 Z0\n"
                 "G17 G3 X10 Y10 I10 J0\nM30")
    assert result.alarm is None, result.alarm
    arcs = [move for move in result.moves if isinstance(move, Arc)]
    mirrored, turned = arcs
    assert mirrored.plane == "G17" and not mirrored.clockwise
    assert mirrored.target_mm == pytest.approx({"X": 0.0, "Y": 10.0})
    assert mirrored.centre_mm == pytest.approx({"X": -10.0, "Y": 10.0})   # work centre (10, 10)
    # work Z lies along machine -X: a G17 circle of the work is a circle in machine Y-Z (G19)
    assert turned.plane == "G19"
    assert turned.target_mm == pytest.approx({"X": 0.0, "Y": 10.0, "Z": 10.0})
    assert turned.centre_mm == pytest.approx({"Y": 0.0, "Z": 10.0})


def test_frame_variables_read_the_components() -> None:
    env = DictEnvironment(offsets={"G54": {"X": 100.0}, "G505": {"Y": 7.0}})
    text = ("G54\nTRANS X5\nAROT Z30\nASCALE Y2\nAMIRROR X0\nR1=$P_PFRAME[X,TR]\nR2=$P_PFRAME[Z,RT]\n"
            "R3=$P_PFRAME[Y,SC]\nR4=$P_PFRAME[X,MI]\nR5=$P_UIFR[1,X,TR]\nR6=$P_UIFR[5,Y,TR]\nR7=$P_IFRAME[X,TR]\n"
            "R8=$P_ACTFRAME[X,TR]\n$P_PFRAME[Y,TR]=3\nR9=$P_PFRAME[Y,TR]\nG0 X0 Y0\nM30")
    result = run(text, env)
    assert result.alarm is None, result.alarm
    assert [env.r_parameter(i) for i in range(1, 10)] == pytest.approx([5, 30, 2, 1, 100, 7, 100, 105, 3])
    assert result.moves[-1].target_mm == pytest.approx({"X": 105.0, "Y": 3.0})


def test_aa_iw_reads_the_position_back_through_the_frame() -> None:
    env = DictEnvironment(offsets={"G54": {"X": 100.0}})
    run("G54 G0 X0 Y0\nROT Z90\nSCALE X2\nAROT Z90\nG0 X3 Y4\nR1=$AA_IW[X]\nR2=$AA_IW[Y]\nR3=$AA_IM[X]\nM30", env)
    assert [env.r_parameter(i) for i in (1, 2, 3)] == pytest.approx([3.0, 4.0, 100.0 - 4.0])


@pytest.mark.parametrize(("block", "line"), [("SCALE X0", 2), ("ASCALE Y=R1", 2), ("$P_PFRAME[Z,SC]=0", 2)])
def test_a_frame_that_scales_by_zero_is_an_alarm_with_program_and_line(block: str, line: int) -> None:
    result = run(f"G0 X1\n{block}\nG0 X2\nM30")
    assert result.alarm is not None
    assert (result.alarm.number, result.alarm.program, result.alarm.line) == (ALARM_FRAME, MAIN, line)
    assert "scale" in str(result.alarm) and result.alarm.block == block


def test_a_rotation_about_an_axis_that_is_not_a_geometry_axis_is_an_alarm() -> None:
    result = run("ROT A30\nM30")
    assert result.alarm is not None and result.alarm.number == ALARM_FRAME and result.alarm.line == 1


def test_save_restores_the_callers_frame() -> None:
    env = DictEnvironment(programs={"TURNED.SPF": "PROC TURNED SAVE\nROT Z90\nG0 X1 Y0\nRET"})
    moves = targets("ROT Z-90\nTURNED\nG0 X1 Y0\nM30", env)
    assert moves == [{"X": 0.0, "Y": 1.0}, {"X": 0.0, "Y": -1.0}]


def test_rpy_angles_round_trip() -> None:
    angles = {"X": 10.0, "Y": -20.0, "Z": 30.0}
    assert rpy_angles(rotation_rpy(angles)) == pytest.approx(angles)
    frame = Frame({"X": 1.0}, rotation_rpy(angles), {"Y": 2.0}, frozenset({"Z"}))
    point = {"X": 1.0, "Y": 2.0, "Z": 3.0}
    assert frame.inverse_apply(frame.apply(point)) == pytest.approx(point)


def test_moves_without_a_frame_stay_on_the_fast_path() -> None:
    result = run("ROT Z45\nROT\nG0 X1\nG1 Y2 F100\nM30")
    assert [move.target_mm for move in result.moves] == [{"X": 1.0}, {"Y": 2.0}]
    assert all(isinstance(move, Move) for move in result.moves)


def test_a_program_writes_settable_frames_through_p_uifr_and_p_iframe() -> None:
    env = DictEnvironment(offsets={"G54": {"X": 100.0}})
    text = ("G54\n$P_UIFR[1,X,TR]=200\nG0 X1\nG54 G0 X1\n$P_UIFR[5,Y,TR]=7\nR1=$P_UIFR[5,Y,TR]\n$P_IFRAME[Y,TR]=30\n"
            "G0 Y1\nM30")
    result = run(text, env)
    assert result.alarm is None, result.alarm
    # $P_UIFR of the active frame counts from its next selection; $P_IFRAME at once
    assert [move.target_mm for move in result.moves] == [{"X": 101.0}, {"X": 201.0}, {"Y": 31.0}]
    assert env.r_parameter(1) == 7.0 and env.offsets["G54"] == {"X": 200.0, "Y": 30.0}
    bad = run("$P_UIFR[1,X,RT]=30\nM30")
    assert bad.alarm is not None and bad.alarm.number == 12550 and bad.alarm.line == 1


def test_a_circle_in_a_tilted_plane_runs_as_chords_on_the_circle() -> None:
    result = run("G0 X0 Y0 Z0\nROT Y-45\nG0 X10 Y0\nG2 X10 Y0 I-10 J0 F500\nG1 X0\nM30")
    assert result.alarm is None, result.alarm
    chords = result.moves[2:-1]
    # chords within 0.01 mm of a 10 mm circle: 2 acos(1 - 0.001) = 0.089 rad each
    assert len(chords) == math.ceil(2 * math.pi / (2 * math.acos(1 - 0.01 / 10))) and all(isinstance(chord, Move) and chord.feed == 500.0 for chord in chords)
    assert [chord.exact_stop for chord in chords[-2:]] == [False, True]
    tilt = math.radians(45)
    for chord in chords:   # the work circle about (0, 0), radius 10, taken through ROT Y-45
        x, y, z = chord.target_mm["X"], chord.target_mm["Y"], chord.target_mm["Z"]
        assert math.hypot(x, y, z) == pytest.approx(10.0)
        assert z == pytest.approx(x * math.tan(tilt))       # the plane turned about Y
    assert chords[-1].target_mm == pytest.approx(result.moves[1].target_mm)


def test_a_circle_under_an_uneven_scale_is_an_ellipse_of_chords() -> None:
    result = run("G0 X10 Y0\nSCALE X2\nG0 X10 Y0\nG3 X-10 Y0 I-10 J0 F500\nM30")
    assert result.alarm is None, result.alarm
    points = [(move.target_mm["X"], move.target_mm["Y"]) for move in result.moves[2:]]
    assert all((x / 20) ** 2 + (y / 10) ** 2 == pytest.approx(1.0) for x, y in points)
    assert points[-1] == pytest.approx((-20.0, 0.0)) and max(y for _, y in points) == pytest.approx(10.0, abs=0.01)


def test_a_circle_after_a_frame_change_starts_where_the_tool_is() -> None:
    # the tool at machine X10; TRANS X5 makes that work X5: the circle runs from there round (10, 0)
    result = run("G0 X10 Y0\nTRANS X5\nG2 X15 Y0 I5 J0 F100\nROT Z90\nG3 X20 Y0 CR=20\nM30")
    assert result.alarm is None, result.alarm
    first, second = [move for move in result.moves if isinstance(move, Arc)]
    assert first.target_mm == {"X": 20.0, "Y": 0.0} and first.centre_mm == pytest.approx({"X": 15.0, "Y": 0.0})
    # ROT Z90 (TRANS deleted): the tool at machine (20, 0) is work (0, -20); a quarter round work (0, 0)
    assert second.target_mm == pytest.approx({"X": 0.0, "Y": 20.0}) and not second.clockwise
    assert second.centre_mm == pytest.approx({"X": 0.0, "Y": 0.0})


def test_supa_and_g53_suppress_a_rotated_frame_for_their_block() -> None:
    env = DictEnvironment(offsets={"G54": {"X": 100.0}})
    moves = targets("G54 ROT Z90\nG0 SUPA X10 Y5\nG53 G0 X20\nG0 X1 Y0\nM30", env)
    assert moves[:2] == [{"X": 10.0, "Y": 5.0}, {"X": 20.0}]
    assert moves[2] == pytest.approx({"X": 100.0, "Y": 1.0})     # the frame again: work X along machine Y


# --- whole FRAME values: CTRANS, CROT, CSCALE, CMIRROR and the chain operator ------------------------
def test_ctrans_and_crot_set_the_programmable_frame_as_trans_and_arot_do() -> None:
    # CTRANS(X,10):CROT(Z,90) is TRANS X10 then AROT Z90: the same targets
    by_words = targets("G0 X0 Y0\nTRANS X10\nAROT Z90\nG0 X1 Y2\nM30")
    by_value = targets("G0 X0 Y0\n$P_PFRAME=CTRANS(X,10):CROT(Z,90)\nG0 X1 Y2\nM30")
    assert by_value == by_words == [{"X": 0.0, "Y": 0.0}, {"X": 8.0, "Y": 1.0}]
    # the chain goes on from the frame in force: a translation along the rotated X lies along machine Y
    assert targets("$P_PFRAME=CROT(Z,90)\n$P_PFRAME=$P_PFRAME:CTRANS(X,10)\nG0 X0 Y0\nM30") == [{"X": 0.0, "Y": 10.0}]
    # CTRANS(X,10,Y,5) is one translation of two axes; CTRANS() the empty frame
    assert targets("$P_PFRAME=CTRANS(X,10,Y,5)\nG0 X0 Y0\n$P_PFRAME=CTRANS()\nG0 X0 Y0\nM30") == [
        {"X": 10.0, "Y": 5.0}, {"X": 0.0, "Y": 0.0}]
    assert targets("$P_PFRAME=CSCALE(X,2):CMIRROR(Y)\nG0 X1 Y1\nM30") == [{"X": 2.0, "Y": -1.0}]


def test_settable_frames_take_a_whole_translation_and_read_back_as_a_value() -> None:
    env = DictEnvironment(offsets={"G54": {"X": 100.0}})
    moves = targets("$P_UIFR[1]=CTRANS(Y,50)\nG54 G0 X1 Y1\n$P_PFRAME=$P_UIFR[1]:CROT(Z,90)\nG0 X1 Y0\n"
                    "$P_IFRAME=CTRANS(X,7)\nG0 X0 Y0\nR1=$P_PFRAME[Z,RT]\nM30", env)
    # the whole frame is replaced: X's 100 gone, Y 50; the programmable frame then holds that frame's Y50
    # and a rotation, on the settable Y50 (X1 turned to Y1: 50 + 50 + 1); $P_IFRAME replaces the active
    # settable frame at once (X7), under the programmable frame's Y50
    assert moves == [{"X": 1.0, "Y": 51.0}, {"X": 0.0, "Y": 101.0}, {"X": 7.0, "Y": 50.0}]
    assert env.offsets["G54"] == {"X": 7.0, "Y": 0.0, "Z": 0.0, "A": 0.0, "B": 0.0, "C": 0.0}
    assert env.r_parameter(1) == pytest.approx(90.0)


@pytest.mark.parametrize(("block", "number"), [
    ("$P_PFRAME=CTRANS(X)", 12080), ("$P_PFRAME=CTRANS(10,X)", 12080), ("$P_PFRAME=CSCALE(X,0)", ALARM_FRAME),
    ("$P_PFRAME=CROT(A,10)", ALARM_FRAME), ("$P_UIFR[1]=CROT(Z,5)", 12550), ("R1=CTRANS(X,1)", 12150),
    ("$P_PFRAME=CTRANS(X,1):5", 12150)])
def test_a_bad_frame_value_is_an_alarm_with_program_and_line(block: str, number: int) -> None:
    result = run(f"G0 X0\n{block}\nM30")
    assert result.alarm is not None
    assert (result.alarm.number, result.alarm.program, result.alarm.line) == (number, MAIN, 2)
