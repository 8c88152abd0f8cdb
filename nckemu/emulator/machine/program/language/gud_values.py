"""Values of global user data (GUD) as a shop keeps them beside its programs: a ``.GUD`` file.

What an operator enters on the HMI into GUD arrays (a grinder's wheel diameter in ``INI[5]``, the
axis name in ``AXIS_EW``) is not in any program; a control's data backup and a workpiece directory
carry it as a file of value assignments, one or more a block::

    %_N_GRINDER_GUD
    ;$PATH=/_N_DEF_DIR
    CHANDATA(1)
    INI[5]=3 INI[53]=1500     ; wheel speed
    AXIS_EW="C"
    M17

``_N_<NAME>_GUD`` (``NAME.GUD``) written to the NCK assigns its values to the variables the activated
definition files define, in the file's order, as soon as it is written (the way an HMI loads a
workpiece's value files when it selects its program). ``CHANDATA(n)`` names the channel the blocks
after it are for (the emulated NCK has channel 1's values only; another channel's are refused). A
name no activated definition file defines, a value of the wrong type or an index outside the array
refuses the whole file with the line (:class:`ProgramAlarm`), and no value of it is kept.
"""

from __future__ import annotations

import re
from typing import Any

from ..motions import ALARM_NAME_NOT_DEFINED, ALARM_SYNTAX, ProgramAlarm
from .expressions import Parser, evaluate, undefined
from .lexer import NAME, NUM, OP, strip_comment, tokenize
from .source import decode_program
from .variables import Variable, convert

_VALUES_LEAF = re.compile(r"_N_[A-Z0-9_]+_GUD")
_BLOCK_NUMBER = re.compile(r"N\d+")
_ENDS = frozenset({"M17", "M30", "M02", "M2", "RET"})
# A value file is a page of assignments, like a definition file; larger is refused before it is read.
MAX_VALUES_BYTES = 1024 * 1024


def is_values_file(path: str) -> bool:
    """``/_N_DEF_DIR/_N_GRINDER_GUD`` (or a workpiece's): GUD values the NCK assigns when written."""
    return bool(_VALUES_LEAF.fullmatch(path.rsplit("/", 1)[-1]))


def _constant_only(parser: Any, name: str) -> Any:
    # A value is a constant: the file is read once, with no program running (a name is 12550).
    raise undefined(name)


Assignment = tuple[Variable, tuple[Any, ...], Any]


def parse_values(path: str, text: str | bytes, variables: dict[str, Variable]) -> list[Assignment]:
    """The assignments of the value file ``text``, each checked against ``variables`` (raises
    ProgramAlarm with the path and line of the first faulty block)."""
    if len(text) > MAX_VALUES_BYTES:
        raise ProgramAlarm(ALARM_SYNTAX, f"GUD value file of {len(text)} bytes (at most {MAX_VALUES_BYTES})",
                           program=path, line=1)
    if isinstance(text, bytes | bytearray):
        text = decode_program(bytes(text))
    assignments: list[Assignment] = []
    channel = 1
    for number, raw in enumerate(text.lstrip("\ufeff").splitlines(), start=1):
        block = strip_comment(raw).strip()
        if not block or block[0] == "%":
            continue
        try:
            channel = _parse_block(block, channel, variables, assignments)
        except ProgramAlarm as alarm:
            raise ProgramAlarm(alarm.number, alarm.args[0], program=path, line=number, block=block) from None
        except ArithmeticError as exc:
            raise ProgramAlarm(ALARM_SYNTAX, f"arithmetic error ({exc})", program=path, line=number,
                               block=block) from None
    return assignments


def _parse_block(block: str, channel: int, variables: dict[str, Variable], out: list[Assignment]) -> int:
    """Append the block's assignments to ``out``; the channel the next blocks are for."""
    tokens = tokenize(block)
    if tokens and tokens[0][0] == NAME and _BLOCK_NUMBER.fullmatch(tokens[0][1]):
        tokens = tokens[1:]
    if not tokens:
        return channel
    if len(tokens) == 1 and tokens[0][0] == NAME and tokens[0][1] in _ENDS:
        return channel
    if tokens[0][:2] == (NAME, "CHANDATA"):
        if len(tokens) != 4 or tokens[2][0] != NUM or tokens[1][1] != "(" or tokens[3][1] != ")":
            raise ProgramAlarm(ALARM_SYNTAX, "CHANDATA(channel number)")
        channel = int(tokens[2][1])
        if channel != 1:
            raise ProgramAlarm(ALARM_SYNTAX, f"CHANDATA({channel}): the emulated NCK has channel 1's values only")
        return channel
    parser = Parser(tokens, _constant_only)
    while not parser.at_end():
        token = parser.peek()
        if token is None or token[0] != NAME:
            raise ProgramAlarm(ALARM_SYNTAX, "a GUD value file holds NAME=value and NAME[index]=value only")
        name = token[1]
        parser.pos += 1
        variable = variables.get(name)
        if variable is None:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"name {name} not defined (no activated definition file "
                                                       "defines it)")
        indices: list[Any] = []
        if parser.at_op("["):
            parser.pos += 1
            while True:
                indices.append(evaluate(parser.expression(), None))  # type: ignore[arg-type]
                if parser.at_op(","):
                    parser.pos += 1
                    continue
                parser.expect_op("]")
                break
        parser.expect_op("=")
        value = evaluate(parser.expression(), None)  # type: ignore[arg-type]
        # checked now, not assigned: the file is refused whole or kept whole
        if indices or variable.dims:
            variable.flat_index(tuple(indices))
        out.append((variable, tuple(indices), convert(variable.kind, value, name)))
        if parser.peek() is not None and parser.peek()[0] == OP and parser.peek()[1] != "[":  # type: ignore[index]
            raise ProgramAlarm(ALARM_SYNTAX, f"{name}: an operator after the value")
    return channel


def apply_values(assignments: list[Assignment]) -> None:
    """Assign the checked values, in the file's order."""
    for variable, indices, value in assignments:
        variable.set(indices, value)
