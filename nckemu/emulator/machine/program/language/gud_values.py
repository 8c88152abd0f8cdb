"""Values of global user data (GUD) and R parameters as a shop keeps them beside its programs: a
``.GUD`` and a ``.RPA`` file.

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

``_N_<NAME>_RPA`` (``NAME.RPA``) holds R parameters the same way (``R1=2.5`` or ``R[1]=2.5``, channel
1's), as a data backup keeps a channel's R parameters (the file type's name is UNCONFIRMED).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from ..motions import ALARM_NAME_NOT_DEFINED, ALARM_SYNTAX, ProgramAlarm
from .expressions import Parser, evaluate, undefined
from .lexer import NAME, NUM, OP, strip_comment, tokenize
from .source import decode_program
from .variables import Variable, convert

_VALUES_LEAF = re.compile(r"_N_[A-Z0-9_]+_GUD")
_R_VALUES_LEAF = re.compile(r"_N_[A-Z0-9_]+_RPA")
_R_NAME = re.compile(r"R(\d+)")
_BLOCK_NUMBER = re.compile(r"N\d+")
_ENDS = frozenset({"M17", "M30", "M02", "M2", "RET"})
# A value file is a page of assignments, like a definition file; larger is refused before it is read.
MAX_VALUES_BYTES = 1024 * 1024


def is_values_file(path: str) -> bool:
    """``/_N_DEF_DIR/_N_GRINDER_GUD`` (or a workpiece's): GUD values the NCK assigns when written."""
    return bool(_VALUES_LEAF.fullmatch(path.rsplit("/", 1)[-1]))


def is_r_values_file(path: str) -> bool:
    """``/_N_DEF_DIR/_N_TAP_RPA``: R parameters the NCK assigns when written."""
    return bool(_R_VALUES_LEAF.fullmatch(path.rsplit("/", 1)[-1]))


def constant_only(parser: Any, name: str) -> Any:
    """The name resolver of a definition or value file: it is read once, with no program running and
    nothing else defined yet, so a value is a constant and a name in it is the control's 12550."""
    raise undefined(name)


Assignment = tuple[Variable | int, tuple[Any, ...], Any]   # a variable and its indices, or an R's number


def file_blocks(text: str) -> Iterator[tuple[int, str]]:
    """(line number, block) of a definition or value file: comments cut, blank and ``%`` lines left out."""
    for number, raw in enumerate(text.lstrip("\ufeff").splitlines(), start=1):
        block = strip_comment(raw).strip()
        if block and block[0] != "%":
            yield number, block


@contextmanager
def at_line(path: str, number: int, block: str) -> Iterator[None]:
    """An alarm raised while one block of a file is read names the file and line; an arithmetic error
    is a syntax alarm there."""
    try:
        yield
    except ProgramAlarm as alarm:
        raise ProgramAlarm(alarm.number, alarm.args[0], program=path, line=number, block=block) from None
    except ArithmeticError as exc:
        raise ProgramAlarm(ALARM_SYNTAX, f"arithmetic error ({exc})", program=path, line=number,
                           block=block) from None


def parse_values(path: str, text: str | bytes, variables: dict[str, Variable],
                 r_parameters: int = 0) -> list[Assignment]:
    """The assignments of the value file ``text``, each checked against ``variables`` (or, with
    ``r_parameters`` > 0, R0 ... R<r_parameters - 1> only; raises ProgramAlarm with the path and line
    of the first faulty block)."""
    if len(text) > MAX_VALUES_BYTES:
        raise ProgramAlarm(ALARM_SYNTAX, f"GUD value file of {len(text)} bytes (at most {MAX_VALUES_BYTES})",
                           program=path, line=1)
    if isinstance(text, bytes | bytearray):
        text = decode_program(bytes(text))
    assignments: list[Assignment] = []
    channel = 1
    for number, block in file_blocks(text):
        with at_line(path, number, block):
            channel = _parse_block(block, channel, variables, assignments, r_parameters)
    return assignments


def _parse_block(block: str, channel: int, variables: dict[str, Variable], out: list[Assignment],
                 r_parameters: int = 0) -> int:
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
    parser = Parser(tokens, constant_only)
    while not parser.at_end():
        token = parser.peek()
        if token is None or token[0] != NAME:
            raise ProgramAlarm(ALARM_SYNTAX, "a GUD value file holds NAME=value and NAME[index]=value only")
        name = token[1]
        parser.pos += 1
        if r_parameters:
            out.append(_r_assignment(name, parser, r_parameters))
            continue
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


def _r_assignment(name: str, parser: Parser, r_parameters: int) -> Assignment:
    """``R12=value`` or ``R[12]=value`` of an R value file."""
    numbered = _R_NAME.fullmatch(name)
    if numbered is not None:
        index: Any = int(numbered.group(1))
    elif name == "R" and parser.at_op("["):
        parser.pos += 1
        index = evaluate(parser.expression(), None)  # type: ignore[arg-type]
        parser.expect_op("]")
    else:
        raise ProgramAlarm(ALARM_SYNTAX, f"{name}: an R value file holds R<n>=value only")
    if isinstance(index, float) and index.is_integer():
        index = int(index)
    if not isinstance(index, int) or not 0 <= index < r_parameters:
        raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"name R{index} not defined (R0...R{r_parameters - 1})")
    parser.expect_op("=")
    return index, (), convert("REAL", evaluate(parser.expression(), None), f"R{index}")  # type: ignore[arg-type]


def apply_values(assignments: list[Assignment], write_r: Any = None) -> None:
    """Assign the checked values, in the file's order (an R parameter's through ``write_r(n, value)``)."""
    for variable, indices, value in assignments:
        if isinstance(variable, int):
            write_r(variable, value)
        else:
            variable.set(indices, value)
