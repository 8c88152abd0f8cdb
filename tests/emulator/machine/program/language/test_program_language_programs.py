"""Real programs from ../shared/programs run by the interpreter.

CEAD examples: the blocks we execute, projected to block number, axis positions (machine
coordinates, filled forward as their table fills them), M functions and T, equal the table CEAD's
interpreter wrote for each program. Both tables are reduced the same way: a row is kept when it has a
block number, an M function or a tool, or when the positions changed (their table has a row per
comment line and none for IF/WHILE; ours a row per executed block; what moved where does not depend
on that).

Where a real SINUMERIK and that interpreter part ways, the Siemens behaviour wins and the test says
why (DIFFERENCES below); the rest of such a program is still compared, with the smallest change that
lets it run on a control (a feed programmed up front).

SYIL 828D warm-up: DAILY.MPF calls WARMUP_CYCLE.SPF twice through the environment's program search.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from nckemu.emulator.machine.program.language.alarms import ALARM_AUXILIARY
from nckemu.emulator.machine.program.motions import (
    ALARM_CIRCLE_END_POINT,
    ALARM_FEED_ZERO,
    ALARM_NAME_NOT_DEFINED,
    ALARM_SYNTAX,
    Arc,
    Block,
    MFunction,
    Move,
    ProgramEnd,
    SpindleCommand,
    ToolSelect,
)
from tests.conftest import SHARED
from tests.emulator.machine.program.support import DictEnvironment, run

CEAD = SHARED / "programs" / "cead_examples"
SYIL = SHARED / "programs" / "syil_828d_warmup"
AXES = ("X", "Y", "Z", "A", "B", "C", "E")
needs_shared = pytest.mark.skipif(not CEAD.is_dir(), reason="../shared/programs is not beside the repository")

FEED_FIRST = "F1000\n"  # one line up front: a G1 without any F alarms on the control (14800 here)

# name -> (alarm number on a real control, line, why; how the rest is still compared)
DIFFERENCES: dict[str, tuple[int, int, str]] = {
    "axis_index_assignment": (ALARM_FEED_ZERO, 4, "G1 without any F programmed: a control alarms (no feed). "
                              "ACC[axis] as an axis index (E is axis 4 of X Y Z E) is kept as their table has it"),
    "function_calls": (ALARM_FEED_ZERO, 2, "G1 without any F programmed"),
    "multiple_m_codes": (ALARM_FEED_ZERO, 2, "G1 without any F; and with a feed, line 4 programs M3, M4 and "
                         "M5 for one spindle in one block, which a control refuses (auxiliary functions "
                         "of one group)"),
    "r_param": (ALARM_SYNTAX, 1, "DEF REAL R0: R0 is the control's R parameter, not a name a program may "
                "define; without the DEF line R0 is that R parameter and the table holds"),
    "simple": (ALARM_FEED_ZERO, 2, "G2 without any F; with a feed the same block still has no centre "
               "(I/J/K) nor radius (CR=), which a control refuses (circle end point error)"),
    "custom_vars": (ALARM_NAME_NOT_DEFINED, 1, "aa and bb are defined nowhere in the program: CEAD's table "
                    "ran defaults.mpf first; so do we for the comparison, as a definition file would"),
}


def cead_names() -> list[str]:
    return sorted(path.stem for path in CEAD.glob("*.mpf")) if CEAD.is_dir() else []


def our_rows(text: str, axes: tuple[str, ...] = AXES, first_line: int = 1) -> tuple[list[dict], object]:
    env = DictEnvironment(axes=axes)
    result = run(text, env)
    rows: list[dict] = []
    positions: dict[str, float] = {}
    row: dict = {}
    for event in result.events:
        if isinstance(event, Block):
            row = {"N": event.number[1:] if event.number.startswith("N") else "", "M": [], "T": "",
                   "line": event.line}
            rows.append(row)
        elif isinstance(event, Move | Arc):
            positions.update(event.target_mm)
        elif isinstance(event, MFunction):
            row["M"].append(f"M{event.code}")
        elif isinstance(event, SpindleCommand) and event.direction:
            row["M"].append(event.direction)
        elif isinstance(event, ToolSelect) and event.tool is not None:
            row["T"] = str(event.tool)
        if row:
            row["positions"] = dict(positions)
    return [row for row in rows if row["line"] >= first_line], result.alarm


def project_ours(rows: list[dict], columns: list[str]) -> list[tuple]:
    flat = []
    for row in rows:
        for m_code in row["M"] or [""]:
            flat.append((row["N"], *(f"{row['positions'][c]:.3f}" if c in row.get("positions", {}) else ""
                                     for c in columns), m_code, row["T"]))
    return reduce(flat)


def project_theirs(path: Path, columns: list[str]) -> list[tuple]:
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    return reduce([(row.get("N") or "", *(row.get(c) or "" for c in columns), row.get("M") or "", row.get("T") or "")
                   for row in rows])


def reduce(rows: list[tuple]) -> list[tuple]:
    kept: list[tuple] = []
    last_positions = None
    for row in rows:
        if all(value == "" for value in row):
            continue
        positions = row[1:-2]
        if not (row[0] or row[-2] or row[-1]) and positions == last_positions:
            continue
        if kept and kept[-1] == row:
            continue
        last_positions = positions
        kept.append(row)
    return kept


def columns_of(path: Path) -> list[str]:
    with path.open(newline="") as handle:
        header = next(csv.reader(handle))
    return [column for column in header if column in AXES]


@needs_shared
def test_every_cead_example_is_covered() -> None:
    assert len(cead_names()) >= 20


@needs_shared
@pytest.mark.parametrize("name", cead_names())
def test_cead_example_matches_its_table(name: str) -> None:
    program = (CEAD / f"{name}.mpf").read_text()
    table = CEAD / f"{name}.csv"
    columns = columns_of(table)
    expected = project_theirs(table, columns)
    axes = ("X", "Y", "Z", "E") if name == "axis_index_assignment" else AXES
    if name not in DIFFERENCES:
        rows, alarm = our_rows(program, axes)
        assert alarm is None, alarm
        assert project_ours(rows, columns) == expected
        return
    number, line, _why = DIFFERENCES[name]
    rows, alarm = our_rows(program, axes)
    assert alarm is not None and (alarm.number, alarm.line) == (number, line), alarm  # type: ignore[attr-defined]
    if name == "custom_vars":
        defaults = (CEAD / "defaults.mpf").read_text()
        prefix_lines = defaults.count("\n") + 1
        rows, alarm = our_rows(defaults + "\n" + program, axes, first_line=prefix_lines + 1)
        assert alarm is None, alarm
        assert project_ours(rows, columns) == expected
    elif name == "r_param":
        without_def = "\n".join("" if line.startswith("DEF REAL R0") else line for line in program.splitlines())
        rows, alarm = our_rows(FEED_FIRST + without_def, axes)
        assert alarm is None, alarm
        assert project_ours(rows, columns) == expected
    elif name == "multiple_m_codes":
        rows, alarm = our_rows(FEED_FIRST + program, axes)
        assert alarm is not None and (alarm.number, alarm.line) == (ALARM_AUXILIARY, 5)  # type: ignore[attr-defined]
        ours = project_ours(rows, columns)
        assert ours == expected[:len(ours)] and len(ours) == 2  # M101, M102, then line 4 alarms
    elif name == "simple":
        rows, alarm = our_rows(FEED_FIRST + program, axes)
        assert alarm is not None and (alarm.number, alarm.line) == (ALARM_CIRCLE_END_POINT, 3)  # type: ignore[attr-defined]
        assert project_ours(rows, columns) == []  # nothing moved before the faulty circle
    else:
        rows, alarm = our_rows(FEED_FIRST + program, axes)
        assert alarm is None, alarm
        assert project_ours(rows, columns) == expected


# --- SYIL 828D warm-up ------------------------------------------------------------------------------

def syil_environment() -> DictEnvironment:
    subprogram = (SYIL / "subroutines" / "WARMUP_CYCLE.SPF").read_text()
    return DictEnvironment(programs={"WARMUP_CYCLE.SPF": subprogram})


@needs_shared
def test_syil_daily_runs_to_m02_with_both_speeds_and_every_move() -> None:
    env = syil_environment()
    result = run((SYIL / "routines" / "DAILY.MPF").read_text(), env, path="/_N_MPF_DIR/_N_DAILY_MPF")
    assert result.alarm is None
    assert result.events[-1] == ProgramEnd(2)
    speeds = [event.speed_rpm for event in result.of(SpindleCommand) if event.speed_rpm is not None]
    assert speeds == [3600.0, 7200.0]
    assert result.of(SpindleCommand)[-1].direction == "M5"
    # 600 s / 15 s = 40 cycles of 13 moves per call, two calls; 2 homing moves before and 2 after
    feed_moves = [move for move in result.moves if isinstance(move, Move) and move.feed is not None]
    assert len(feed_moves) == 2 * 40 * 13
    assert len(result.moves) == 2 * 40 * 13 + 4
    # G700: F300 in/min is 7620 mm/min; SUPA Z-4 in inch is 101.6 mm below machine zero
    assert {move.feed for move in feed_moves} == {300 * 25.4}
    assert min(move.target_mm.get("Z", 0.0) for move in feed_moves) == pytest.approx(-101.6)
    depths = {block.depth for block in result.blocks if "WARMUP_CYCLE" in block.program}
    assert depths == {1}


@needs_shared
def test_syil_one_cycle_by_hand() -> None:
    """One cycle's path: 10 axis-parallel moves of 4 or 5 in and 3 diagonals of 5*sqrt(2) in."""
    env = syil_environment()
    result = run((SYIL / "routines" / "DAILY.MPF").read_text(), env)
    feed_moves = [move for move in result.moves if isinstance(move, Move) and move.feed is not None][:13]
    position = {"X": 0.0, "Y": 0.0, "Z": 0.0}
    length_mm = 0.0
    for move in feed_moves:
        target = {**position, **move.target_mm}
        length_mm += math.dist([position[a] for a in "XYZ"], [target[a] for a in "XYZ"])
        position = target
    by_hand_in = 4 * 4 + 6 * 5 + 3 * 5 * math.sqrt(2)
    assert length_mm / 25.4 == pytest.approx(by_hand_in)
    # at F300 in/min the moves alone take 13.4 s; the author's "approx 15 s" includes the ramps
    assert by_hand_in / 300 * 60 == pytest.approx(13.44, abs=0.01)


@needs_shared
@pytest.mark.parametrize("name", ["FIRST_SPINDLE_RUN_IN", "IDLE_2_WEEKS", "IDLE_72_HOURS", "TEST"])
def test_the_other_syil_routines_run_without_alarm(name: str) -> None:
    result = run((SYIL / "routines" / f"{name}.MPF").read_text(), syil_environment())
    assert result.alarm is None
    assert isinstance(result.events[-1], ProgramEnd)
