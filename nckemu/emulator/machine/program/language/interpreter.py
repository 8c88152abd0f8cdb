"""The SINUMERIK part-program interpreter: walks a program's blocks and emits canonical events.

Lazy and without look-ahead: :meth:`Interpreter.events` is a generator, and the block after an event
is only prepared when the caller asks for the next event, so ``$AA_IM[X]`` in a block sees where the
previous motion ended (the caller moves the machine in between). Every error is a
:class:`~..motions.ProgramAlarm` naming program, line and block; nothing else escapes.

The interpreter reads each block, runs its words and keeps the modal state, the frames and the tool;
its jobs have their own modules, each asking the interpreter only for what a protocol of its own names:
the names a program reads and writes (names.py, the expressions' environment), control flow
(control_flow.py), subprogram calls and MCALL (calls.py), motion (motion_builder.py), the standard
cycles (cycle_runner.py) and the radius compensation (radius_compensation.py).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterator
from types import FunctionType
from typing import Any

from nckemu.emulator.machine.frame_math import IDENTITY_FRAME, Frame

from ..environment import ProgramEnvironment
from ..motions import (
    ALARM_FEED_ZERO,
    ALARM_NAME_NOT_DEFINED,
    ALARM_SYNTAX,
    AxesWait,
    Block,
    Dwell,
    Event,
    Message,
    MFunction,
    Move,
    ProgramAlarm,
    ProgramEnd,
    SpindleCommand,
    ToolSelect,
)
from . import blocks as b
from . import framing
from . import words as w
from .alarms import (
    ALARM_ARITHMETIC,
    ALARM_AUXILIARY,
    ALARM_UNKNOWN_G,
    MAX_M_PER_BLOCK,
    VALUE_LIMIT,
    located,
    out_of_range,
)
from .blocks import STRAIGHT, BlockCompiler, Compiled
from .calls import Calls, as_text
from .control_flow import ControlFlow, ProgramLevel
from .cycle_runner import CycleRunner
from .definitions import expand_macros
from .expressions import Parser, evaluate, number, to_text, truth, undefined
from .feedrules import DIAMETER_WORDS, TRANSVERSE_AXIS
from .gfunctions import (
    BY_NUMBER,
    G_FUNCTIONS,
    GROUP_TITLES,
    NOT_SUPPORTED,
    RUN,
)
from .lexer import strip_comment, tokenize
from .modal import ModalState
from .motion_builder import INCH_MM, MotionBuilder
from .motion_builder import PLANES as _PLANES
from .names import ProgramNames
from .radius_compensation import RadiusCompensation
from .source import ProgramSource

log = logging.getLogger(__name__)

MAX_CACHED_BLOCKS = 50_000
_BLOCK_NUMBER = re.compile(r"(?:/\d?\s*)?(N\d+)", re.IGNORECASE)
_END_CODES = frozenset({0, 1, 2, 17, 30})
# A synchronized action: [N..] [ID=n|IDS=n] WHEN|WHENEVER|FROM|EVERY condition DO actions
_SYNC_ACTION = re.compile(r"(?:/\d?\s*)?(N\d+\s*)?(?:IDS?\s*=\s*\S+\s+)?(WHENEVER|WHEN|FROM|EVERY)\b(.*?)\bDO\b.*",
                          re.IGNORECASE | re.DOTALL)
_SYNC_WORDS = frozenset({"WHEN", "WHENEVER", "FROM", "EVERY"})


class Interpreter:
    """Runs the program ``text`` at NC path ``path`` against ``env`` (see the package docstring)."""

    def __init__(self, env: ProgramEnvironment, path: str, text: str | bytes) -> None:
        self.env = env
        self.path = path
        self._main = ProgramSource(path, as_text(text))
        self._axes = tuple(axis.upper() for axis in env.axes)
        self.names = ProgramNames(self, self._axes)  # the expressions' environment: variables, R, $...
        self._compiler = BlockCompiler(self._axes, self.names.resolve, env.repeated_g_group == "alarm")
        self._macros: dict[str, str] = env.macros()
        self._logged: set[str] = set()
        self._compensation: RadiusCompensation | None = None  # G41/G42 active (radius_compensation.py)
        self.paths = MotionBuilder(self)  # the motion job: a block's axis words into moves and circles
        self._cycles = CycleRunner(self)
        self.flow = ControlFlow(self.names)  # the control-flow job: IF, loops, jumps, REPEAT
        self.calls = Calls(self, self.names, self._compiler, self._cycles)  # the call stack, MCALL
        # Machine positions of axes that have not moved since a frame change: the tool stays where the
        # old frame put it (a circle starts there), while the work position keeps the programmed value.
        self.stale_mm: dict[str, float] = {}
        self._reset_modal()

    # --- modal state ------------------------------------------------------------------------------
    def _reset_modal(self) -> None:
        env = self.env
        plane = env.reset_plane if env.reset_plane in _PLANES else "G17"
        self.modal = ModalState(motion=1 if env.reset_motion == 1 else 0, plane=plane,
                                inch_geometry=bool(env.reset_inch), inch_feed=bool(env.reset_inch),
                                g_groups={6: plane, 13: "G70" if env.reset_inch else "G71"})
        self.feed_mm = 0.0
        self.spindle_speed: dict[int, float] = {}
        self.swivel: Frame = IDENTITY_FRAME   # CYCLE800's frame, under the programmable frame
        self.tool: int | str | None = None
        self.edge: int | None = None
        self.preselected: int | str | None = None
        self.tool_length_mm = 0.0
        self.work_pos: dict[str, float] = {}
        self.stale_mm = {}
        for axis in self._axes:
            try:
                self.work_pos[axis] = float(env.machine_position_mm(axis))
            except Exception:
                self.work_pos[axis] = 0.0
        self._load_settable("G500")

    def _load_settable(self, name: str) -> None:
        self.modal.frame_name = name
        settable: dict[str, float] = {}
        for axis in self._axes:
            try:
                offset = float(self.env.work_offset_mm(name, axis))
            except Exception:
                offset = 0.0
            if offset:
                settable[axis] = offset
        self.modal.settable = settable
        self.update_shift()

    @property
    def modal_call(self) -> Any:
        """The modal call (MCALL name and arguments) or None."""
        return self.calls.modal_call

    def programmable_frame(self) -> Frame:
        """The frames a program has put on the settable frame: CYCLE800's swivel, then TRANS/ROT/..."""
        return self.modal.pframe if self.swivel is IDENTITY_FRAME else self.swivel.after(self.modal.pframe)

    def set_swivel_frame(self, frame: Frame) -> None:
        """CYCLE800 sets (identity: deselects) the swivel frame."""
        self.swivel = frame
        self.update_shift()
        self.env.set_programmable_frame(self.programmable_frame())

    def machine_now(self) -> dict[str, float]:
        """Where the last motions left every axis (machine mm), under the frames they ran in."""
        machine = self._machine_of_work()
        machine.update(self.stale_mm)
        return machine

    def _machine_of_work(self) -> dict[str, float]:
        """The work positions through the frames active now (machine mm)."""
        modal, work_pos = self.modal, self.work_pos
        infeed = _PLANES[modal.plane][2]
        if modal.chain is None:
            return {axis: value + modal.shift.get(axis, 0.0) for axis, value in work_pos.items()}
        machine = {**work_pos, **modal.chain.apply(work_pos)}
        if infeed in machine:
            machine[infeed] += modal.shift.get(infeed, 0.0) - modal.chain.translation.get(infeed, 0.0)
        return machine

    def update_shift(self) -> None:
        before = self.machine_now() if getattr(self, "work_pos", None) else None
        chain = framing.chain(self.modal.settable, self.programmable_frame())
        self.modal.chain = None if chain.is_translation else chain
        shift = dict(chain.translation)
        if self.tool_length_mm:
            infeed = _PLANES[self.modal.plane][2]
            shift[infeed] = shift.get(infeed, 0.0) + self.tool_length_mm
        self.modal.shift = shift
        if before is not None:  # the axes the change moves keep, until they move, where the old frames put them
            after = self._machine_of_work()
            stale = self.stale_mm
            for axis, value in before.items():
                if abs(after.get(axis, value) - value) > 1e-12:
                    stale[axis] = value
                else:
                    stale.pop(axis, None)

    def _update_tool_length(self) -> None:
        length = 0.0
        if self.edge:
            try:
                length = float(self.env.tool_length_mm(self.tool, self.edge))
            except Exception:
                length = 0.0
        self.tool_length_mm = length
        self.update_shift()

    def is_rotary(self, axis: str) -> bool:
        try:
            return bool(self.env.axis_is_rotary(axis))
        except Exception:
            return axis in ("A", "B", "C")

    # --- running ----------------------------------------------------------------------------------
    def programs_in_use(self) -> frozenset[str]:
        """The NC paths of the programs being executed: the main program and each subprogram called
        and not yet returned from (a control refuses to replace them)."""
        return frozenset(frame.source.path for frame in self.calls.stack)

    def events(self) -> Iterator[Event]:
        """The program's events in execution order (a Block before each executed block)."""
        try:
            yield from self._run()
        except ProgramAlarm:
            raise
        except Exception as exc:  # a fault of ours must still reach the user as an alarm
            log.exception("interpreter fault")
            frame = self.calls.frame
            raise ProgramAlarm(ALARM_SYNTAX, f"cannot interpret the block ({type(exc).__name__})",
                               program=frame.source.path if frame else self.path,
                               line=max(frame.line - 1, 1) if frame else 0) from None

    def _run(self) -> Iterator[Event]:
        calls, flow = self.calls, self.flow
        if calls.stack:  # events() called again: the program from its start, the modal state reset
            self._reset_modal()
            self.names.settings.clear()
            calls.modal_call = None
            calls.modal_depth = None
        frame = calls.start(self._main)
        try:
            calls.main_proc(frame)
        except ProgramAlarm as alarm:  # the PROC line is the faulty block on the display
            yield Block(self._main.path, alarm.line, "", alarm.block, 0)
            raise
        while True:
            frame = calls.frame
            source = frame.source
            text = source.text
            pos = frame.pos
            if frame.sections and pos > frame.sections[-1].last:
                flow.section_pass_done(frame)
                continue
            if pos >= len(text):
                if frame.depth == 0:
                    yield ProgramEnd(0)
                    return
                calls.leave()
                continue
            end = text.find("\n", pos)
            if end < 0:
                end = len(text)
            line = frame.line
            frame.pos = end + 1
            frame.line = line + 1
            cache = source.compiled
            compiled = cache.get(pos)
            if compiled is None:
                raw = text[pos:end]
                try:
                    try:
                        compiled = self._compile(raw)
                    except ArithmeticError as exc:
                        raise ProgramAlarm(ALARM_ARITHMETIC, f"arithmetic error ({exc})") from None
                except ProgramAlarm as alarm:
                    # the faulty block is the current block on the control's display
                    text_only = strip_comment(raw).strip()
                    number = _BLOCK_NUMBER.match(text_only)
                    yield Block(source.path, line, number.group(1).upper() if number else "", text_only, frame.depth)
                    raise located(alarm, source.path, line, raw) from None
                if compiled is None:
                    continue
                if source.subprogram or source.has_jumps or (source.loop_spans and source.in_loop(pos)):
                    if len(cache) >= MAX_CACHED_BLOCKS:
                        cache.clear()
                    cache[pos] = compiled
            block: Block | None = Block(source.path, line, compiled.number, compiled.text, frame.depth)
            if self._compensation is None or not self._compensation.holding:
                yield block  # type: ignore[misc]
                block = None
            try:
                events = self._straight(compiled, frame) if compiled.kind == STRAIGHT else \
                    self._execute(compiled, frame, pos)
            except ProgramAlarm as alarm:
                raise located(alarm, source.path, line, compiled.text) from None
            except ArithmeticError as exc:  # an overflow deep in a conversion is still arithmetic
                alarm = ProgramAlarm(ALARM_ARITHMETIC, f"arithmetic error ({exc})")
                raise located(alarm, source.path, line, compiled.text) from None
            if self._compensation is not None:  # G41/G42: a contour element waits for the next one
                try:
                    events = self._compensation.take(block, events or [])
                except ProgramAlarm as alarm:
                    raise located(alarm, source.path, line, compiled.text) from None
                if self._compensation.done:
                    self._compensation = None
            if events:
                yield from events
                if events[-1].__class__ is ProgramEnd:
                    return

    def _compile(self, raw: str) -> Compiled | None:
        text = (strip_comment(raw) if ";" in raw else raw).strip()  # most CAM blocks carry no comment
        if not text or text[0] == "%":
            return None
        if self._macros:
            text = expand_macros(text, self._macros)
        simple = self._compiler.compile_simple(text)  # most CAM blocks: the short way, checked first
        if simple is not None:
            return simple
        sync = _SYNC_ACTION.match(text)
        if sync is not None:
            return self._compile_sync_action(text, sync)
        return self._compiler.compile(text, tokenize(text))

    def _compile_sync_action(self, text: str, sync: re.Match[str]) -> Compiled:
        """``[ID=n] WHEN|WHENEVER|FROM|EVERY condition DO actions``: the condition compiled, the actions not
        (the emulator runs no synchronized actions; see _sync_action)."""
        parser = Parser(tokenize(sync.group(3)), self.names.resolve)
        condition = parser.expression()
        if not parser.at_end():
            raise ProgramAlarm(ALARM_SYNTAX, f"{sync.group(2).upper()} condition DO: the condition does not end")
        number = sync.group(1).upper() if sync.group(1) else ""
        return Compiled(number, b.WORDS, [w.NoOp(sync.group(2).upper(), condition)], text)

    def _sync_action(self, word: str, condition: Any) -> None:
        """A synchronized action is accepted while its condition is false when the block runs (a
        grinder's WHEN $A_IN[2]==1 DO ... waits for a retract key nobody presses); the condition is not
        watched afterwards. One whose condition already holds would act now: 12550, not supported."""
        if truth(evaluate(condition, self.names)):
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"synchronized action {word} ... DO with its condition "
                                                       "true is not supported by the emulator")
        self._log_once(f"SYNC{word}", f"synchronized action {word} ... DO accepted: its condition is false "
                                      "now and not watched (actions not simulated)")

    # --- names ------------------------------------------------------------------------------------
    def axis_name(self, value: Any) -> str:
        """An axis by name or index (the motion job asks, as a MotionSource)."""
        return self.names.axis_name(value)

    def _log_once(self, what: str, message: str) -> None:
        if what not in self._logged:
            self._logged.add(what)
            log.info("%s: %s", self.path, message)

    # --- control flow -----------------------------------------------------------------------------
    def _straight(self, compiled: Compiled, frame: ProgramLevel) -> list[Event] | None:
        """A block of constant axis words, F and modal G only (most CAM blocks), the short way."""
        g_codes, axis_words, feed = compiled.items  # axis_words: name -> value (the compiled block's: copied)
        modal = self.modal
        for code in g_codes:
            if code <= 1:
                modal.motion = code
            else:
                self._g(code, {})
                modal = self.modal
        if feed is not None:
            self.feed_mm = feed * INCH_MM if (modal.inch_feed and modal.feed_mode != "G93") else feed
        if not axis_words:
            return None
        motion = modal.motion
        if modal.inch_geometry or not modal.absolute or motion > 1 or modal.chain is not None \
                or not modal.feed_rules.plain:
            moved = self._motion([(axis, value, None) for axis, value in axis_words.items()], {}, {})
            events: list[Event] = moved if moved.__class__ is list else [moved]  # type: ignore[assignment,list-item]
        else:
            shift = modal.shift
            work_pos = self.work_pos
            programmed = axis_words.copy()
            work_pos.update(axis_words)
            if shift:
                targets = {axis: value + shift[axis] if axis in shift else value for axis, value in axis_words.items()}
            else:
                targets = axis_words.copy()
            stale = self.stale_mm
            if stale:
                for axis in programmed:
                    stale.pop(axis, None)
            if motion == 0:
                events = [Move(targets, None, modal.feed_mode, modal.exact_stop, programmed)]  # type: ignore[arg-type]
            else:
                if self.feed_mm <= 0:
                    raise ProgramAlarm(ALARM_FEED_ZERO, "programmed path velocity less than or equal to zero (no F)")
                events = [Move(targets, self.feed_mm, modal.feed_mode, modal.exact_stop, programmed)]  # type: ignore[arg-type]
        calls = self.calls
        if calls.modal_call is not None and calls.may_call_modal(frame):
            events += calls.call_modal(frame)
        return events

    def _execute(self, compiled: Compiled, frame: ProgramLevel, pos: int) -> list[Event] | None:
        """Any block but a STRAIGHT one (_run hands that to :meth:`_straight` itself, a call fewer a block)."""
        kind = compiled.kind
        if kind == b.WORDS:
            return self._words(compiled.items, frame, pos)
        if kind != b.NOTHING and kind != b.EXTERN and kind != b.PROC:
            self.flow.execute(compiled, frame, pos)
        return None

    # --- the words of a block ---------------------------------------------------------------------
    def _g(self, code: int, flags: dict) -> None:
        """A G function as its entry in the table (gfunctions.py) says: run by its group's handler,
        accepted without effect, refused as not supported (12550), or unknown (12470)."""
        entry = BY_NUMBER.get(code)
        if entry is None:
            raise ProgramAlarm(ALARM_UNKNOWN_G, f"G function G{code} unknown (no SINUMERIK G function)")
        if entry.modal and entry.group != 1:
            self.modal.g_groups[entry.group] = entry.name
        if entry.emulation is RUN:
            _G_GROUP_HANDLERS[entry.group](self, code, flags)
        elif entry.emulation is NOT_SUPPORTED:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"G{code} (G group {entry.group}, "
                               f"{GROUP_TITLES[entry.group]}) is not supported by the emulator")
        else:
            self._log_once(f"G{code}", f"G{code} accepted, not modelled")

    # one handler per G group the interpreter runs (the groups of the table's RUN entries)
    def _g_motion(self, code: int, flags: dict) -> None:           # group 1
        self.modal.motion = code

    def _g_non_modal(self, code: int, flags: dict) -> None:        # group 2 (G4), 3 (G25/G26), 9, 11
        flags[_G_FLAGS[code]] = code

    def _g_plane(self, code: int, flags: dict) -> None:            # group 6
        self.modal.plane = f"G{code}"
        if self.tool_length_mm:
            self.update_shift()

    def _g_settable_frame(self, code: int, flags: dict) -> None:   # group 8
        self._load_settable(f"G{code}")
        self.env.select_settable_frame(f"G{code}")

    def _g_path_mode(self, code: int, flags: dict) -> None:        # group 10
        self.modal.exact_stop = code == 60

    def _g_units(self, code: int, flags: dict) -> None:            # group 13
        self.modal.inch_geometry = code in (70, 700)
        # G70/G71 switch the geometry only: F stays in the basic system (MD10240); G700/G710 switch both
        self.modal.inch_feed = code == 700 or (code in (70, 71) and bool(self.env.reset_inch))

    def _g_dimensions(self, code: int, flags: dict) -> None:       # group 14
        self.modal.absolute = code == 90

    def _g_radius_compensation(self, code: int, flags: dict) -> None:  # group 7
        compensation = self._compensation
        if code == 40:
            if compensation is not None:
                compensation.ending = True
            return
        radius = float(self.env.tool_radius_mm(self.tool, self.edge))
        if radius <= 0.0:
            self._log_once(f"G{code}", f"G{code} with an edge radius of 0: the contour runs as programmed")
            return
        if compensation is None:
            first, second, _ = _PLANES[self.modal.plane]
            start = (self.work_pos.get(first, 0.0) + self.modal.shift.get(first, 0.0),
                     self.work_pos.get(second, 0.0) + self.modal.shift.get(second, 0.0))
            self._compensation = RadiusCompensation(code, radius, (first, second), start)
        else:
            compensation.ending = False

    def _g_feed_type(self, code: int, flags: dict) -> None:        # group 15
        # G96/G97 (constant cutting speed on/off) are both feed per revolution
        self.modal.feed_mode = f"G{code}" if code in (93, 94, 95) else "G95"
        self.modal.feed_rules = self.modal.feed_rules.g(code)
        if code in (96, 97):
            flags["css"] = code == 96

    def _words(self, items: list, frame: ProgramLevel, pos: int) -> list[Event] | None:
        names = self.names
        flags: dict[str, Any] = {}
        axis_words: list[tuple[str, Any, Any]] = []
        address: dict[str, Any] = {}
        m_codes: list[tuple[int, int]] = []
        message: Any = None
        jump = call = None
        ret = False
        spos: list[int] = []
        positions: list[tuple[str, str, Any, str | None]] = []  # POS/POSA/POSP: kind, axis, value, mode
        waits: list[Event] = []
        for item in items:
            kind = item.__class__
            if kind is w.AxisWord:
                value = item.value
                axis_words.append((item.axis, value(names) if value.__class__ is FunctionType else value, item.mode))
            elif kind is w.IndirectAxisWord:
                value = item.value
                axis_words.append((names.axis_name(evaluate(item.axis, names)),
                                   value(names) if value.__class__ is FunctionType else value, item.mode))
            elif kind is w.GWord:
                self._g(item.code, flags)
                if item.spline is not None:
                    self._log_once(item.spline, f"{item.spline}: runs as straight moves through its points")
            elif kind is w.AddressWord:
                letter = item.letter
                value = item.value
                if value.__class__ is FunctionType:
                    value = value(names)
                if letter == "M":
                    m_codes.append((item.extension, _m_code(value)))
                elif letter == "S":
                    address[f"S{item.extension or 1}"] = value
                elif letter == "L":
                    call = (f"L{int(number(value))}", [], None)
                elif letter == "E":
                    raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, "name E not defined (no axis E; a number's exponent "
                                                               "is written EX: 1EX3)")
                else:
                    address[letter] = value
            elif kind is w.CentreWord:
                value = item.value
                address[item.letter] = (value(names) if value.__class__ is FunctionType else value, item.mode)
            elif kind is w.Assign:
                value = item.value
                names.assign(item.target, value(names) if value.__class__ is FunctionType else value)
            elif kind is w.Suppress:
                flags["supa"] = True
            elif kind is w.Msg:
                message = to_text(evaluate(item.text, names))
            elif kind is w.Jump:
                jump = (item.kind, item.target)
            elif kind is w.Call:
                call = (item.name, item.args, item.repeat)
            elif kind is w.Return:
                ret = True
            elif kind is w.FrameWord:
                self._frame_instruction(item.word, item.pairs)
            elif kind is w.AxisSetting:
                indices = tuple(evaluate(i, names) for i in item.indices)
                if len(indices) != 1:
                    raise ProgramAlarm(ALARM_SYNTAX, f"{item.name}[axis]=value")
                names.settings[(item.name, names.axis_name(indices[0]))] = evaluate(item.value, names)
            elif kind is w.PositionWord:
                value = item.value
                positions.append((item.kind, names.axis_name(evaluate(item.axis, names)),
                                  value(names) if value.__class__ is FunctionType else value, item.mode))
            elif kind is w.WaitPosition:
                waits.append(AxesWait(tuple(names.axis_name(evaluate(axis, names)) for axis in item.axes)))
            elif kind is w.Fill:
                target_kind, name, indices = item.target
                variable = names.variable(name) if target_kind == "VAR" else None
                if variable is None:
                    raise undefined(name if isinstance(name, str) else "R")
                variable.fill(tuple(evaluate(i, names) for i in indices),
                              [evaluate(v, names) for v in item.values], repeat=item.which == "REP")
            elif kind is w.ModalCall:
                self.calls.set_modal_call(item.name, item.args)
            elif kind is w.Spos:
                spos.append(item.spindle)
            elif kind is w.Setal:
                self._setal(evaluate(item.number, names))
            elif kind is w.NoOp:
                if item.name in _SYNC_WORDS:
                    self._sync_action(item.name, item.args)
                    continue
                entry = G_FUNCTIONS.get(item.name)
                if entry is not None and entry.modal:
                    self.modal.g_groups[entry.group] = item.name
                if item.name in DIAMETER_WORDS or item.name == "FGROUP":
                    self.modal.feed_rules = self.modal.feed_rules.word(item.name, item.args, self.paths.fgroup_axes)
                elif item.name != "N":
                    self._log_once(item.name, f"{item.name} accepted, not modelled")
        events: list[Event] = []
        if message is not None:
            events.append(Message(message))
        self._tool_words(address, m_codes, events)
        self._spindle_words(address, m_codes, spos, flags, events)
        if "F" in address and not flags.get("dwell"):
            feed = float(number(address["F"]))
            self.feed_mm = feed * INCH_MM if (self.modal.inch_feed and self.modal.feed_mode != "G93") else feed
        for extension, m_code in m_codes:
            if m_code not in (3, 4, 5) and m_code not in _END_CODES:
                events.append(MFunction(m_code, extension))
        if flags.get("pole") or "AP" in address or "RP" in address:
            axis_words = self.paths.polar(axis_words, address, flags)
        if waits or positions:  # WAITP first; positioning axes start with the block's path motion
            events += waits
            events += self.paths.positioning(positions, names.settings)
        moved = False
        if flags.get("dwell"):
            if axis_words:
                raise ProgramAlarm(ALARM_SYNTAX, "G4 stands in a block of its own")
            if "F" in address:
                events.append(Dwell(seconds=float(number(address["F"]))))
            elif "S1" in address:
                events.append(Dwell(spindle_revolutions=float(number(address["S1"]))))
            else:
                raise ProgramAlarm(ALARM_SYNTAX, "G4 needs F (seconds) or S (revolutions)")
        elif axis_words or "I" in address or "J" in address or "K" in address or "CR" in address:
            motion = self._motion(axis_words, address, flags)
            if motion.__class__ is list:  # a circle as chords (framing.framed_arc)
                events += motion  # type: ignore[arg-type]
            else:
                events.append(motion)  # type: ignore[arg-type]
            moved = True
        if positions and any(kind != "POSA" for kind, _, _, _ in positions):  # POS: the block waits for them
            events.append(AxesWait(tuple(axis for kind, axis, _, _ in positions if kind != "POSA")))
        end_code = None
        for extension, m_code in m_codes:
            if m_code in _END_CODES:
                events.append(MFunction(m_code, extension))
                if m_code in (2, 30, 17):
                    end_code = m_code
        calls = self.calls
        modal = moved and calls.modal_call is not None and call is None and calls.may_call_modal(frame)
        if end_code is not None or ret:
            if frame.depth == 0 or (end_code in (2, 30) and not self.env.subprogram_end_returns):
                events.append(ProgramEnd(end_code if end_code is not None else 0))
                return events
            calls.leave()
            return events
        if modal:
            events += calls.call_modal(frame)
        elif call is not None:
            events += calls.call(call[0], call[1], call[2], frame) or ()
        if jump is not None:
            self.flow.jump(frame, jump[0], jump[1], pos)
        return events

    def _motion(self, axis_words: list, address: dict, flags: dict) -> Event | list[Event]:
        return self.paths.motion(axis_words, address, flags)

    def _setal(self, value: Any) -> None:
        number_value = int(number(value))
        if 60000 <= number_value <= 64999:
            raise ProgramAlarm(number_value, f"cycle alarm {number_value} (SETAL)")
        self._log_once(f"SETAL{number_value}", f"SETAL({number_value}): alarm shown, program continues")

    def _tool_words(self, address: dict, m_codes: list, events: list) -> None:
        has_t = "T" in address
        has_d = "D" in address
        change = any(m_code == 6 for _, m_code in m_codes)
        if not (has_t or has_d or change):
            return
        tool: int | str | None = None
        if has_t:
            value = address["T"]
            tool = value.upper() if value.__class__ is str else int(number(value))
            self.preselected = tool
        direct = self.env.tool_change_mode == 0
        if change or (has_t and direct):
            self.tool = self.preselected
            tool = self.tool
            change = True
            self.edge = 1
        edge = None
        if has_d:
            edge = int(number(address["D"]))
            self.edge = edge
        elif change:
            edge = self.edge
        if change or has_d:
            self._update_tool_length()
        events.append(ToolSelect(tool=tool, edge=edge, change=change))

    def _spindle_words(self, address: dict, m_codes: list, spos: list, flags: dict, events: list) -> None:
        if not (address or m_codes or spos or flags):  # a block of assignments, jumps or calls only
            return
        directions: dict[int, str] = {}
        if len(m_codes) > MAX_M_PER_BLOCK:
            raise ProgramAlarm(ALARM_AUXILIARY, f"{len(m_codes)} M functions in one block (at most {MAX_M_PER_BLOCK})")
        for extension, m_code in m_codes:
            if m_code in (3, 4, 5):
                if (extension or 1) in directions:
                    raise ProgramAlarm(ALARM_AUXILIARY, f"two spindle directions for spindle {extension or 1} in one block")
                directions[extension or 1] = f"M{m_code}"
        for spindle in spos:
            directions[spindle] = "M5"
        speeds: dict[int, float] = {}
        if not flags.get("dwell") and not flags.get("limit"):
            for key, value in address.items():
                if key[0] == "S" and key[1:].isdigit():
                    speed = float(number(value))
                    speeds[int(key[1:])] = speed
                    self.spindle_speed[int(key[1:])] = speed
        rules = self.modal.feed_rules
        if "LIMS" in address or rules.constant_speed:
            self.modal.feed_rules = rules.spindle_words(speeds.get(1), address.get("LIMS"))
        # under G96 S is the cutting speed: the master spindle's speed follows X (from the block's G96 on)
        css = self.modal.feed_rules.css(self.modal.shift.get(TRANSVERSE_AXIS, 0.0))
        if css is not None and (flags.get("css") or self.modal.feed_rules != rules):
            directions.setdefault(1, None)  # type: ignore[arg-type]
        for spindle in sorted(set(directions) | set(speeds)):
            if spindle == 1 and css is not None:
                events.append(SpindleCommand(spindle=1, direction=directions.get(1), css=css))  # type: ignore[arg-type]
                continue
            events.append(SpindleCommand(spindle=spindle, speed_rpm=speeds.get(spindle),
                                         direction=directions.get(spindle)))  # type: ignore[arg-type]

    def _frame_instruction(self, word: str, pairs: list) -> None:
        values: list[tuple[str, float]] = []
        for axis, raw in pairs:
            value = float(number(evaluate(raw, self.names)))
            if not -VALUE_LIMIT <= value <= VALUE_LIMIT:
                raise out_of_range(f"{word} {axis}", value)
            if word.endswith("TRANS") and not self.is_rotary(axis) and self.modal.inch_geometry:
                value *= INCH_MM
            values.append((axis, value))
        self.modal.pframe = framing.programmed_frame(self.modal.pframe, word, values, self.modal.plane)
        self.update_shift()
        self.env.set_programmable_frame(self.programmable_frame())


_G_GROUP_HANDLERS: dict[int, Any] = {
    1: Interpreter._g_motion, 2: Interpreter._g_non_modal, 3: Interpreter._g_non_modal, 6: Interpreter._g_plane,
    7: Interpreter._g_radius_compensation,
    8: Interpreter._g_settable_frame, 9: Interpreter._g_non_modal, 10: Interpreter._g_path_mode,
    11: Interpreter._g_non_modal, 13: Interpreter._g_units, 14: Interpreter._g_dimensions,
    15: Interpreter._g_feed_type,
}
# the block flag a non-modal G function sets: G4 a dwell, G25/G26 S as a speed limit (not applied),
# G53/G153 frames suppressed, G9 exact stop in this block
_G_FLAGS = {4: "dwell", 25: "limit", 26: "limit", 53: "supa", 153: "supa", 9: "g9", 110: "pole", 111: "pole",
            112: "pole"}


def _m_code(value: Any) -> int:
    code = number(value)
    if code.__class__ is float:
        if code != int(code):
            raise ProgramAlarm(ALARM_SYNTAX, f"M{code} is not an M function")
        code = int(code)
    if code < 0:
        raise ProgramAlarm(ALARM_SYNTAX, f"M{code} is not an M function")
    return code


__all__ = ["Interpreter"]
