"""Programs as shops write them: the G-function table and its groups, text as editors save it,
program section repetition, and a main program that starts with PROC (issue 49)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from nckemu.emulator.machine.program.language.alarms import (
    ALARM_G_GROUP_TWICE,
    ALARM_SYNTAX_G_TWICE,
    ALARM_UNKNOWN_G,
)
from nckemu.emulator.machine.program.language.gfunctions import (
    BY_NUMBER,
    NO_EFFECT,
    NOT_SUPPORTED,
    RUN,
    STRAIGHT_G,
    markdown_table,
)
from nckemu.emulator.machine.program.language.modal import ModalState
from nckemu.emulator.machine.program.motions import (
    ALARM_JUMP_TARGET,
    ALARM_NAME_NOT_DEFINED,
    ALARM_SYNTAX,
    Message,
)
from tests.emulator.machine.program.support import DictEnvironment, run

DOC = Path(__file__).resolve().parents[5] / "docs" / "programs-language.md"


def xs(text: str | bytes) -> list[float | None]:
    result = run(text)  # type: ignore[arg-type]
    assert result.alarm is None, result.alarm
    return [move.target_mm.get("X") for move in result.moves]


# --- G functions and their groups --------------------------------------------------------------------
@pytest.mark.parametrize("block", ["G0 G1 X10 F100", "N10 G0 G1 X10", "G0 G1 X=R1 F100", "G1 ASPLINE X1 F100",
                                   "G2 G3 X1 CR=5 F100"])
def test_two_g_functions_of_a_syntax_defining_group_raise_12070(block: str) -> None:
    result = run(f"G0 X0\n{block}\nM30")
    assert result.alarm is not None
    assert (result.alarm.number, result.alarm.line) == (ALARM_SYNTAX_G_TWICE, 2)
    assert "group 1" in str(result.alarm)
    assert result.moves == [result.moves[0]]  # the faulty block moved nothing


def test_the_same_g_twice_and_two_of_another_group_are_no_alarm() -> None:
    assert xs("G1 G1 X10 F100\nM30") == [10.0]
    # G90 G91: the one written last is active, as the control does for groups that define no syntax
    assert xs("G0 X5\nG90 G91 X5\nX5\nM30") == [5.0, 10.0, 15.0]
    assert xs("G0 X5\nN20 G91 G90 X5\nM30") == [5.0, 5.0]


@pytest.mark.parametrize("block", ["G90 G91 X5", "N20 G91 G90 X5", "G17 G18", "SOFT BRISK G1 X1 F10",
                                   "G1 G90 X=R1 G91 F100", "G54 G500"])
def test_two_of_another_group_are_12060_where_the_machine_says_alarm(block: str) -> None:
    env = DictEnvironment()
    env.repeated_g_group = "alarm"  # the machine file's [program] repeated_g_group
    result = run(f"G0 X5\n{block}\nM30", env)
    assert result.alarm is not None
    assert (result.alarm.number, result.alarm.line) == (ALARM_G_GROUP_TWICE, 2)
    assert "same G group programmed repeatedly" in str(result.alarm)
    assert len(result.moves) == 1  # the faulty block moved nothing
    # the same G function twice is no repetition of the group; a syntax-defining group keeps its 12070
    assert run("G1 G1 X10 F100\nG90 G90 X1\nM30", env).alarm is None
    assert run("G0 G1 X1 G90 G91\nM30", env).alarm.number == ALARM_SYNTAX_G_TWICE  # type: ignore[union-attr]


def test_repeated_g_group_is_a_machine_file_setting() -> None:
    from nckemu.emulator.machine.clock import SimulatedClock
    from nckemu.emulator.machine.core import Emulator
    from nckemu.emulator.machine.machine_file import parse_machine
    from nckemu.emulator.machine.offline import run_offline
    from nckemu.errors import NckConfigError

    machine = parse_machine('name = "m"\n[program]\nrepeated_g_group = "alarm"\n', "m.toml")
    assert machine.program.repeated_g_group == "alarm"
    emulator = Emulator(machine, clock=SimulatedClock())
    emulator.nck.programs.write("/_N_MPF_DIR/_N_GG_MPF", b"R1=1\nG90 G91\nM30\n")
    result = run_offline(emulator, "/_N_MPF_DIR/_N_GG_MPF")
    assert result.outcome == "alarm" and "12060" in result.alarms[0] and "line 2" in result.alarms[0]
    assert parse_machine('name = "m"\n', "m.toml").program.repeated_g_group == "last_wins"
    with pytest.raises(NckConfigError, match="repeated_g_group"):
        parse_machine('name = "m"\n[program]\nrepeated_g_group = "first"\n', "m.toml")


@pytest.mark.parametrize("block", ["G43 H01 Z50", "G999", "G620", "G61 X1"])
def test_a_g_function_no_sinumerik_has_is_12470(block: str) -> None:
    result = run(f"G0 X0\n{block}\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_UNKNOWN_G, 2)
    assert "unknown" in str(result.alarm)


@pytest.mark.parametrize("number", sorted(n for n, entry in BY_NUMBER.items() if entry.emulation is NOT_SUPPORTED))
def test_a_g_function_the_control_has_and_we_do_not_run_is_not_supported(number: int) -> None:
    result = run(f"G0 X0\nG{number}\nM30")
    assert result.alarm is not None and result.alarm.number == ALARM_NAME_NOT_DEFINED
    assert f"G{number} " in str(result.alarm) and "not supported by the emulator" in str(result.alarm)


@pytest.mark.parametrize("word", ["CIP X1 Y1 I1=1 J1=2", "CT X5", "REPOSA"])
def test_named_functions_we_do_not_run_are_not_supported(word: str) -> None:
    result = run(f"G0 X0\n{word}\nM30")
    assert result.alarm is not None and result.alarm.number == ALARM_NAME_NOT_DEFINED
    assert "not supported by the emulator" in str(result.alarm)


@pytest.mark.parametrize("number", sorted(n for n, entry in BY_NUMBER.items() if entry.emulation is not NOT_SUPPORTED))
def test_every_g_function_we_run_or_accept_is_known(number: int) -> None:
    result = run(f"G{number}\nM30")
    assert result.alarm is None or (result.alarm.number not in (ALARM_UNKNOWN_G, ALARM_NAME_NOT_DEFINED)
                                    and "cannot interpret" not in str(result.alarm)), result.alarm


def test_the_table_gives_the_fast_path_and_the_docs_list() -> None:
    assert STRAIGHT_G == {0, 1, 17, 18, 19, 40, 60, 64, 70, 71, 90, 91, 94, 95, 601, 602, 603, 641, 642, 643, 644,
                          645, 700, 710}
    assert all(BY_NUMBER[number].modal for number in STRAIGHT_G)
    assert BY_NUMBER[1].group == 1 and BY_NUMBER[4].group == 2 and not BY_NUMBER[4].modal
    assert BY_NUMBER[500].default and BY_NUMBER[17].default and BY_NUMBER[90].default
    assert {BY_NUMBER[n].emulation for n in (0, 641, 54)} == {RUN} and BY_NUMBER[451].emulation is NO_EFFECT
    page = DOC.read_text(encoding="utf-8")
    listed = re.search(r"<!-- gfunctions -->\n(.*?)<!-- end gfunctions -->", page, re.S)
    assert listed is not None and listed.group(1) == markdown_table()


# --- text as it comes ---------------------------------------------------------------------------------
def test_a_byte_order_mark_crlf_and_lower_case_run() -> None:
    assert xs("\ufeffG0 X1\r\nx2\r\nM30\r\n") == [1.0, 2.0]
    assert xs("\ufeffG0 X1\nM30".encode()) == [1.0]
    assert xs("n10 g0 x1 y2\ng1 x=r1+2 f100\nif r1 == 0 gotof done\ng0 x9\ndone: m30") == [1.0, 2.0]


def test_latin1_and_utf8_files_run_and_keep_their_text() -> None:
    for data in ('MSG("Warmlauf 20 °C")\nG0 X1\nM30'.encode("latin-1"),
                 'MSG("Warmlauf 20 → 25 °C")\nG0 X1\nM30'.encode()):
        result = run(data)  # type: ignore[arg-type]
        assert result.alarm is None and len(result.moves) == 1
        assert result.of(Message)[0].text.startswith("Warmlauf 20 ") and result.of(Message)[0].text.endswith("°C")
        assert "\ufffd" not in result.blocks[0].text


# --- program section repetition -----------------------------------------------------------------------
@pytest.mark.parametrize(("text", "expected"), [
    ("A1: G0 X1\nX2\nREPEAT A1 P=3\nX0\nM30", [1, 2, 1, 2, 1, 2, 1, 2, 0]),
    ("G0 X0\nREPEATB A1 P=2\nX9\nA1: X1\nM30", [0, 1, 1, 9, 1]),
    ("S1: G0 X1\nX2\nS2: X3\nX4\nREPEAT S1 S2 P2\nM30", [1, 2, 3, 4, 1, 2, 3, 1, 2, 3]),
    ("S1: G0 X1\nX2\nENDLABEL: X3\nX4\nREPEAT S1 ENDLABEL\nM30", [1, 2, 3, 4, 1, 2, 3]),
    ("A1: G0 X1\nREPEAT A1 P=R1\nM30", [1]),
    ("A1: G0 X1\nB1: REPEAT A1 P=2\nREPEAT B1 P=2\nM30", [1] * 7),
    ("R1=0\nREPEAT\nR1=R1+1\nG0 X=R1\nUNTIL R1>2\nM30", [1, 2, 3]),
])
def test_repeat_runs_a_program_section(text: str, expected: list[float]) -> None:
    assert xs(text) == expected


def test_repeat_of_a_missing_label_is_14080_and_a_bad_count_12080() -> None:
    result = run("G0 X1\nREPEAT NOPE P=2\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_JUMP_TARGET, 2)
    result = run("A1: G0 X1\nREPEAT A1 Q=2\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_SYNTAX, 2)


# --- PROC at the top of a main program ----------------------------------------------------------------
def test_a_main_program_may_start_with_proc() -> None:
    assert xs("PROC MAIN(REAL _A)\nG0 X=_A+1\nM30") == [1.0]
    text = "; made by a post\n%_N_MAIN_MPF\nPROC MAIN(REAL _A, INT _B, STRING[8] _S) SAVE DISPLOF\nG0 X=_A+_B+2\nM30"
    result = run(text)
    assert result.alarm is None and [block.line for block in result.blocks] == [4, 5]
    result = run("PROC MAIN(REAL _A, _B)\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_SYNTAX, 1)
    assert result.blocks[0].text.startswith("PROC MAIN")


# --- the modal state as one record ------------------------------------------------------------------
def test_save_puts_the_callers_modal_record_back_and_a_copy_is_independent() -> None:
    env = DictEnvironment(programs={"SUB.SPF": "PROC SUB SAVE\nG91 G70 G64 TRANS X100\nG1 X1 F10\nRET",
                                    "NOSAVE.SPF": "PROC NOSAVE\nG91\nRET"})
    result = run("G0 X1\nSUB\nX2\nNOSAVE\nX2\nM30", env)
    assert result.alarm is None
    targets = [move.target_mm["X"] for move in result.moves]
    assert targets == [1.0, 1.0 + 25.4 + 2540.0, 2.0, 4.0]   # back: G90, mm, no TRANS; G91 stays after NOSAVE
    assert [move.feed for move in result.moves][2] is None and result.moves[1].exact_stop is False
    assert result.moves[2].exact_stop is True
    state = ModalState(settable={"X": 1.0}, shift={"X": 1.0})
    copied = state.copy()
    copied.settable["X"] = 5.0
    copied.motion = 2
    assert state.settable == {"X": 1.0} and state.motion == 0


def test_words_read_the_same_in_the_fast_and_the_full_reader() -> None:
    """A circle with a constant centre, once in a block of constants (the fast reader) and once beside
    an expression (the full reader): the same arc."""
    fast = run("G0 X0 Y0\nG2 X10 Y0 I5 J0 F100\nM30").moves[1]
    full = run("R1=100\nG0 X0 Y0\nG2 X10 Y0 I5 J0 F=R1\nM30").moves[1]
    assert fast == full and fast.centre_mm == {"X": 5.0, "Y": 0.0}


@pytest.mark.parametrize(("r1", "expected"), [(0, [1.0]), (1, [2.0]), (2, [3.0])])
def test_several_conditional_jumps_in_one_block_are_tried_in_order(r1: int, expected: list[float]) -> None:
    text = (f"R1={r1}\nIF R1==0 GOTOF ZERO IF R1==1 GOTOF ONE\nG0 X3\nGOTOF END\nZERO: G0 X1\nGOTOF END\n"
            "ONE: G0 X2\nEND: M30")
    assert xs(text) == expected


def test_an_axis_named_by_an_expression_moves_that_axis() -> None:
    result = run('DEF AXIS _Z\n_Z=AXNAME("Z")\nG0 AX[X]=5 AX[_Z]=3\nAX[AXNAME("Y")]=IC(1)\nG0 AX[Q]=1\nM30')
    assert [move.target_mm for move in result.moves] == [{"X": 5.0, "Z": 3.0}, {"Y": 1.0}]
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_NAME_NOT_DEFINED, 5)


def test_a_program_written_all_in_lower_case_runs() -> None:
    env = DictEnvironment(programs={"SUB.SPF": "proc sub(real _a) save\ng91 g1 x=_a f100\nret"})
    text = ("def int _i\ndef real _s\nfor _i = 1 to 3\n  _s = _s + _i\nendfor\nif _s == 6\n  g0 x=_s\nelse\n"
            "  g0 x99\nendif\na1: g0 y1\nrepeat a1 p=1\nwhile r1 < 2\n  r1 = r1 + 1\nendwhile\nsub(2) p2\n"
            'msg("fertig")\ngotof ende\ng0 x77\nende: m30\n')
    result = run(text, env)
    assert result.alarm is None
    assert [move.target_mm for move in result.moves] == [{"X": 6.0}, {"Y": 1.0}, {"Y": 1.0}, {"X": 8.0}, {"X": 10.0}]
    assert result.of(Message)[0].text == "fertig"


def test_p_gg_reads_the_active_g_function_of_a_group_by_its_place_in_the_list() -> None:
    env = DictEnvironment()
    text = ("R1=$P_GG[13]\nR2=$P_GG[6]\nG18 G700 G91 G64 SOFT\nR3=$P_GG[13]\nR4=$P_GG[6]\nR5=$P_GG[14]\n"
            "R6=$P_GG[10]\nR7=$P_GG[21]\nR8=$P_GG[1]\nG1 X0 F1\nR9=$P_GG[1]\nIF ($P_GG[13]==1) OR ($P_GG[13]==3)\n"
            "R10=1\nENDIF\nM30")
    assert run(text, env).alarm is None
    # G71 G17 | G700 G18 G91 G64 SOFT | G0, G1 | inch (the test Siemens' cycles make)
    assert [env.r_parameter(i) for i in range(1, 11)] == [2, 1, 3, 2, 2, 2, 2, 1, 2, 1]


# --- values beyond the control's range ---------------------------------------------------------------
@pytest.mark.parametrize(("block", "what"), [
    ("SCALE X=1EX300", "SCALE X"), ("X=1EX300", "X"), ("G1 Y=-2EX9 F100", "Y"), ("TRANS Z=1EX10", "TRANS Z"),
    ("R1=1EX400", "1EX400"), ("C=1EX12", "C"), ("AROT RPL=1EX10", "AROT RPL")])
def test_a_value_beyond_the_controls_range_is_12160_with_program_and_line(block: str, what: str) -> None:
    from nckemu.emulator.machine.program.language.alarms import ALARM_VALUE_RANGE

    result = run(f"G0 X0\n{block}\nM30")
    assert result.alarm is not None
    assert (result.alarm.number, result.alarm.line, result.alarm.program) == (ALARM_VALUE_RANGE, 2, "/_N_MPF_DIR/_N_TEST_MPF")
    assert "value range exceeded" in str(result.alarm) and what in str(result.alarm)
    assert len(result.moves) == 1  # the faulty block moved nothing
    assert xs("G0 X=999999999\nX=1EX300/1EX300\nM30") == [999999999.0, 1.0]  # within the range: runs


def test_an_e_exponent_is_no_sinumerik_number_and_the_alarm_says_how_to_write_it() -> None:
    result = run("G0 X0\nSCALE X1E300\nM30")
    assert result.alarm is not None and (result.alarm.number, result.alarm.line) == (ALARM_NAME_NOT_DEFINED, 2)
    assert "EX" in str(result.alarm)
