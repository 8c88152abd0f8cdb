"""Property tests of the language: arithmetic against a Python reference, and any text whatever
gives events or a ProgramAlarm, never another exception."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.machine.program.language import Interpreter
from nckemu.emulator.machine.program.motions import ProgramAlarm
from tests.emulator.machine.program.support import MAIN, DictEnvironment

# --- arithmetic against Python -------------------------------------------------------------------------

numbers = st.one_of(st.integers(-1000, 1000), st.floats(-1000, 1000, allow_nan=False).map(lambda x: round(x, 3)))


def literal(value: float) -> tuple[str, float]:
    text = repr(float(value)) if isinstance(value, float) else str(value)
    if "e" in text.lower():
        text = f"{value:.6f}"
    return (f"({text})" if value < 0 else text), float(text.strip("()"))


@st.composite
def expressions(draw, depth: int = 0) -> tuple[str, float]:
    """A bracketed SINUMERIK expression and its value computed by Python (degrees for trig)."""
    if depth > 3 or draw(st.integers(0, 3)) == 0:
        return literal(draw(numbers))
    kind = draw(st.sampled_from(["+", "-", "*", "/", "SIN", "COS", "ABS", "POT", "TRUNC", "MOD", "ATAN2"]))
    left_text, left = draw(expressions(depth + 1))
    if kind in ("SIN", "COS", "ABS", "POT", "TRUNC"):
        value = {"SIN": lambda x: math.sin(math.radians(x)), "COS": lambda x: math.cos(math.radians(x)),
                 "ABS": abs, "POT": lambda x: x * x, "TRUNC": math.trunc}[kind](left)
        return f"{kind}({left_text})", value
    right_text, right = draw(expressions(depth + 1))
    if kind in ("/", "MOD") and abs(right) < 1e-6:
        right_text, right = "7", 7.0
    if kind == "ATAN2":
        if left == 0 and right == 0:
            right_text, right = "1", 1.0
        return f"ATAN2({left_text}, {right_text})", math.degrees(math.atan2(left, right))
    value = {"+": lambda: left + right, "-": lambda: left - right, "*": lambda: left * right,
             "/": lambda: left / right, "MOD": lambda: math.fmod(left, right)}[kind]()
    return f"({left_text} {kind} {right_text})", value


def evaluate(expression: str) -> float:
    env = DictEnvironment()
    for _ in Interpreter(env, MAIN, f"R1 = {expression}\nM30").events():
        pass
    return env.r_parameter(1)


@given(expressions())
def test_bracketed_arithmetic_equals_python(case: tuple[str, float]) -> None:
    text, expected = case
    if not math.isfinite(expected) or abs(expected) > 1e12:
        return
    assert math.isclose(evaluate(text), expected, rel_tol=1e-9, abs_tol=1e-6)


@given(st.lists(st.tuples(st.sampled_from(["+", "-", "*", "/"]), st.integers(1, 50)), min_size=1, max_size=6),
       st.integers(-50, 50))
def test_unbracketed_priority_of_arithmetic(tail: list[tuple[str, int]], head: int) -> None:
    """* and / before + and -, left to right: the same as Python for these four."""
    text = f"({head})" + "".join(f" {op} {value}" for op, value in tail)
    expected = eval(text)  # noqa: S307 - digits and four operators only
    assert math.isclose(evaluate(text), expected, rel_tol=1e-9, abs_tol=1e-9)


# --- garbage in, alarm out ---------------------------------------------------------------------------

WORDS = ["G0", "G1", "G2", "G3", "G4", "G90", "G91", "G17", "G18", "G70", "G700", "X10", "Y-5", "Z=", "F100",
         "S1000", "M3", "M5", "M30", "M17", "T1", "D1", "M6", "R1", "R1=", "=", "IF", "ELSE", "ENDIF", "WHILE",
         "ENDWHILE", "FOR", "TO", "ENDFOR", "REPEAT", "UNTIL", "LOOP", "ENDLOOP", "GOTOF", "GOTOB", "GOTO",
         "GOTOC", "LBL:", "LBL", "N10", "DEF", "INT", "REAL", "STRING[5]", "BOOL", "VAR1", "VAR1[", "]", "(",
         ")", ",", "+", "-", "*", "/", "DIV", "MOD", "AND", "OR", "NOT", "<<", "==", "<>", "SIN(", "SQRT(",
         "IC(", "AC(", "CR=", "I5", "J-5", "TRANS", "ATRANS", "SUPA", "G54", "MSG(", '"text"', "CASE(",
         "OF", "DEFAULT", "PROC", "EXTERN", "RET", "SUB", "SUB(", "CYCLE81(", "SET(", "REP(", "$AA_IM[X]",
         "$AC_TIME", ";", "%", "1.5", "0", "'H1F'", "1EX400", "TURN=", "\t", "/"]


@given(st.lists(st.lists(st.sampled_from(WORDS), max_size=8).map(" ".join), max_size=12).map("\n".join))
def test_token_soup_gives_events_or_an_alarm(text: str) -> None:
    run_guarded(text)


@given(st.text(max_size=300))
def test_any_text_gives_events_or_an_alarm(text: str) -> None:
    run_guarded(text)


def run_guarded(text: str) -> None:
    env = DictEnvironment(programs={"SUB.SPF": "PROC SUB(REAL _A)\nR2 = _A\nRET"})
    events = Interpreter(env, MAIN, text).events()
    try:
        for count, event in enumerate(events):
            env.arrive(event)
            if count > 2_000:  # an endless loop is a correct program too
                break
    except ProgramAlarm as alarm:
        assert alarm.program == MAIN or alarm.program.startswith("/_N_SPF_DIR")
        assert alarm.line >= 1
        # an exception of ours turned into an alarm would still be a bug
        assert "cannot interpret the block" not in str(alarm), alarm
    finally:
        events.close()


# --- control flow against a Python reference ---------------------------------------------------------

def structures(depth: int = 0) -> st.SearchStrategy:
    """A list of statements: ("add", k) | ("for", n, body) | ("repeat", n, body) | ("if", then, else)."""
    add = st.tuples(st.just("add"), st.integers(-3, 5))
    if depth >= 3:
        return st.lists(add, min_size=1, max_size=3)
    inner = st.deferred(lambda: structures(depth + 1))
    statement = st.one_of(
        add,
        st.tuples(st.just("for"), st.integers(0, 3), inner),
        st.tuples(st.just("repeat"), st.integers(1, 3), inner),
        st.tuples(st.just("if"), inner, st.one_of(st.none(), inner)),
    )
    return st.lists(statement, min_size=1, max_size=3)


def render(statements: list, depth: int = 0) -> list[str]:
    lines: list[str] = []
    counter = f"CNT{depth}"
    for statement in statements:
        kind = statement[0]
        if kind == "add":
            lines.append(f"R1 = R1 + {statement[1]}")
        elif kind == "for":
            lines += [f"FOR {counter} = 1 TO {statement[1]}", *render(statement[2], depth + 1), "ENDFOR"]
        elif kind == "repeat":
            lines += [f"{counter} = 0", "REPEAT", *render(statement[2], depth + 1), f"{counter} = {counter} + 1",
                      f"UNTIL {counter} >= {statement[1]}"]
        else:
            lines += ["IF R1 MOD 2 == 0", *render(statement[1], depth + 1)]
            if statement[2] is not None:
                lines += ["ELSE", *render(statement[2], depth + 1)]
            lines.append("ENDIF")
    return lines


def reference(statements: list, r1: float = 0.0) -> float:
    for statement in statements:
        kind = statement[0]
        if kind == "add":
            r1 += statement[1]
        elif kind == "for":
            for _ in range(statement[1]):
                r1 = reference(statement[2], r1)
        elif kind == "repeat":
            for _ in range(statement[1]):
                r1 = reference(statement[2], r1)
        elif math.fmod(r1, 2) == 0:
            r1 = reference(statement[1], r1)
        elif statement[2] is not None:
            r1 = reference(statement[2], r1)
    return r1


@given(structures())
def test_nested_control_structures_equal_python(program: list) -> None:
    text = "\n".join(["DEF INT CNT0, CNT1, CNT2, CNT3", *render(program), "M30"])
    env = DictEnvironment()
    for _ in Interpreter(env, MAIN, text).events():
        pass
    assert env.r_parameter(1) == reference(program)


# --- real programs, damaged -------------------------------------------------------------------------

def real_programs() -> list[str]:
    from tests.conftest import SHARED

    folder = SHARED / "programs"
    if not folder.is_dir():
        return ["G1 X10 F100\nIF R1 == 0\nR2 = SIN(30)\nENDIF\nM30"]
    return [path.read_text() for path in sorted(folder.rglob("*")) if path.suffix.upper() in (".MPF", ".SPF")]


REAL = real_programs()


@given(st.sampled_from(REAL), st.lists(st.tuples(st.integers(0, 10_000), st.sampled_from(
    list("XYZ=()[];\"\n0123456789.-+*/<>:,$_ ") + ["IF", "ENDIF", "GOTOB", "FOR", "DEF", "PROC", "M17"])),
    min_size=1, max_size=6))
def test_damaged_real_programs_give_events_or_an_alarm(program: str, edits: list[tuple[int, str]]) -> None:
    for position, text in edits:
        at = position % (len(program) + 1)
        program = program[:at] + text + program[at + 1:]
    run_guarded(program)
