"""Tokens of one block of a SINUMERIK part program.

A hand lexer: one compiled regular expression matched token by token. Measured on the straight-move
program of bench/bench_programs.py, a minimal lark LALR grammar parsed about 9 800 lines/s and this
tokenizer about 59 000 lines/s (docs/programs-language.md), so lark could not meet 50 000 blocks/s.
Names come out in upper case (the language is case-insensitive); strings keep their case.
"""

from __future__ import annotations

import math
import re

from ..motions import ALARM_SYNTAX, ProgramAlarm
from .alarms import ALARM_VALUE_RANGE

# Token kinds
NUM = 1     # value: float or int
NAME = 2    # value: upper-case name; ``frac`` set when a fraction follows the name (X10.5)
STR = 3     # value: the text between the quotes
OP = 4      # value: the operator text

_TOKEN = re.compile(
    r"""[ \t]*(?:
      (?P<num>(?:\d+\.?\d*|\.\d+)(?:EX[+-]?\d+)?)
     |(?P<name>[A-Z_$][A-Z0-9_$]*)(?P<frac>\.\d*)?
     |"(?P<str>[^"]*)"
     |'(?P<hex>H[0-9A-F]+|B[01]+)'
     |(?P<op>==|<>|<=|>=|<<|[-+*/()\[\],=<>:])
    )""",
    re.IGNORECASE | re.VERBOSE,
)


# A name that starts with one letter and a digit is no identifier (those begin with two letters or _):
# address words packed without spaces, split at each letter after a digit (N10G1X=R12F800 is N10 G1
# X=R12 F800). Only letters and digits: CYCLE81, X1 and F_ZC_START stay whole.
_PACKED = re.compile(r"[A-Z]\d+[A-Z][A-Z0-9]*$")
_PACKED_WORD = re.compile(r"[A-Z]+\d*")


def strip_comment(line: str) -> str:
    """The block without its ``;`` comment (a ``;`` inside a string is text)."""
    cut = line.find(";")
    if cut < 0:
        return line
    if '"' not in line[:cut]:
        return line[:cut]
    quoted = False
    for index, char in enumerate(line):
        if char == '"':
            quoted = not quoted
        elif char == ";" and not quoted:
            return line[:index]
    return line


INT_LIMIT = 2**31 - 1  # INT is 32 bits on the control; larger constants are REAL


def _number(text: str) -> float | int:
    upper = text.upper()
    try:
        if "EX" in upper:
            mantissa, exponent = upper.split("EX")
            value: float | int = float(mantissa) * 10.0 ** int(exponent)
        elif "." in text:
            value = float(text)
        else:
            value = int(text)
            if abs(value) > INT_LIMIT:
                value = float(value)
    except OverflowError:
        value = math.inf
    if value.__class__ is float and not math.isfinite(value):
        raise ProgramAlarm(ALARM_VALUE_RANGE, f"value range exceeded: the number {text} is beyond REAL's range")
    return value


def tokenize(text: str) -> list[tuple[int, object, str | None]]:
    """The tokens of ``text`` (a block without its comment); raises alarm 12080 on a stray character."""
    tokens: list[tuple[int, object, str | None]] = []
    append = tokens.append
    position = 0
    end = len(text.rstrip())
    match_at = _TOKEN.match
    while position < end:
        match = match_at(text, position)
        if match is None or match.end() == position:
            raise ProgramAlarm(ALARM_SYNTAX, f"syntax error at {text[position:position + 12].strip()!r}")
        kind = match.lastgroup
        if kind == "name" or kind == "frac":
            name = match.group("name").upper()
            if _PACKED.match(name) is not None:  # G01G90X, R12F800: address words written without spaces
                *words, last = _PACKED_WORD.findall(name)
                for word in words:
                    append((NAME, word, None))
                name = last
            append((NAME, name, match.group("frac")))
        elif kind == "num":
            append((NUM, _number(match.group("num")), None))
        elif kind == "op":
            append((OP, match.group("op"), None))
        elif kind == "str":
            append((STR, match.group("str"), None))
        else:
            digits = match.group("hex")
            append((NUM, int(digits[1:], 16 if digits[0] in "Hh" else 2), None))
        position = match.end()
    return tokens
