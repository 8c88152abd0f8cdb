"""Definition files as a shop keeps them: global user data (GUD) and macros.

A control reads its definition files from ``/_N_DEF_DIR``: ``_N_SGUD_DEF``, ``_N_MGUD_DEF``,
``_N_UGUD_DEF`` (and ``_N_GUD4_DEF`` ... ``_N_GUD9_DEF``) hold ``DEF NCK/CHAN type name[..]``
declarations, ``_N_SMAC_DEF``, ``_N_MMAC_DEF``, ``_N_UMAC_DEF`` hold ``DEFINE name AS text`` macros.
A file of one of these names in another directory (a workpiece's ``MGUD.DEF``) counts the same.

:class:`GlobalDefinitions` is what the NCK keeps: the files it has activated, each parsed whole when
it is written. A file with a syntax error is refused (:class:`DefinitionRefused`, naming the file's
path and line) and the definitions of the file it would replace stay in force. The variables live
as long as their file is unchanged, so a value a program writes is what the next program reads, as
GUD on a control.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from nckemu.errors import NckPiBadArguments

from ..motions import ALARM_SYNTAX, ProgramAlarm
from .blocks import DEF, BlockCompiler
from .expressions import evaluate
from .gud_values import apply_values, at_line, constant_only, file_blocks, parse_values
from .lexer import tokenize
from .source import decode_program
from .variables import Variable

# The files a control activates, in the order it reads them (later ones win on a name both define).
GUD_FILES = ("SGUD", "MGUD", "UGUD", "GUD4", "GUD5", "GUD6", "GUD7", "GUD8", "GUD9")
MACRO_FILES = ("SMAC", "MMAC", "UMAC")
_DEFINITION_LEAF = re.compile(r"_N_(" + "|".join(GUD_FILES + MACRO_FILES) + r")_DEF")
# A definition file is a page of declarations; one larger than this is refused before it is read
# (a 10 MB file would otherwise be parsed line by line and hold the NCK).
MAX_DEFINITION_BYTES = 1024 * 1024
# Elements of all arrays of all definition files together (a DEF of 10^6 REAL is 8 MB on a control).
MAX_DEFINED_ELEMENTS = 4_000_000
_DEFINE = re.compile(r"DEFINE\s+([A-Z_][A-Z0-9_]*)\s+AS\s+(.*)", re.IGNORECASE)
_ENDS = frozenset({"M17", "M30", "M02", "M2", "RET"})


class DefinitionRefused(NckPiBadArguments):
    """A definition file the NCK will not activate: the alarm, the file's path and the line."""

    def __init__(self, alarm: ProgramAlarm) -> None:
        super().__init__(str(alarm))
        self.alarm = alarm


def is_definition_file(path: str) -> bool:
    """``/_N_DEF_DIR/_N_MGUD_DEF`` and a workpiece's ``_N_MGUD_DEF``: a file the NCK activates."""
    return bool(_DEFINITION_LEAF.fullmatch(path.rsplit("/", 1)[-1]))


def _kind(path: str) -> str:
    match = _DEFINITION_LEAF.fullmatch(path.rsplit("/", 1)[-1])
    return match.group(1) if match else ""


@dataclass
class DefinitionFile:
    """One activated file: its variables (by name) and its macros (name -> replacement text)."""

    path: str
    variables: dict[str, Variable] = field(default_factory=dict)
    macros: dict[str, str] = field(default_factory=dict)


def parse_definitions(path: str, text: str | bytes) -> DefinitionFile:
    """The declarations and macros of the definition file ``text`` at ``path`` (raises ProgramAlarm
    with the path and line of the first block that is neither)."""
    if isinstance(text, bytes | bytearray):
        if len(text) > MAX_DEFINITION_BYTES:
            raise ProgramAlarm(ALARM_SYNTAX, f"definition file of {len(text)} bytes (at most "
                                             f"{MAX_DEFINITION_BYTES})", program=path, line=1)
        text = decode_program(bytes(text))
    elif len(text) > MAX_DEFINITION_BYTES:
        raise ProgramAlarm(ALARM_SYNTAX, f"definition file of {len(text)} characters (at most "
                                         f"{MAX_DEFINITION_BYTES})", program=path, line=1)
    compiler = BlockCompiler((), constant_only)
    parsed = DefinitionFile(path)
    elements = 0
    for number, block in file_blocks(text):
        with at_line(path, number, block):
            elements += _parse_block(block, compiler, parsed)
            if elements > MAX_DEFINED_ELEMENTS:
                raise ProgramAlarm(ALARM_SYNTAX, f"more than {MAX_DEFINED_ELEMENTS} elements defined")
    return parsed


def _parse_block(block: str, compiler: BlockCompiler, parsed: DefinitionFile) -> int:
    """Add one block's definitions to ``parsed``; the array elements it defined."""
    define = _DEFINE.fullmatch(block)
    if define:
        name, replacement = define.group(1).upper(), define.group(2).strip()
        if not replacement:
            raise ProgramAlarm(ALARM_SYNTAX, f"DEFINE {name} AS: the replacement is empty")
        parsed.macros[name] = replacement
        return 0
    if block.upper() in _ENDS:
        return 0
    compiled = compiler.compile(block, tokenize(block))
    if compiled.kind != DEF:
        raise ProgramAlarm(ALARM_SYNTAX, "a definition file holds DEF and DEFINE ... AS blocks only")
    elements = 0
    for name, kind, dims, init, _shared in compiled.items:
        if name in parsed.variables:
            raise ProgramAlarm(ALARM_SYNTAX, f"DEF {name}: defined twice")
        variable = Variable(name, kind, dims)
        if init is not None:
            which, value = init
            if which == "value":
                if dims:
                    variable.fill((), [evaluate(value, None)], repeat=True)
                else:
                    variable.set((), evaluate(value, None))
            else:
                variable.fill((), [evaluate(item, None) for item in value], repeat=which == "REP")
        parsed.variables[name] = variable
        elements += len(variable.value) if dims else 1
    return elements


def expand_macros(block: str, macros: dict[str, str]) -> str:
    """``block`` with every macro name (a whole word, outside strings) replaced by its text; a
    macro's text may use other macros (three levels, as deep as shop files go)."""
    for _ in range(3):
        expanded = _expand_once(block, macros)
        if expanded == block:
            return block
        block = expanded
    return block


_WORD = re.compile(r"(?<![A-Z0-9_$])([A-Z_][A-Z0-9_]*)(?![A-Z0-9_])", re.IGNORECASE)


def _expand_once(block: str, macros: dict[str, str]) -> str:
    pieces = block.split('"')
    for index in range(0, len(pieces), 2):  # even pieces are outside strings
        pieces[index] = _WORD.sub(lambda match: macros.get(match.group(1).upper(), match.group(1)), pieces[index])
    return '"'.join(pieces)


class GlobalDefinitions:
    """The NCK's activated definition files (see the module docstring)."""

    def __init__(self) -> None:
        self.files: dict[str, DefinitionFile] = {}
        self._variables: dict[str, Variable] = {}
        self._macros: dict[str, str] = {}
        # Told of each check of a written file: (path, None) when it is in force, (path, alarm) when
        # it was refused (the NCK keeps the alarm on its list).
        self.on_checked: Callable[[str, ProgramAlarm | None], None] | None = None

    def _checked(self, path: str, read: Callable[[], Any]) -> Any:
        """What ``read`` returns; its alarm refuses the file (DefinitionRefused). Either way
        ``on_checked`` hears of it."""
        try:
            result = read()
        except ProgramAlarm as alarm:
            if self.on_checked is not None:
                self.on_checked(path, alarm)
            raise DefinitionRefused(alarm) from None
        if self.on_checked is not None:
            self.on_checked(path, None)
        return result

    def activate(self, path: str, text: bytes) -> None:
        """Parse ``text`` and put it in force for ``path`` (raises DefinitionRefused; then what
        ``path`` defined before stays)."""
        parsed: DefinitionFile = self._checked(path, lambda: parse_definitions(path, text))
        old = self.files.get(path)
        if old is not None:
            # a file written again keeps the values of the variables it still defines alike
            for name, variable in parsed.variables.items():
                before = old.variables.get(name)
                if before is not None and (before.kind, before.dims) == (variable.kind, variable.dims):
                    parsed.variables[name] = before
        self.files[path] = parsed
        self._merge()

    def assign_values(self, path: str, text: bytes) -> None:
        """Assign the GUD values of the value file ``text`` (gud_values.py) to the activated variables
        (raises DefinitionRefused with the line; then no value of the file is assigned)."""
        apply_values(self._checked(path, lambda: parse_values(path, text, self._variables)))

    def assign_r_values(self, path: str, text: bytes, r_parameters: int,
                        write_r: Callable[[int, float], None]) -> None:
        """Assign the R parameters of the R value file ``text`` through ``write_r`` (raises
        DefinitionRefused with the line; then none is assigned)."""
        apply_values(self._checked(path, lambda: parse_values(path, text, {}, r_parameters)), write_r)

    def remove(self, path: str) -> None:
        if self.files.pop(path, None) is not None:
            self._merge()

    def _merge(self) -> None:
        order = {name: index for index, name in enumerate(GUD_FILES + MACRO_FILES)}
        variables: dict[str, Variable] = {}
        macros: dict[str, str] = {}
        for path in sorted(self.files, key=lambda path: (order.get(_kind(path), 99), path)):
            variables.update(self.files[path].variables)
            macros.update(self.files[path].macros)
        self._variables = variables
        self._macros = macros

    def variables(self) -> dict[str, Variable]:
        """Every activated variable by name (the same objects each time: values persist)."""
        return self._variables

    def macros(self) -> dict[str, str]:
        return self._macros

    def restore(self, texts: dict[str, bytes]) -> None:
        """Activate the definition files of a restored program store; a damaged one is left out."""
        self.files.clear()
        for path, text in texts.items():
            if is_definition_file(path):
                try:
                    self.files[path] = parse_definitions(path, text)
                except ProgramAlarm:
                    continue
        self._merge()
