"""Subprogram calls of a running program: the call stack of program levels, a call (by name, CALL, L,
with parameters and a repetition count P), its PROC line (parameters by value and by VAR reference,
SAVE), the return (M17, RET, the end of the text) and the modal call MCALL after each motion block.

:class:`Calls` is the interpreter's call job, split from it. A name no program has may be a standard
cycle (cycle_runner.py). It reads and restores the interpreter's modal state as a :class:`CallHost`,
named here so that this module does not import the interpreter.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any, Protocol

from ..motions import ALARM_PROGRAM_NOT_FOUND, ALARM_SYNTAX, Event, ProgramAlarm
from .alarms import ALARM_CALL_DEPTH, MAX_CALL_DEPTH, located
from .control_flow import ProgramLevel
from .cycle_runner import is_standard_cycle
from .expressions import NAME, Parser, evaluate, number, undefined
from .lexer import strip_comment, tokenize
from .source import ProgramSource, decode_program, normalized
from .variables import Variable

if TYPE_CHECKING:
    from nckemu.emulator.machine.frame_math import Frame

    from ..environment import ProgramEnvironment
    from .blocks import BlockCompiler
    from .cycle_runner import CycleRunner
    from .modal import ModalState
    from .names import ProgramNames

_STANDARD_CYCLE = re.compile(r"(CYCLE\d+[A-Z]?|POCKET\d+|SLOT\d+|LONGHOLE|HOLES\d|WORKPIECE|[EF]_[A-Z0-9_]+)")
# a line that is a block: not blank, not only a comment, not a % header
_BLOCK_LINE = re.compile(r"^[ \t]*[^ \t;%\n]", re.MULTILINE)


class CallHost(Protocol):
    """What a call reads and puts back of the interpreter (the Interpreter is it)."""

    env: ProgramEnvironment
    modal: ModalState   # PROC ... SAVE: copied at the call, put back on return

    def programmable_frame(self) -> Frame: ...


def as_text(text: str | bytes) -> str:
    """A program's text; bytes (as the program store keeps them) are UTF-8 or else Latin-1."""
    if isinstance(text, bytes | bytearray):
        return decode_program(bytes(text))
    return text


class Calls:
    """The call stack of one interpreter run: ``frame`` is the level that runs now (``stack[-1]``)."""

    def __init__(self, host: CallHost, names: ProgramNames, compiler: BlockCompiler, cycles: CycleRunner) -> None:
        self.host = host
        self.names = names
        self.compiler = compiler
        self.cycles = cycles
        self.sources: dict[str, ProgramSource] = {}
        self.stack: list[ProgramLevel] = []
        self.frame: ProgramLevel | None = None
        self.modal_call: tuple[Any, Any] | None = None   # MCALL: the name and the arguments' values
        self.modal_refs: tuple = ()   # MCALL: the references of its arguments (for VAR parameters)
        # The depth of the subprogram a modal call entered while it runs: its own motion blocks do not
        # call it again (a user's CYCLE82.SPF under MCALL CYCLE82 would otherwise call itself forever).
        self.modal_depth: int | None = None

    def start(self, main: ProgramSource) -> ProgramLevel:
        """The main program's level alone on the stack (a run from the start)."""
        self.sources.setdefault(main.path, main)
        frame = ProgramLevel(main, 0, 1, 0)
        self.stack = [frame]
        self._switch(frame)
        return frame

    def _switch(self, frame: ProgramLevel) -> None:
        self.frame = frame
        self.names.locals = frame.vars

    # --- calling ----------------------------------------------------------------------------------
    def call(self, name_expr: Any, args: list | None, repeat: Any, frame: ProgramLevel) -> list[Event] | None:
        """``name(args) P=repeat`` from ``frame``: the subprogram's level is entered (its blocks come
        next), or a standard cycle's events are returned."""
        return self._call(name_expr, args, repeat, frame, None)

    def _call(self, name_expr: Any, args: list | None, repeat: Any, frame: ProgramLevel,
              refs: tuple | None) -> list[Event] | None:
        names = self.names
        name = evaluate(name_expr, names)
        if name.__class__ is not str or not name:
            raise ProgramAlarm(ALARM_SYNTAX, "CALL needs a program name")
        name = name.upper()
        try:
            found = self.host.env.find_program(name, frame.source.path)
        except Exception:
            found = None
        if found is None:
            if is_standard_cycle(name):
                return self.cycles.call(name, args)
            if _STANDARD_CYCLE.fullmatch(name):
                raise ProgramAlarm(ALARM_PROGRAM_NOT_FOUND, f"{name}: no standard cycle and no program of that name")
            if args is None:
                raise undefined(name)
            raise ProgramAlarm(ALARM_PROGRAM_NOT_FOUND, f"program {name} not existing")
        path, text = found[0], as_text(found[1])
        if frame.depth + 1 > MAX_CALL_DEPTH:
            raise ProgramAlarm(ALARM_CALL_DEPTH, f"{name}: subprograms nested deeper than {MAX_CALL_DEPTH} levels")
        source = self.sources.get(path)
        if source is None or source.text != normalized(text):
            source = ProgramSource(path, text, subprogram=True)
            self.sources[path] = source
        values = tuple(None if arg is None else evaluate(arg, names) for arg in (args or ()))
        if refs is None:
            refs = tuple(getattr(arg, "lvalue", None) for arg in (args or ()))
        count = 1 if repeat is None else int(number(evaluate(repeat, names)))
        if count < 1:
            return None
        self._enter(source, values, refs, count - 1)
        return None

    def set_modal_call(self, name: Any, args: list | None) -> None:
        """``MCALL name(args)`` (``name`` None: ``MCALL`` alone ends it). The arguments passed by value
        are evaluated here, in the scope of the block that programs the MCALL: the calls come later
        from blocks of other levels (HOLES1's positioning blocks call ``CYCLE81(RTP, RFP, ...)`` with
        the main program's RTP, a name HOLES1 does not have). A VAR argument keeps its reference."""
        if name is None:
            self.modal_call = None
            return
        names = self.names
        values = None if args is None else [None if arg is None else evaluate(arg, names) for arg in args]
        self.modal_refs = tuple(getattr(arg, "lvalue", None) for arg in (args or ()))
        self.modal_call = (name, values)

    def may_call_modal(self, frame: ProgramLevel) -> bool:
        return self.modal_depth is None or frame.depth < self.modal_depth

    def call_modal(self, frame: ProgramLevel) -> list[Event]:
        """The modal call after a motion block; the subprogram it enters does not call it again."""
        events = self._call(self.modal_call[0], self.modal_call[1], None, frame,  # type: ignore[index]
                            self.modal_refs) or []
        if self.frame is not frame and self.modal_depth is None:
            self.modal_depth = self.frame.depth  # type: ignore[union-attr]
        return list(events)

    def _enter(self, source: ProgramSource, values: tuple, refs: tuple, repeat_left: int) -> None:
        depth = self.frame.depth + 1  # type: ignore[union-attr]
        frame = ProgramLevel(source, 0, 1, depth)
        params, save = self._proc_line(source, frame)
        if len(values) > len(params):
            raise ProgramAlarm(ALARM_SYNTAX, f"{len(values)} parameters given, the program takes {len(params)}")
        for index, (param, kind, by_reference, dims) in enumerate(params):
            variable = Variable(param, kind, tuple(d for d in dims if isinstance(d, int)))
            value = values[index] if index < len(values) else None
            if value is not None:
                if variable.dims:
                    raise ProgramAlarm(ALARM_SYNTAX, f"{param}: arrays are passed with VAR")
                variable.set((), value)
            frame.vars[param] = variable
            if by_reference and index < len(refs) and refs[index] is not None:
                frame.back_refs.append((refs[index], param))
        frame.saved_modal = self.host.modal.copy() if save else None
        frame.repeat_left = repeat_left
        frame.call_args = (values, refs)
        self.stack.append(frame)
        self._switch(frame)

    def _proc_line(self, source: ProgramSource, frame: ProgramLevel) -> tuple[list, bool]:
        """The parameters and SAVE of the program's PROC line (none without one); ``frame`` starts
        after that line."""
        if source.proc_offset < 0:
            return [], False
        end = source.text.find("\n", source.proc_offset)
        header = source.text[source.proc_offset: len(source.text) if end < 0 else end]
        tokens = tokenize(strip_comment(header).strip())
        parser = Parser(tokens, self.names.resolve)
        while not parser.at_name("PROC"):
            if parser.at_end():  # the line the scan took for a PROC line holds no PROC word
                raise ProgramAlarm(ALARM_SYNTAX, "PROC line without PROC")
            parser.pos += 1
        parser.pos += 1
        _, params = self.compiler.proc_header(parser)
        save = any(token[0] == NAME and token[1] == "SAVE" for token in tokens[parser.pos:])
        frame.pos = len(source.text) if end < 0 else end + 1
        frame.line = source.line_number(source.proc_offset) + 1
        return params, save

    def main_proc(self, frame: ProgramLevel) -> None:
        """A main program that starts with ``PROC NAME(...)`` (as a subprogram does): its parameters
        are its variables, 0 (empty) as nobody passes them. A PROC line after blocks is left where it is."""
        source = frame.source
        if source.proc_offset < 0 or _BLOCK_LINE.search(source.text, 0, source.proc_offset):
            return
        try:
            params, _ = self._proc_line(source, frame)
        except ProgramAlarm as alarm:
            raise located(alarm, source.path, source.line_number(source.proc_offset),
                          source.text[source.proc_offset:].split("\n", 1)[0]) from None
        for param, kind, _by_reference, dims in params:
            frame.vars[param] = Variable(param, kind, tuple(d for d in dims if isinstance(d, int)))

    # --- returning --------------------------------------------------------------------------------
    def leave(self) -> None:
        """Back to the caller: VAR parameters written back, a SAVEd modal state put back, and the
        subprogram entered again while its repetition count P lasts."""
        frame = self.stack.pop()
        self._switch(self.stack[-1])
        if frame.depth == self.modal_depth:
            self.modal_depth = None
        for ref, param in frame.back_refs:
            self.names.assign(ref, frame.vars[param].get(()))
        if frame.saved_modal is not None:
            host = self.host
            host.modal = frame.saved_modal
            host.env.set_programmable_frame(host.programmable_frame())
        if frame.repeat_left > 0 and frame.source.has_blocks:  # repeating an empty one would never yield
            values, refs = frame.call_args
            self._enter(frame.source, values, refs, frame.repeat_left - 1)


__all__ = ["CallHost", "Calls", "as_text"]
