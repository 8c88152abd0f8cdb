"""Units of the SINUMERIK language: expressions, variables, control flow, subprograms, motion words,
and the alarms (with program and line) a faulty block raises when it executes."""

from __future__ import annotations

import math

import pytest

from nckemu.emulator.machine.program.language import Interpreter
from nckemu.emulator.machine.program.language.alarms import (
    ALARM_AUXILIARY,
    ALARM_DIVISION_BY_ZERO,
    ALARM_INDEX,
    ALARM_NESTING,
    ALARM_UNKNOWN_G,
)
from nckemu.emulator.machine.program.motions import (
    ALARM_CIRCLE_END_POINT,
    ALARM_FEED_ZERO,
    ALARM_JUMP_TARGET,
    ALARM_NAME_NOT_DEFINED,
    ALARM_PROGRAM_NOT_FOUND,
    ALARM_SYNTAX,
    Arc,
    Block,
    Dwell,
    Message,
    MFunction,
    Move,
    ProgramEnd,
    SpindleCommand,
    ToolSelect,
)
from tests.emulator.machine.program.support import MAIN, DictEnvironment, run


def r_after(text: str, *indices: int, env: DictEnvironment | None = None) -> list[float]:
    env = env or DictEnvironment()
    result = run(text, env)
    assert result.alarm is None, result.alarm
    return [env.r_parameter(index) for index in indices]


# --- expressions -----------------------------------------------------------------------------------

@pytest.mark.parametrize(("expression", "expected"), [
    ("1+2*3", 7), ("(1+2)*3", 9), ("7 DIV 3", 2), ("-7 DIV 2", -3), ("7 MOD 4", 3), ("7 MOD 4.1", 2.9),
    ("7 DIV 0.4", 17), ("2/4", 0.5), ("1+1-1+-1", 0), ("SIN(30)", 0.5), ("COS(60)", 0.5), ("TAN(45)", 1),
    ("ASIN(0.5)", 30), ("ACOS(0.5)", 60), ("ATAN2(1, 1)", 45), ("SQRT(16)", 4), ("ABS(-3.5)", 3.5),
    ("POT(3)", 9), ("TRUNC(-2.7)", -2), ("ROUND(2.5)", 3), ("ROUND(-2.5)", -3), ("LN(EXP(2))", 2),
    ("3 > 2", 1), ("3 == 2", 0), ("3 <> 2", 1), ("2 >= 2", 1), ("NOT 0", 1), ("1 AND 0", 0),
    ("1 OR 0", 1), ("1 XOR 1", 0), ("6 B_AND 3", 2), ("6 B_OR 3", 7), ("6 B_XOR 3", 5), ("B_NOT 0", -1),
    ("MINVAL(2, 3)", 2), ("MAXVAL(2, 3)", 3), ("BOUND(0, 10, 12)", 10), ("'H1F'", 31), ("'B101'", 5),
    ("1.5EX2", 150), ("STRLEN(\"ABC\")", 3), ("NUMBER(\"2.5\")", 2.5), ("-2*-3", 6),
])
def test_expressions(expression: str, expected: float) -> None:
    (value,) = r_after(f"R1={expression}\nM30", 1)
    assert value == pytest.approx(expected)


def test_comparison_binds_loosest_as_on_the_control() -> None:
    # SINUMERIK priority: AND before ==, so 1==1 AND 0==0 reads 1==(1 AND 0)==0 -> (1==0)==0 -> 1
    # (brackets give the intended meaning, as the Siemens manual asks for)
    assert r_after("R1=1==1 AND 2==2\nR2=(1==1) AND (2==3)\nM30", 1, 2) == [0.0, 0.0]
    assert r_after("R1=(1==1) AND (2==2)\nM30", 1) == [1.0]


def test_string_concatenation_and_message() -> None:
    result = run('DEF STRING[20] TXT="PART"\nDEF INT NUM=3\nMSG(TXT << "_" << NUM)\nMSG()\nM30')
    assert [event.text for event in result.of(Message)] == ["PART_3", ""]


def test_names_are_case_insensitive_and_r_parameters_go_through_the_environment() -> None:
    env = DictEnvironment()
    env.set_r_parameter(5, 2.0)
    result = run("def real layer\nLayer = r5 * 4\nR6 = LAYER\nm30", env)
    assert result.alarm is None
    assert env.r_parameter(6) == 8.0


# --- variables ---------------------------------------------------------------------------------------

def test_def_types_convert_on_assignment() -> None:
    text = """DEF INT IVAL = 2.5
DEF REAL RVAL = 1
DEF BOOL FLAG = 7
DEF INT NVAL
NVAL = -2.5
R1 = IVAL
R2 = FLAG
R3 = NVAL
R4 = 7/2
M30"""
    assert r_after(text, 1, 2, 3, 4) == [3.0, 1.0, -3.0, 3.5]


def test_arrays_with_set_and_rep() -> None:
    text = """DEF REAL ARR[2,3] = SET(1, 2, 3, 4, 5, 6)
DEF INT BR[4] = REP(7)
DEF REAL CR_[2,2,2]
CR_[1,1,1] = 9
BR[1] = SET(10, 11)
R1 = ARR[1,2]
R2 = BR[0] + BR[1] + BR[2] + BR[3]
R3 = CR_[1,1,1] + CR_[0,0,0]
M30"""
    assert r_after(text, 1, 2, 3) == [6.0, 35.0, 9.0]


def test_def_of_a_name_the_control_owns_alarms() -> None:
    for name in ("X", "K", "R2", "F"):
        result = run(f"DEF INT {name}\nM30")
        assert result.alarm is not None and result.alarm.line == 1, name


def test_array_index_outside_alarms() -> None:
    result = run("DEF INT BRR[3]\nBRR[3] = 1\nM30")
    assert result.alarm is not None and result.alarm.number == ALARM_INDEX and result.alarm.line == 2


def test_undefined_name_alarms_with_program_line_and_block() -> None:
    result = run("G0 X0\nX=UNKNOWN_NAME\nM30")
    assert result.alarm is not None
    assert (result.alarm.number, result.alarm.program, result.alarm.line) == (ALARM_NAME_NOT_DEFINED, MAIN, 2)
    assert result.alarm.block == "X=UNKNOWN_NAME"
    assert "12550" in str(result.alarm) and "line 2" in str(result.alarm)


def test_system_variables_from_the_environment_and_unknown_ones() -> None:
    env = DictEnvironment(system={"$AC_TIME": 12.5, "$AC_ACTUAL_PARTS": 4})
    result = run("R1=$AC_TIME\n$AC_ACTUAL_PARTS=$AC_ACTUAL_PARTS+1\nR2=$AC_NO_SUCH\nM30", env)
    assert env.r_parameter(1) == 12.5 and env.system["$AC_ACTUAL_PARTS"] == 5
    assert result.alarm is not None and result.alarm.number == ALARM_NAME_NOT_DEFINED and result.alarm.line == 3


def test_position_reads_see_the_end_of_the_previous_motion() -> None:
    text = "G54\nG0 X10 Y20\nR1=$AA_IM[X]\nR2=$AA_IW[X]\nR3=$P_EP[Y]\nM30"
    env = DictEnvironment(offsets={"G54": {"X": 100.0}})
    assert r_after(text, 1, 2, 3, env=env) == [110.0, 10.0, 20.0]


def test_the_interpreter_is_lazy() -> None:
    env = DictEnvironment()
    events = Interpreter(env, MAIN, "G0 X10\nR1=$AA_IM[X]\nM30").events()
    move = next(event for event in events if isinstance(event, Move))
    env._position_mm["X"] = 7.0  # the channel stopped the axis short (as a reset would)
    list(events)
    assert move.target_mm == {"X": 10.0} and env.r_parameter(1) == 7.0


# --- control flow ------------------------------------------------------------------------------------

def test_if_else_nested() -> None:
    text = """DEF INT AA=1
IF AA == 1
  IF AA > 5
    R1 = 1
  ELSE
    R1 = 2
  ENDIF
ELSE
  R1 = 3
ENDIF
M30"""
    assert r_after(text, 1) == [2.0]


def test_while_for_repeat_loop() -> None:
    text = """DEF INT IDX
DEF INT COUNTER
WHILE R1 < 5
  R1 = R1 + 1
ENDWHILE
FOR IDX = 1 TO 10
  R2 = R2 + IDX
ENDFOR
REPEAT
  R3 = R3 + 2
UNTIL R3 >= 7
LOOP
  COUNTER = COUNTER + 1
  IF COUNTER == 4 GOTOF OUT
ENDLOOP
OUT: R4 = COUNTER
FOR IDX = 5 TO 1
  R5 = 99
ENDFOR
M30"""
    assert r_after(text, 1, 2, 3, 4, 5) == [5.0, 55.0, 8.0, 4.0, 0.0]


def test_gotob_gotof_goto_search_directions_and_block_numbers() -> None:
    text = """N10 R1 = R1 + 1
IF R1 < 3 GOTOB N10
GOTOF MARK
R2 = 99
MARK: R3 = 1
GOTO BACK
R4 = 99
BACK:
R5 = R5 + 1
IF R5 < 2 GOTO BACK
M30"""
    assert r_after(text, 1, 2, 3, 4, 5) == [3.0, 0.0, 1.0, 0.0, 2.0]


def test_gotof_finds_the_nearest_label_forward_only() -> None:
    text = "L1: R1 = R1 + 1\nGOTOF L1\nR2 = 5\nL1: R3 = 1\nM30"
    assert r_after(text, 1, 2, 3) == [1.0, 0.0, 1.0]


def test_missing_jump_target_alarms_when_the_jump_runs_and_gotoc_continues() -> None:
    assert run("IF 0 GOTOF NOWHERE\nGOTOC NOWHERE\nR1=1\nM30").alarm is None
    result = run("R1=1\nGOTOF NOWHERE\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_JUMP_TARGET, 2)
    # GOTOF does not look backward
    result = run("BACK: R1=1\nGOTOF BACK\nM30")
    assert result.alarm is not None and result.alarm.number == ALARM_JUMP_TARGET


def test_a_label_named_like_a_keyword_is_a_label() -> None:
    text = "WHILE R1 < 2\nR1 = R1 + 1\nENDWHILE\nGOTOF LOOP\nR2 = 9\nLOOP: R3 = 1\nM30"
    assert r_after(text, 1, 2, 3) == [2.0, 0.0, 1.0]


def test_gotos_goes_back_to_the_start() -> None:
    assert r_after("R1 = R1 + 1\nIF R1 < 3 GOTOS\nM30", 1) == [3.0]


def test_case() -> None:
    text = """DEF INT SEL = 2
CASE(SEL) OF 1 GOTOF ONE 2 GOTOF TWO DEFAULT GOTOF OTHER
ONE: R1 = 1
GOTOF END
TWO: R1 = 2
GOTOF END
OTHER: R1 = 3
END: M30"""
    assert r_after(text, 1) == [2.0]
    assert r_after(text.replace("SEL = 2", "SEL = 9"), 1) == [3.0]


def test_bad_nesting_alarms_when_it_runs() -> None:
    result = run("R1=1\nIF R1 == 1\nR2=2\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_NESTING, 2)
    result = run("R1=1\nENDWHILE\nM30")
    assert result.alarm is not None and result.alarm.number == ALARM_NESTING


def test_endless_loop_yields_blocks_and_closes_at_any_point() -> None:
    events = Interpreter(DictEnvironment(), MAIN, "LOOP\nG1 X1 F100\nG1 X0\nENDLOOP").events()
    seen = [next(events) for _ in range(1000)]
    assert sum(isinstance(event, Block) for event in seen) > 400
    events.close()  # as the channel does on reset
    events.close()
    assert list(events) == []


# --- subprograms -------------------------------------------------------------------------------------

def test_subprogram_with_parameters_by_value_and_by_reference() -> None:
    env = DictEnvironment(programs={
        "ADD.SPF": "PROC ADD(REAL _A, INT _B, VAR REAL _OUT)\n_OUT = _A + _B\n_A = 0\nRET",
    })
    text = "EXTERN ADD(REAL, INT, VAR REAL)\nDEF REAL RES, AVAL = 1.5\nADD(AVAL, 2, RES)\nR1 = RES\nR2 = AVAL\nM30"
    assert r_after(text, 1, 2, env=env) == [3.5, 1.5]


def test_subprogram_locals_are_their_own_and_m17_returns() -> None:
    env = DictEnvironment(programs={"SUB.SPF": "PROC SUB\nDEF INT IDX = 5\nR1 = R1 + IDX\nM17"})
    text = "DEF INT IDX = 1\nSUB\nSUB P2\nR2 = IDX\nM30"
    assert r_after(text, 1, 2, env=env) == [15.0, 1.0]


def test_an_empty_subprogram_repeated_ends() -> None:
    env = DictEnvironment(programs={"EMPTY.SPF": "PROC EMPTY\n; nothing\n"})
    result = run("EMPTY P999999999\nM30", env)
    assert result.alarm is None and result.events[-1] == ProgramEnd(30)


def test_events_again_starts_over() -> None:
    env = DictEnvironment()
    interpreter = Interpreter(env, MAIN, "G91 G0 X1\nM30")
    first = [event for event in interpreter.events() if isinstance(event, Move)]
    env._position_mm["X"] = 0.0
    second = [event for event in interpreter.events() if isinstance(event, Move)]
    assert first == second == [Move({"X": 1.0}, None, "G94", True, {"X": 1.0})]


def test_def_nck_is_global_to_subprograms() -> None:
    env = DictEnvironment(programs={"USE.SPF": "PROC USE\nCOUNTER = COUNTER + 1\nRET"})
    assert r_after("DEF NCK INT COUNTER = 4\nUSE\nUSE\nR1 = COUNTER\nM30", 1, env=env) == [6.0]
    result = run("DEF INT COUNTER = 4\nUSE\nM30", env)
    assert result.alarm is not None and result.alarm.number == ALARM_NAME_NOT_DEFINED


def test_m30_in_a_subprogram_returns_or_ends_as_set() -> None:
    env = DictEnvironment(programs={"SUB.SPF": "PROC SUB\nR1 = 1\nM30"})
    result = run("SUB\nR2 = 2\nM2", env)
    assert result.events[-1] == ProgramEnd(2) and env.r_parameter(2) == 2.0
    env = DictEnvironment(programs={"SUB.SPF": "PROC SUB\nR1 = 1\nM30"})
    env.subprogram_end_returns = False
    result = run("SUB\nR2 = 2\nM2", env)
    assert result.events[-1] == ProgramEnd(30) and env.r_parameter(2) == 0.0


def test_a_subprogram_sent_again_between_calls_runs_as_sent() -> None:
    env = DictEnvironment(programs={"SUB.SPF": "PROC SUB\nR1 = R1 + 1\nRET"})
    events = Interpreter(env, MAIN, "SUB\nSUB\nM30").events()
    for event in events:
        if isinstance(event, Block) and event.line == 2 and event.depth == 0:
            env.programs["/_N_SPF_DIR/_N_SUB_SPF"] = "PROC SUB\nR1 = R1 + 10\nRET"
    assert env.r_parameter(1) == 11.0


def test_missing_subprogram_alarms_14011() -> None:
    result = run("G0 X0\nNO_SUCH_SUB(1, 2)\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_PROGRAM_NOT_FOUND, 2)


def test_alarm_in_a_subprogram_names_the_subprogram() -> None:
    env = DictEnvironment(programs={"BAD.SPF": "PROC BAD\nR1 = 1 / 0\nRET"})
    result = run("BAD\nM30", env)
    assert result.alarm is not None
    assert (result.alarm.number, result.alarm.program, result.alarm.line) == (
        ALARM_DIVISION_BY_ZERO, "/_N_SPF_DIR/_N_BAD_SPF", 2)
    assert [block.depth for block in result.blocks] == [0, 1]


def test_standard_cycles_run_as_motions() -> None:
    result = run("G0 X0 Z20 F100\nCYCLE832(0.01, 0, 1)\nMCALL CYCLE81(10, 0, 1, -5)\nX10\nMCALL\nM30")
    assert result.alarm is None and len(result.moves) == 5   # tests/emulator/machine/program/test_program_cycles.py


def test_settings_without_a_model_are_accepted() -> None:
    text = "FGROUP(X, Y)\nSOFT BRISK FFWON G642 G40 G97\nACC[X]=50\nR1=ACC[X]\nLIMS=3000\nG0 X1\nM30"
    result = run(text)
    assert result.alarm is None and len(result.moves) == 1
    assert run("NO_SUCH_WORD\nM30").alarm.number == ALARM_NAME_NOT_DEFINED  # type: ignore[union-attr]


def test_pi_the_handwheels_drf_and_waitp_as_a_grinders_cycles_read_them() -> None:
    env = DictEnvironment()
    result = run("R1=1000*60/($PI*400)\nR2=$AC_DRF[X]\nPOSA[X]=5 FA[X]=100\nWAITP(X)\nG1 X=10-$AC_DRF[X] F100\nM30", env)
    assert result.alarm is None, result.alarm
    assert env.r_parameter(1) == pytest.approx(60000 / (math.pi * 400)) and env.r_parameter(2) == 0.0
    assert [move.target_mm for move in result.moves] == [{"X": 10.0}]
    assert run("R1=$AC_DRF[Q]\nM30").alarm.number == ALARM_NAME_NOT_DEFINED  # type: ignore[union-attr]


def test_a_synchronized_action_whose_condition_is_false_is_accepted_and_one_that_holds_is_refused() -> None:
    env = DictEnvironment()
    text = ("N10 WHEN R5==1 DO DELDTG(X) $R[280]=$AA_IM[X]\nID=2 WHENEVER $AA_IM[X]>100 DO POS[X]=0.2 FA[X]=30\n"
            "G1 X1 F100\nR5=1\nWHEN R5==1 DO M120\nM30")
    result = run(text, env)
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_NAME_NOT_DEFINED, 5)
    assert "synchronized action WHEN" in str(result.alarm) and len(result.moves) == 1
    bad = run("WHEN R5== DO M120\nM30").alarm
    assert bad is not None and bad.line == 1


def test_words_packed_without_spaces_are_the_words_a_control_reads() -> None:
    # an identifier begins with two letters or _: G01G90X and R12F800 are address words run together
    env = DictEnvironment(programs={"CYCLE_A1.SPF": "PROC CYCLE_A1(REAL _V)\nR3=_V\nRET"})
    result = run("R12=5\nN10G01G90X=R12F800\nG1X=R12+1Y2F=R12*100\nT01M06\nCYCLE_A1(R12)\nM30", env)
    assert result.alarm is None, result.alarm
    assert [(move.target_mm, move.feed) for move in result.moves] == [({"X": 5.0}, 800.0),
                                                                       ({"X": 6.0, "Y": 2.0}, 500.0)]
    assert [block.number for block in result.blocks][1] == "N10" and env.r_parameter(3) == 5.0


def test_modal_call_of_a_program_runs_after_each_motion_block() -> None:
    env = DictEnvironment(programs={"DRILL.SPF": "PROC DRILL(REAL _DEPTH)\nR1 = R1 + 1\nR2 = _DEPTH\nRET"})
    result = run("MCALL DRILL(-5)\nG0 X1\nX2\nR3 = 1\nMCALL\nX3\nM30", env)
    assert result.alarm is None
    assert (env.r_parameter(1), env.r_parameter(2)) == (2.0, -5.0)


def test_modal_call_arguments_are_the_callers_values_at_the_mcall() -> None:
    # HOLES1 under MCALL CYCLE81(RTP, ...): the calls come from the pattern's blocks, where the main
    # program's RTP is no name; the arguments are evaluated in the block that programs the MCALL
    env = DictEnvironment(programs={
        "DRILL.SPF": "PROC DRILL(REAL _RTP, REAL _DP)\nR1 = R1 + 1\nR2 = _RTP\nR3 = _DP\nRET",
        "ROW.SPF": "PROC ROW(INT _N)\nDEF INT _I\nLOOP_:G0 X=_I*10\n_I=_I+1\nIF _I<_N GOTOB LOOP_\nRET"})
    result = run("DEF REAL RTP=112, DP=22\nMCALL DRILL(RTP, DP)\nRTP=5\nROW(3)\nMCALL\nM30", env)
    assert result.alarm is None, result.alarm
    assert [env.r_parameter(index) for index in (1, 2, 3)] == [3.0, 112.0, 22.0]
    assert [move.target_mm["X"] for move in result.moves] == [0.0, 10.0, 20.0]


def test_proc_save_restores_the_callers_modal_state() -> None:
    env = DictEnvironment(programs={"INCH.SPF": "PROC INCH SAVE\nG70 G91 G1 X1 F10\nRET"})
    result = run("G0 X0\nINCH\nG0 X1\nM30", env)
    assert [move.target_mm for move in result.moves] == [{"X": 0.0}, {"X": 25.4}, {"X": 1.0}]


def test_setal_cycle_alarm() -> None:
    result = run("SETAL(61000)\nM30")
    assert result.alarm is not None and result.alarm.number == 61000


# --- motion words ----------------------------------------------------------------------------------

def test_straight_moves_modal_g_and_feed() -> None:
    result = run("N10 G1 X10 Y-5.5 F200\nN20 G91 X1 Y1\nN30 G0 G90 Z=5*2\nN40 G64 G1 X.5 F=R1+100\nM30")
    moves = result.moves
    assert [move.target_mm for move in moves] == [{"X": 10.0, "Y": -5.5}, {"X": 11.0, "Y": -4.5}, {"Z": 10.0},
                                                   {"X": 0.5}]
    assert [move.feed for move in moves] == [200.0, 200.0, None, 100.0]
    assert [move.exact_stop for move in moves] == [True, True, True, False]
    assert [block.number for block in result.blocks][:4] == ["N10", "N20", "N30", "N40"]


def test_ic_and_ac_override_the_mode_per_axis() -> None:
    result = run("G0 X5 Y5\nG91 X=AC(1) Y2\nG90 X=IC(3) Y1\nM30")
    assert [move.target_mm for move in result.moves][1:] == [{"X": 1.0, "Y": 7.0}, {"X": 4.0, "Y": 1.0}]


def test_rotary_positioning_modes_are_absolute_positions() -> None:
    result = run("G0 C10\nG91 C=DC(90)\nC=ACP(180) B=ACN(5)\nC=CIC(10)\nM30")
    assert [move.target_mm for move in result.moves] == [{"C": 10.0}, {"C": 90.0}, {"C": 180.0, "B": 5.0},
                                                         {"C": 190.0}]


def test_inch_geometry_and_feed() -> None:
    result = run("G70 G1 X1 F10\nG700 X2 F10\nG71 X25.4\nG710 X0\nM30")
    moves = result.moves
    assert [move.target_mm["X"] for move in moves] == pytest.approx([25.4, 50.8, 25.4, 0.0])
    assert [move.feed for move in moves] == pytest.approx([10.0, 254.0, 254.0, 254.0])
    assert moves[1].programmed == {"X": 2.0}


def test_frames_work_offsets_trans_atrans_supa() -> None:
    env = DictEnvironment(offsets={"G54": {"X": 100.0, "Z": -50.0}})
    text = "G54 G0 X1 Z1\nTRANS X10\nX1\nATRANS X5\nX1\nG0 SUPA X0 Z0\nG53 X3\nX1\nG500 X1\nTRANS\nX1\nM30"
    moves = run(text, env).moves
    assert [move.target_mm for move in moves] == [
        {"X": 101.0, "Z": -49.0}, {"X": 111.0}, {"X": 116.0}, {"X": 0.0, "Z": 0.0}, {"X": 3.0}, {"X": 116.0},
        {"X": 16.0}, {"X": 1.0}]
    assert moves[3].programmed == {"X": 0.0, "Z": 0.0}


def test_bare_rot_clears_the_frame_and_rot_with_values_turns_it() -> None:
    result = run("TRANS X10\nROT\nG0 X1\nROT Z90\nG0 X1\nM30")
    assert result.alarm is None
    assert result.moves[0].target_mm == {"X": 1.0}
    assert result.moves[1].target_mm == pytest.approx({"X": 0.0, "Y": 1.0})  # tests/emulator/machine/program/test_program_frames.py


def test_arcs_ijk_cr_helical_and_planes() -> None:
    text = """G0 X0 Y0 Z0
G17 G2 X100 Y0 I50 J0 F1000
G3 X0 Y0 CR=50
G2 X0 Y0 Z10 I0 J-25 TURN=2
G18 G3 Z20 X10 K0 I10
M30"""
    arcs = run(text).of(Arc)
    assert arcs[0].centre_mm == {"X": 50.0, "Y": 0.0} and arcs[0].clockwise
    assert arcs[1].centre_mm == pytest.approx({"X": 50.0, "Y": 0.0}) and not arcs[1].clockwise
    assert arcs[2].target_mm == {"X": 0.0, "Y": 0.0, "Z": 10.0} and arcs[2].turns == 2
    assert arcs[2].centre_mm == {"X": 0.0, "Y": -25.0}
    assert arcs[3].plane == "G18" and arcs[3].centre_mm == {"Z": 10.0, "X": 10.0}


def test_arc_end_point_error_and_missing_centre() -> None:
    result = run("G0 X0 Y0\nG2 X100 Y0 I10 J0 F100\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_CIRCLE_END_POINT, 2)
    result = run("G0 X0 Y0\nG2 X10 F100\nM30")
    assert result.alarm is not None and result.alarm.number == ALARM_CIRCLE_END_POINT


def test_cr_radius_centre_side() -> None:
    # short arc (CR>0) clockwise from (0,0) to (10,0): centre below the chord
    (arc,) = run("G0 X0 Y0\nG2 X10 Y0 CR=5 F100\nM30").of(Arc)
    assert arc.centre_mm == pytest.approx({"X": 5.0, "Y": 0.0})
    (arc,) = run("G0 X0 Y0\nG2 X10 Y0 CR=10 F100\nM30").of(Arc)
    assert arc.centre_mm["Y"] == pytest.approx(-math.sqrt(75))
    (arc,) = run("G0 X0 Y0\nG2 X10 Y0 CR=-10 F100\nM30").of(Arc)
    assert arc.centre_mm["Y"] == pytest.approx(math.sqrt(75))


def test_feed_zero_alarms_on_a_feed_move_only() -> None:
    result = run("G0 X10\nG1 X20\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_FEED_ZERO, 2)
    result = run("G1 X20 F=R1\nM30")
    assert result.alarm is not None and result.alarm.number == ALARM_FEED_ZERO


def test_dwell_spindle_tool_m_functions_and_order() -> None:
    result = run('G4 F2.5\nG4 S10\nT="DRILL" D1 M6 S1200 M3 X1 M8\nM1=4 S1=500\nM5\nM0\nM30')
    kinds = [type(event).__name__ for event in result.events if not isinstance(event, Block)]
    assert result.of(Dwell) == [Dwell(seconds=2.5), Dwell(spindle_revolutions=10.0)]
    assert result.of(ToolSelect) == [ToolSelect(tool="DRILL", edge=1, change=True)]
    assert result.of(SpindleCommand) == [SpindleCommand(1, 1200.0, "M3"), SpindleCommand(1, 500.0, "M4"),
                                         SpindleCommand(1, None, "M5")]
    assert [m.code for m in result.of(MFunction)] == [6, 8, 0, 30]
    assert kinds[2:6] == ["ToolSelect", "SpindleCommand", "MFunction", "MFunction"]  # T/S/M before the move
    assert result.of(ProgramEnd) == [ProgramEnd(30)]


def test_tool_length_applies_along_the_infeed_axis() -> None:
    env = DictEnvironment(tool_lengths={(3, 1): 100.0})
    moves = run("T3 M6\nG0 Z5\nG18 Z5\nD0 Z5\nM30", env).moves
    assert [move.target_mm for move in moves] == [{"Z": 105.0}, {"Z": 5.0}, {"Z": 5.0}]


def test_two_directions_for_one_spindle_alarm() -> None:
    result = run("M3 M4\nM30")
    assert result.alarm is not None and result.alarm.number == ALARM_AUXILIARY


def test_unknown_g_and_syntax_errors() -> None:
    assert run("G1234\nM30").alarm.number == ALARM_UNKNOWN_G  # type: ignore[union-attr]
    for text in ("X=(1+\nM30", "R1=1 +* 2\nM30", "IF\nM30", "G0 X10 ?\nM30", "FOR IDX=1\nENDFOR"):
        result = run(text)
        assert result.alarm is not None and result.alarm.number in (ALARM_SYNTAX, ALARM_NAME_NOT_DEFINED), text
        assert result.alarm.line == 1


def test_division_by_zero_alarms_where_it_runs() -> None:
    assert run("IF 0\nR1=1/0\nENDIF\nM30").alarm is None
    result = run("R2=0\nR1=5/R2\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_DIVISION_BY_ZERO, 2)


def test_program_end_without_m30_and_comments_header_lines() -> None:
    result = run("%_N_TEST_MPF\n;$PATH=/_N_MPF_DIR\n\n   ; only a comment\nG0 X1 ; move\n")
    assert result.alarm is None and result.events[-1] == ProgramEnd(0)
    assert [block.text for block in result.blocks] == ["G0 X1"]
    assert result.blocks[0].line == 5


def test_program_text_as_bytes_from_the_store() -> None:
    events = list(Interpreter(DictEnvironment(), MAIN, b"G0 X1 ; \xb0C\nM30").events())
    assert events[1] == Move({"X": 1.0}, None, "G94", True, {"X": 1.0})


def test_crlf_and_block_skip_and_labels_with_numbers() -> None:
    result = run("N5 START: G0 X1\r\n/ G0 X2\r\nN10 M30\r\n")
    assert [move.target_mm for move in result.moves] == [{"X": 1.0}, {"X": 2.0}]
    assert [block.line for block in result.blocks] == [1, 2, 3]


def test_named_axes_from_the_environment() -> None:
    env = DictEnvironment(axes=("X", "Y", "Z", "B", "SP1", "U"))
    moves = run("G0 B90 U=5 SP1=3\nM30", env).moves
    assert moves[0].target_mm == {"B": 90.0, "U": 5.0, "SP1": 3.0}


# --- big programs ------------------------------------------------------------------------------------

def ten_mb_program() -> str:
    line = "N{} G1 X{:.3f} Y{:.3f} Z-1.500 F2000 ; cut\n"
    thousand = "".join(line.format(i, i % 500 * 0.1, i % 300 * 0.2) for i in range(1000))
    return "G90 G94\n" + thousand * 250 + "M30\n"


def test_a_10_mb_program_loads_without_copies_per_line() -> None:
    import tracemalloc

    text = ten_mb_program()
    assert len(text) > 10_000_000
    tracemalloc.start()
    try:
        interpreter = Interpreter(DictEnvironment(), MAIN, text)
        events = interpreter.events()
        for _ in range(2_000):
            next(events)
        kept, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert kept < 2_000_000  # bytes beyond the text itself: nothing per line is kept
    assert peak < len(text) + 2_000_000  # one passing upper-case copy for the load-time scan
    events.close()


@pytest.mark.slow
def test_a_10_mb_program_runs_to_its_end() -> None:
    result = run(ten_mb_program(), limit=10_000_000)
    assert result.alarm is None and result.events[-1] == ProgramEnd(30)
    assert len(result.moves) == 250_000


CAM_POST = """%_N_1001_MPF
;$PATH=/_N_MPF_DIR
; T1 D=10 - flat end mill
N10 G90 G94 G17
N12 G71
N14 WORKPIECE(,"",,"BOX",112,0,-50,-80,0,0,100,100)
N16 T="FLAT10" D1 M6
N18 CYCLE800(0,"TABLE",200000,57,0,0,0,0,0,0,0,0,0,-1,100,1)
N20 S5000 M3
N22 G54
N24 M8
N26 CYCLE832(0.01,_ROUGH,1)
N28 G0 X-5.35 Y12.5
N30 G0 Z15.
N32 G1 Z5. F1000
N34 G1 Z-4.5 F333.3
N36 G3 X0.5 Y6.65 CR=5.85
N38 G1 X45.
N40 G2 X50. Y11.65 I0. J5.
N42 G1 Y88.35
N44 G0 Z15.
N46 CYCLE832()
N48 M9
N50 G0 SUPA Z0 D0
N52 G0 SUPA X0 Y0
N54 M30
"""


def test_a_cam_post_program_runs_with_its_cycles_as_no_ops() -> None:
    env = DictEnvironment(offsets={"G54": {"X": 200.0, "Y": 100.0, "Z": -300.0}},
                          tool_lengths={("FLAT10", 1): 80.0})
    result = run(CAM_POST, env)
    assert result.alarm is None and result.events[-1] == ProgramEnd(30)
    assert [block.number for block in result.blocks][:3] == ["N10", "N12", "N14"]
    moves = result.moves
    assert moves[0].target_mm == {"X": 194.65, "Y": 112.5}
    assert moves[1].target_mm == {"Z": -300.0 + 15.0 + 80.0}
    arc = moves[4]
    assert isinstance(arc, Arc) and not arc.clockwise
    assert arc.centre_mm == pytest.approx({"X": 200.5, "Y": 112.5})
    assert moves[6].centre_mm == pytest.approx({"X": 245.0, "Y": 111.65})  # type: ignore[union-attr]
    assert moves[-2].target_mm == {"Z": 0.0} and moves[-1].target_mm == {"X": 0.0, "Y": 0.0}
    assert [event.code for event in result.of(MFunction)] == [6, 8, 9, 30]
