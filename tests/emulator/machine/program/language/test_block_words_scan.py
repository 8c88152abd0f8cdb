"""The block compiler's one-pass scan of a CAM block (blocks._CAM_WORDS) compiles exactly what the
pair of scans over any text (_SIMPLE_BLOCK, then _SIMPLE_WORD) compiles, on random blocks: the same
block, the same None (not a simple block), the same alarm."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.emulator.machine.program.language.blocks import BlockCompiler
from nckemu.emulator.machine.program.motions import ProgramAlarm

LETTERS = ["N", "G", "X", "Y", "Z", "F", "A", "C", "I", "J", "M", "S", "T", "D", "H", "L", "x", "g", "f", "CR",
           "TURN", "AR", "XX", "ſ", "K", "K"]  # the long s and the Kelvin sign: IGNORECASE's letters
NUMBERS = ["0", "1", "01", "001", "1.", ".5", "-3", "+2", "12.250", "-0.0", "90", "91", "17", "64", "4", "9",
           "33", "94", "95", "500", "1e5", "٣", "1.2.3", "", "2147483648", "-1"]
BETWEEN = [" ", " ", "\t", "  ", "", " = ", "="]
INSIDE = ["", "", "", "=", " ", " = ", "\t"]
EXTRA = ["", "", "", "", ";", "(", '"', "$", ",", "X", " "]


def outcome(compile_block, text: str) -> object:
    try:
        compiled = compile_block(text)
    except ProgramAlarm as alarm:
        return ("alarm", alarm.number)
    return None if compiled is None else (compiled.number, compiled.kind, compiled.items, compiled.text)


@settings(max_examples=400, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(LETTERS), st.sampled_from(INSIDE), st.sampled_from(NUMBERS),
                          st.sampled_from(BETWEEN)), min_size=1, max_size=7),
       st.sampled_from(EXTRA), st.integers(min_value=0, max_value=80))
def test_one_pass_equals_the_pair_of_scans(words: list[tuple[str, str, str, str]], extra: str, at: int) -> None:
    text = "".join(letters + inside + digits + between for letters, inside, digits, between in words)
    text = (text[:at] + extra + text[at:]).strip()
    if not text:
        return
    compiler = BlockCompiler(("X", "Y", "Z", "A", "C"), lambda *args: None)
    assert outcome(compiler.compile_simple, text) == outcome(compiler._compile_simple_any, text)
