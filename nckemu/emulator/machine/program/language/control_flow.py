"""Control flow of a running program: where the next block is read (IF/ELSE, WHILE, FOR, REPEAT/UNTIL,
LOOP, CASE, GOTOF/GOTOB/GOTOC/GOTOS, REPEAT of a program section) and the program levels it moves in.

:class:`ControlFlow` is the interpreter's control-flow job, split from it: it moves a
:class:`ProgramLevel`'s read position and evaluates conditions and loop counters through the run's
:class:`~.names.ProgramNames`. The block compiler found each structure's partner lines when the program
was read (:class:`~.source.ProgramSource`), so nothing here scans the text for an ENDIF.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..motions import ALARM_JUMP_TARGET, ProgramAlarm
from . import blocks as b
from .alarms import ALARM_NESTING
from .expressions import evaluate, number, truth

if TYPE_CHECKING:
    from .blocks import Compiled
    from .modal import ModalState
    from .names import ProgramNames
    from .source import ProgramSource
    from .variables import Variable


class ProgramLevel:
    """One program level: the main program (depth 0) or a subprogram call, with where it reads next."""

    __slots__ = ("source", "pos", "line", "depth", "vars", "for_state", "back_refs", "saved_modal",
                 "repeat_left", "call_args", "sections")

    def __init__(self, source: ProgramSource, pos: int, line: int, depth: int) -> None:
        self.source = source
        self.pos = pos
        self.line = line
        self.depth = depth
        self.vars: dict[str, Variable] = {}
        self.for_state: dict[int, tuple[Any, Any]] = {}
        self.back_refs: list[tuple[Any, str]] = []
        self.saved_modal: ModalState | None = None   # PROC ... SAVE: the caller's, put back on return
        self.repeat_left = 0
        self.call_args: tuple[Any, ...] = ()
        # program section repetitions under way (REPEAT LABEL P=n), innermost last
        self.sections: list[Repetition] = []


class Repetition:
    """A REPEAT of a program section under way: lines ``start``..``last`` (offsets of line starts),
    ``left`` more passes, then on at ``back_pos``/``back_line`` (the line after the REPEAT)."""

    __slots__ = ("start", "last", "left", "back_pos", "back_line")

    def __init__(self, start: int, last: int, left: int, back_pos: int, back_line: int) -> None:
        self.start = start
        self.last = last
        self.left = left
        self.back_pos = back_pos
        self.back_line = back_line


class ControlFlow:
    """The control-flow job of one interpreter run; conditions and counters read and write ``names``."""

    def __init__(self, names: ProgramNames) -> None:
        self.names = names

    # --- moving the read position -----------------------------------------------------------------
    @staticmethod
    def go_after(frame: ProgramLevel, offset: int) -> None:
        """Continue with the line after the line starting at ``offset``."""
        text = frame.source.text
        end = text.find("\n", offset)
        frame.pos = len(text) if end < 0 else end + 1
        frame.line = frame.source.line_number(offset) + 1

    @staticmethod
    def go_to(frame: ProgramLevel, offset: int) -> None:
        frame.pos = offset
        frame.line = frame.source.line_number(offset)

    @staticmethod
    def _partner(frame: ProgramLevel, pos: int, what: str) -> int:
        partner = frame.source.partner.get(pos)
        if partner is None or partner < 0 or pos in frame.source.bad_nesting:
            raise ProgramAlarm(ALARM_NESTING, f"{what}: control structure not closed or nested wrongly")
        return partner

    def jump(self, frame: ProgramLevel, kind: str, target: str, pos: int) -> None:
        """GOTOF/GOTOB/GOTO/GOTOC to a label or block number (or a STRING variable naming one); GOTOS
        to the program's start."""
        if kind == "GOTOS":
            frame.pos, frame.line = 0, 1
            return
        direction = {"GOTOF": "F", "GOTOB": "B"}.get(kind, "")
        offset = frame.source.find_target(target, pos, direction)
        if offset is None:
            variable = self.names.variable(target)
            if variable is not None and variable.value.__class__ is str and variable.value:
                offset = frame.source.find_target(variable.value.upper(), pos, direction)
        if offset is None:
            if kind == "GOTOC":
                return
            raise ProgramAlarm(ALARM_JUMP_TARGET, f"jump destination {target} not found")
        self.go_to(frame, offset)

    # --- the structured statements ----------------------------------------------------------------
    def execute(self, compiled: Compiled, frame: ProgramLevel, pos: int) -> None:
        """A block of control flow (or DEF) at offset ``pos``: moves ``frame``'s read position."""
        kind = compiled.kind
        names = self.names
        if kind == b.SECTION:
            self.repeat_section(compiled.items, frame, pos)
            return
        source = frame.source
        if kind == b.IF:
            if pos in source.bad_nesting or pos not in source.partner:
                raise ProgramAlarm(ALARM_NESTING, "IF without ENDIF")
            if not truth(evaluate(compiled.items, names)):
                else_at = source.else_of.get(pos)
                self.go_after(frame, else_at if else_at is not None else source.partner[pos])
        elif kind == b.ELSE:
            self.go_after(frame, self._partner(frame, pos, "ELSE"))
        elif kind == b.WHILE:
            if not truth(evaluate(compiled.items, names)):
                self.go_after(frame, self._partner(frame, pos, "WHILE"))
            elif pos in source.bad_nesting:
                raise ProgramAlarm(ALARM_NESTING, "WHILE without ENDWHILE")
        elif kind == b.ENDWHILE:
            self.go_to(frame, self._partner(frame, pos, "ENDWHILE"))
        elif kind == b.FOR or kind == b.ENDFOR:
            self._for(compiled, frame, pos)
        elif kind == b.REPEAT or kind == b.LOOP:
            if pos in source.bad_nesting or pos not in source.partner:
                raise ProgramAlarm(ALARM_NESTING, "REPEAT/LOOP not closed")
        elif kind == b.UNTIL:
            opener = self._partner(frame, pos, "UNTIL")
            if not truth(evaluate(compiled.items, names)):
                self.go_after(frame, opener)
        elif kind == b.ENDLOOP:
            self.go_after(frame, self._partner(frame, pos, "ENDLOOP"))
        elif kind == b.ENDIF:
            if pos in source.bad_nesting:
                raise ProgramAlarm(ALARM_NESTING, "ENDIF without IF")
        elif kind == b.IF_JUMP:
            for condition, (jump_kind, target) in compiled.items:
                if truth(evaluate(condition, names)):
                    self.jump(frame, jump_kind, target, pos)
                    break
        elif kind == b.CASE:
            self._case(compiled.items, frame, pos)
        elif kind == b.DEF:
            names.define(compiled.items, frame.vars)

    def _for(self, compiled: Compiled, frame: ProgramLevel, pos: int) -> None:
        """FOR target = start TO end ... ENDFOR: the counter is the target itself (a variable or R)."""
        names = self.names
        if compiled.kind == b.FOR:
            target, start, end = compiled.items
            closer = self._partner(frame, pos, "FOR")
            start_value = evaluate(start, names)
            end_value = number(evaluate(end, names))
            names.assign(target, start_value)
            frame.for_state[pos] = (target, end_value)
            if number(names.read_target(target)) > end_value:
                self.go_after(frame, closer)
            return
        opener = self._partner(frame, pos, "ENDFOR")
        state = frame.for_state.get(opener)
        if state is None:
            raise ProgramAlarm(ALARM_NESTING, "ENDFOR without its FOR having run")
        target, end_value = state
        value = number(names.read_target(target)) + 1
        names.assign(target, value)
        if number(names.read_target(target)) <= end_value:
            self.go_after(frame, opener)

    def _case(self, items: tuple, frame: ProgramLevel, pos: int) -> None:
        """CASE (expr) OF value GOTOF label ... DEFAULT GOTOF label: a STRING matches only a STRING."""
        selector, branches, default = items
        value = evaluate(selector, self.names)
        for candidate, (jump_kind, target) in branches:
            if (candidate.__class__ is str) == (value.__class__ is str) and candidate == value:
                self.jump(frame, jump_kind, target, pos)
                return
        if default is not None:
            self.jump(frame, default[0], default[1], pos)

    # --- REPEAT of a program section --------------------------------------------------------------
    def repeat_section(self, section: b.Section, frame: ProgramLevel, pos: int) -> None:
        """REPEAT/REPEATB: find the section's lines and run them ``count`` times from here."""
        count = int(number(evaluate(section.count, self.names)))
        if count < 1:
            return
        source = frame.source
        start = source.find_target(section.start, pos, "B")
        if start is None:
            start = source.find_target(section.start, pos, "F")
        if start is None:
            raise ProgramAlarm(ALARM_JUMP_TARGET, f"jump destination {section.start} not found")
        if section.single:
            last: int | None = start
        elif section.end is None:  # from the label up to the line before the REPEAT
            last = source.text.rfind("\n", 0, max(pos - 1, 0)) + 1 if pos > 0 else -1
            if start >= pos or last is None or last < start:
                raise ProgramAlarm(ALARM_JUMP_TARGET, f"REPEAT {section.start}: the label is not before the REPEAT")
        elif section.end == section.start:
            last = start
        else:
            last = source.find_target(section.end, start, "F")
            if last is None:
                raise ProgramAlarm(ALARM_JUMP_TARGET, f"jump destination {section.end} not found")
        frame.sections.append(Repetition(start, last, count - 1, frame.pos, frame.line))
        self.go_to(frame, start)

    def section_pass_done(self, frame: ProgramLevel) -> None:
        """The read position passed the last line of the innermost repeated section: again, or on after the REPEAT."""
        section = frame.sections[-1]
        if section.left > 0:
            section.left -= 1
            self.go_to(frame, section.start)
        else:
            frame.sections.pop()
            frame.pos, frame.line = section.back_pos, section.back_line


__all__ = ["ControlFlow", "ProgramLevel", "Repetition"]
