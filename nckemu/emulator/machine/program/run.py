"""One run of a part program on a channel: the interpreter's events, one at a time, finished in
simulated time by the planner.

:class:`ProgramRun` asks the interpreter for the next event only when the last one has finished in
simulated time (a move has arrived, a dwell has passed), so the interpreter's reads (``$AA_IM``,
``$AC_TIME``, R parameters) see the machine as the block sees it on a control. :meth:`ProgramRun.advance`
runs up to a simulated time and at most a number of blocks, so an endless loop never holds the cycle.
:class:`NckEnvironment` is what the interpreter may ask of the NCK: R parameters (the ones the NCK
serves), positions, work offsets, tool lengths, system variables and subprograms.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from datetime import datetime
from typing import TYPE_CHECKING

from nckemu.emulator.machine.nck import nck_io
from nckemu.emulator.machine.nck.geometric_axes import channel_axis_name
from nckemu.emulator.machine.nck.programs import program_text
from nckemu.emulator.machine.program.environment import ProgramEnvironment, UndefinedName
from nckemu.emulator.machine.program.motions import (
    ALARM_FEED_ZERO,
    ALARM_NAME_NOT_DEFINED,
    Arc,
    Block,
    CycleCall,
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
from nckemu.emulator.machine.program.planner import (
    EPSILON_MM,
    ArcPath,
    AxisLimits,
    LawArgs,
    MotionLimits,
    Overrides,
    Planner,
    SpindleRamp,
    TimeLaw,
    css_rpm,
    time_law,
)
from nckemu.errors import NckError, NckNoSuchFile, NckPiBadArguments

if TYPE_CHECKING:
    from nckemu.catalogue.table import VariableSpec
    from nckemu.emulator.machine.nck.channel import Channel, Spindle
    from nckemu.emulator.machine.nck.parts import NckParts

# Where a called subprogram is looked for after the caller's own directory (programs.md 7).
SEARCH_DIRECTORIES = ("/_N_SPF_DIR", "/_N_CUS_DIR", "/_N_CMA_DIR", "/_N_CST_DIR", "/_N_MPF_DIR")
TURN_STOPPED, TURN_CW, TURN_CCW = 0, 1, 2
_DIRECTIONS = {"M3": TURN_CW, "M4": TURN_CCW, "M5": TURN_STOPPED}
# Machine data ($MN_ NCK, $MC_ channel, $MA_ axis) and setting data ($SN_, $SC_, $SA_) a program
# reads by their catalogue name; writing machine data is the control's "data write-protected".
DATA_PREFIXES = frozenset({"$MN_", "$MC_", "$MA_", "$SN_", "$SC_", "$SA_"})
ALARM_WRITE_PROTECTED = 17070  # UNCONFIRMED number ("data write-protected")
# The NCK's date and time ($A_YEAR ... $A_MSECOND), local time of the emulator's clock.
CLOCK_VARIABLES = frozenset({"$A_YEAR", "$A_MONTH", "$A_DAY", "$A_HOUR", "$A_MINUTE", "$A_SECOND",
                             "$A_MSECOND"})
# The part counters a program reads and writes: system variable -> the channel state's field.
PART_COUNTERS = {"$AC_ACTUAL_PARTS": "actual_parts", "$AC_TOTAL_PARTS": "total_parts",
                 "$AC_REQUIRED_PARTS": "required_parts", "$AC_SPECIAL_PARTS": "specified_parts"}


def _clock_value(key: str, now_s: float) -> int:
    moment = datetime.fromtimestamp(now_s) if now_s > 1.0e8 else datetime.now()
    if key == "$A_MSECOND":
        return moment.microsecond // 1000
    return int(getattr(moment, key[3:].lower()))


def channel_axes(parts: NckParts) -> dict[str, int]:
    """The channel's axis names (X, Y, Z, A, ...: the machine axis names without trailing digits,
    as MD20080 by default) and the machine axis names (X1), each to its machine axis number; spindles
    are no path axes."""
    names: dict[str, int] = {}
    for axis in sorted(parts.machine.axes, key=lambda axis: axis.number):
        if axis.spindle:
            continue
        names.setdefault(channel_axis_name(axis.name).upper(), axis.number)
        names.setdefault(axis.name.upper(), axis.number)
    return names


def path_axis_names(parts: NckParts, axes: dict[str, int] | None = None) -> list[str]:
    """The names a program moves the channel's axes by (and the block table's columns): the channel
    axis names (X), or the machine axis names when no axis has a shorter one."""
    axes = channel_axes(parts) if axes is None else axes
    short = [name for name, number in axes.items()
             if parts.machine.axis(number) is not None and name != parts.machine.axis(number).name.upper()]
    return short or list(axes)


def motion_limits(parts: NckParts) -> MotionLimits:
    """MD32000 / MD32300 of every path axis (the active values) and the spindle's limits."""
    store = parts.store
    axes: dict[str, AxisLimits] = {}
    for name, number in channel_axes(parts).items():
        axes[name] = AxisLimits(float(store.active_value("MAX_AX_VELO", number)),
                                float(store.active_value("MAX_AX_ACCEL", number)))
    spindle_max = 1.0e9
    for axis in parts.machine.axes:
        if axis.spindle:
            spindle_max = min(spindle_max, float(store.active_value("SPIND_VELO_LIMIT", axis.number)))
    return MotionLimits(axes, parts.machine.program.spindle_accel_rev_s2,
                        spindle_max if spindle_max < 1.0e9 else 1.0e6)


@dataclass
class BlockRecord:
    """One executed block as a block table shows it (``program run --blocks``)."""

    start_s: float
    program: str
    line: int
    number: str
    text: str
    depth: int
    end_s: float = 0.0
    positions_mm: dict[str, float] = field(default_factory=dict)
    feed_mm_min: float = 0.0
    spindle_rpm: float = 0.0
    m_codes: list[int] = field(default_factory=list)
    alarm: str = ""
    note: str = ""                # a standard cycle's word: "CYCLE62 not simulated", CYCLE832's tolerance


@dataclass(slots=True)
class _Motion:
    """The segment the channel runs: positions at an instant come from its time law and its geometry."""

    start_s: float
    end_s: float
    # (machine axis number, position at the start, target) of every axis the block moves
    axes: list[tuple[int, float, float]]
    feed_mm_min: float
    # share of the path behind at a time since start_s (None: linear in time; a tuple: its arguments)
    law: TimeLaw | LawArgs | None = None
    arc: ArcPath | None = None     # a circle or helix (by channel axis name); None: a straight line


class NckEnvironment(ProgramEnvironment):
    """The interpreter's view of the NCK: the channel's axes, the NCK's R parameters and state."""

    def __init__(self, channel: Channel, parts: NckParts, run: ProgramRun) -> None:
        self._channel = channel
        self._parts = parts
        self._run = run
        self._axes = channel_axes(parts)
        super().__init__(axes=path_axis_names(parts, self._axes), r_parameters=self._r_spec_lines())

    def _r_spec_lines(self) -> int:
        spec = self._parts.store.spec("R")
        return spec.lines - self._parts.machine.settings.r_parameter_line_offset + 1

    def _r_line(self, index: int) -> int:
        line = index + self._parts.machine.settings.r_parameter_line_offset
        spec = self._parts.store.spec("R")
        if not 1 <= line <= spec.lines or index < 0:
            raise UndefinedName(f"R{index}")
        return line

    def r_parameter(self, index: int) -> float:
        spec = self._parts.store.spec("R")
        return float(self._parts.store.read_lines(spec, self._channel.number, self._r_line(index), 1)[0])

    def set_r_parameter(self, index: int, value: float) -> None:
        spec = self._parts.store.spec("R")
        self._parts.store.write_lines(spec, self._channel.number, self._r_line(index), [float(value)])

    def machine_position_mm(self, axis: str) -> float:
        number = self._axes.get(axis.upper())
        if number is None:
            raise UndefinedName(axis)
        return self._parts.axes.positions_mm[number]

    def work_offset_mm(self, frame: str, axis: str) -> float:
        from nckemu.emulator.machine.machine_file import SETTABLE_FRAMES

        number = self._axes.get(axis.upper())
        index = SETTABLE_FRAMES.get(frame.upper())
        frames = self._parts.frames
        if number is None or index is None or index >= frames.count:
            return 0.0
        return frames.shifts_mm[self._channel.number][index].get(number, 0.0)

    def set_work_offset_mm(self, frame: str, axis: str, value_mm: float) -> None:
        from nckemu.emulator.machine.machine_file import SETTABLE_FRAMES

        number = self._axes.get(axis.upper())
        index = SETTABLE_FRAMES.get(frame.upper())
        frames = self._parts.frames
        if number is None or index is None or index >= frames.count:
            raise UndefinedName(frame)
        frames.shifts_mm[self._channel.number][index][number] = float(value_mm)

    def select_settable_frame(self, frame: str) -> None:
        from nckemu.emulator.machine.machine_file import SETTABLE_FRAMES

        index = SETTABLE_FRAMES.get(frame.upper())
        if index is not None and index < self._parts.frames.count:
            self._parts.frames.select(self._channel.number, index)

    def set_programmable_frame(self, frame: object) -> None:
        from nckemu.emulator.machine.nck.frame_math import Frame

        if isinstance(frame, Frame):
            self._parts.frames.set_programmable(self._channel.number, frame)

    def tool_length_mm(self, tool: int | str | None, edge: int | None) -> float:
        number = self._tool_number(tool)
        if not number or not edge:
            return 0.0
        try:
            return self._parts.tools.active_length_mm(number, edge, 1)
        except NckError:
            return 0.0

    def tool_radius_mm(self, tool: int | str | None, edge: int | None) -> float:
        number = self._tool_number(tool)
        if not number or not edge:
            return 0.0
        try:
            return self._parts.tools.active_radius_mm(number, edge)
        except NckError:
            return 0.0

    def _tool_number(self, tool: int | str | None) -> int:
        if isinstance(tool, int):
            return tool
        if isinstance(tool, str):
            for number, ident in self._parts.tools.idents.items():
                if ident.upper() == tool.upper():
                    return number
        return 0

    def system_variable(self, name: str, indices: tuple[object, ...] = ()) -> object:
        key = name.upper()
        state = self._channel.state
        if key == "$AC_TIME":  # time since the start of the block (s)
            return max(0.0, self._run.t_s - self._run.block_start_s)
        if key in ("$AA_IM", "$AA_MM") and len(indices) == 1 and str(indices[0]).upper() in self._axes:
            # the actual machine position, with the compensation ($P_EP, $AA_IW: the interpreter's own)
            return self._parts.actual_position_mm(self._axes[str(indices[0]).upper()])
        if key in PART_COUNTERS:
            return self._channel.figure(PART_COUNTERS[key])
        if key == "$AC_PROG":
            return self._channel.ac_prog
        if key == "$P_TOOLNO":
            return state.t_number
        if key == "$P_TOOL":
            return state.d_number
        if key[:4] in DATA_PREFIXES:
            spec, unit, line = self._data_address(key, indices)
            return self._parts.store.active_value(spec.name, unit, line)
        if key in CLOCK_VARIABLES:
            return _clock_value(key, self._parts.clock.now_s())
        if key in nck_io.READABLE:
            return self._parts.nck_io.read(key, self._io_index(key, indices))
        raise UndefinedName(name)

    def _io_index(self, key: str, indices: tuple[object, ...]) -> int:
        if len(indices) != 1 or not isinstance(indices[0], int | float):
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{key}[n]: one number as the index")
        return int(indices[0])

    def set_system_variable(self, name: str, indices: tuple[object, ...], value: object) -> None:
        key = name.upper()
        if key[:4] in DATA_PREFIXES:
            spec, unit, line = self._data_address(key, indices)
            if key[1] == "M":  # machine data: set up by the machine maker, not by a part program
                raise ProgramAlarm(ALARM_WRITE_PROTECTED, f"{name}: machine data {spec.number} is write-protected "
                                                          "for a part program (the machine file sets it)")
            store = self._parts.store
            store.write_lines(spec, unit, line, [store.checked_value(spec, value)])
            return
        if key in nck_io.WRITABLE:
            self._parts.nck_io.write(key, self._io_index(key, indices), float(value))  # type: ignore[arg-type]
            return
        attribute = PART_COUNTERS.get(key)
        if attribute is None:
            raise UndefinedName(name)
        self._channel.set_figure(attribute, float(value))  # type: ignore[arg-type]

    def _data_address(self, key: str, indices: tuple[object, ...]) -> tuple[VariableSpec, int, int]:
        """The catalogue entry, unit and line of ``$MA_MAX_AX_VELO[X]``, ``$MN_..[2]``, ``$SA_..[AX4]``:
        axis data take the axis (its name, AXn, or its number) as the last index, an array its element
        (from 0) first; channel data are this channel's."""
        try:
            spec = self._parts.store.spec(key[4:])
        except KeyError:
            raise UndefinedName(key) from None
        if not spec.number.startswith(f"{key[1]}D"):  # $M.. is machine data (MD), $S.. setting data (SD)
            raise UndefinedName(key)
        area = key[2]
        rest = list(indices)
        if area == "A":
            if not rest:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{key}: axis data need the axis ({key}[X])")
            unit = self._axis_unit(rest.pop())
        else:
            unit = self._channel.number if area == "C" else 1
        line = 1
        if rest:
            element = rest[0]
            if not isinstance(element, int | float) or not 0 <= int(element) < spec.lines:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{key}[{element}]: index outside 0..{spec.lines - 1}")
            line = int(element) + 1
        if (spec.name, unit) not in self._parts.store.active:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{key}: not defined for unit {unit}")
        return spec, unit, line

    def _axis_unit(self, axis: object) -> int:
        if isinstance(axis, int | float):
            return int(axis)
        text = str(axis).upper()
        if text in self._axes:
            return self._axes[text]
        if text.startswith("AX") and text[2:].isdigit():
            return int(text[2:])
        raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"axis {axis} not defined")

    def global_variables(self) -> dict:
        return self._parts.programs.definitions.variables()

    def macros(self) -> dict[str, str]:
        return self._parts.programs.definitions.macros()

    def find_program(self, name: str, caller: str) -> tuple[str, str] | None:
        from nckemu.catalogue.program_names import program_path

        programs = self._parts.programs
        stem = name.strip().upper()
        candidates: list[str] = []
        if "/" in stem or stem.endswith((".SPF", ".MPF")) or stem.startswith("_N_"):
            try:
                candidates.append(program_path(stem, default_type="SPF"))
            except NckPiBadArguments:
                return None
        else:
            if not stem.replace("_", "A").isalnum():
                return None
            caller_dir = caller.rsplit("/", 1)[0] if "/" in caller else ""
            for directory in (caller_dir, *SEARCH_DIRECTORIES):
                if not directory:
                    continue
                for kind in ("SPF", "MPF"):
                    candidates.append(f"{directory}/_N_{stem}_{kind}")
        for path in dict.fromkeys(candidates):
            if programs.exists(path):
                try:
                    return path, program_text(programs.read(path))
                except NckNoSuchFile:
                    continue
        return None


class ProgramRun:
    """The run of one main program on ``channel`` from simulated time ``start_s``."""

    def __init__(self, channel: Channel, parts: NckParts, path: str, text: str, start_s: float) -> None:
        from nckemu.emulator.machine.program.language import Interpreter

        self.channel = channel
        self.parts = parts
        self.path = path
        self.t_s = float(start_s)           # the end of the last finished event
        self.block_start_s = self.t_s
        self.planner = Planner(motion_limits(parts))
        self.axes = channel_axes(parts)
        # What each move needs of an axis, looked up once: (number, travel min, travel max, checked),
        # checked False for a rotary axis (no software limit switches).
        self._travel = {name: (number, parts.axes.specs[number].travel_min_mm,
                               parts.axes.specs[number].travel_max_mm, not parts.axes.specs[number].rotary)
                        for name, number in self.axes.items()}
        self._numbers = sorted(set(self.axes.values()))
        self._wait_for_spindle = parts.machine.program.wait_for_spindle
        self.env = NckEnvironment(channel, parts, self)
        self.interpreter = Interpreter(self.env, path, text)
        self._events: Iterator[Event] = self.interpreter.events()
        self._pending: Event | None = None   # a move held by an override of 0, dispatched again next cycle
        self._motion: _Motion | None = None
        self._paused_at: float | None = None
        self._spindle_ready_s = self.t_s
        self.blocks = 0
        # standard cycles without a motion model: name -> calls (each counted 0 s)
        self.not_simulated: dict[str, int] = {}
        self.record: BlockRecord | None = None
        self.ended = False
        # What the run did other than programmed, said once each (a speed MD35100 held lower).
        self.notes: list[str] = []

    # ------------------------------------------------------------------ time
    def pause(self, now_s: float) -> None:
        if self._paused_at is None:
            self._move_axes(now_s)
            self._paused_at = now_s

    def resume(self, now_s: float) -> None:
        if self._paused_at is None:
            return
        shift = max(0.0, now_s - self._paused_at)
        self._paused_at = None
        self.t_s += shift
        self.block_start_s += shift
        self._spindle_ready_s += shift
        if self._motion is not None:
            self._motion.start_s += shift
            self._motion.end_s += shift

    def close(self, now_s: float) -> None:
        """Reset or end: motion stops where it is, the spindle runs down, the interpreter is closed."""
        if self._paused_at is None:
            self._move_axes(now_s)
        self._motion = None
        self._finish_record(now_s)
        self._drop_programmable_frame()
        close = getattr(self._events, "close", None)
        if close is not None:
            close()
        for spindle in self.channel.state.spindles.values():
            if spindle.ramp is not None or spindle.direction != TURN_STOPPED:
                self._ramp_spindle(spindle, 0.0, now_s)
                spindle.direction = TURN_STOPPED

    def advance(self, until_s: float, max_blocks: int) -> str:
        """Execute up to ``until_s``: 'running', 'waiting' (feed override 0), 'stopped' (M0/M1) or 'ended'."""
        if self._paused_at is not None or self.ended:
            return "ended" if self.ended else "running"
        blocks = 0
        channel = self.channel
        self.parts.axes.catch_up(self._numbers)  # once a cycle, not once a move: the clock stands meanwhile
        while True:
            motion = self._motion
            if motion is not None:
                if motion.end_s > until_s:
                    self._move_axes(until_s, caught_up=True)
                    channel.set_path_feed(motion.feed_mm_min if until_s >= motion.start_s else 0.0)
                    return "running"
                self._arrive(motion)
                self.t_s = motion.end_s
                self._motion = None
                channel.set_path_feed(0.0)
            if blocks >= max_blocks:
                # Blocks take no simulated time of their own: a long computation runs on in the next
                # cycle at the same simulated time (so the time does not depend on the cycle), and the
                # cycle returns, so the faces are served meanwhile.
                return "running"
            event, self._pending = self._pending, None
            if event is None:
                try:
                    event = next(self._events)
                except StopIteration:
                    return self._end()
            kind = event.__class__  # the events are final (slotted) classes: a type, not isinstance
            if kind is Block:
                blocks += 1
                self.blocks += 1
                self._begin_block(event)
            elif kind is Move or kind is Arc:
                if not self._start_path(event, until_s):
                    return "waiting"
            elif kind is Dwell:
                timed = self.planner.dwell(event, self._spindle_rpm(self.t_s))
                self._motion = _Motion(self.t_s, self.t_s + timed.duration_s, [], 0.0)
            elif isinstance(event, SpindleCommand):
                self._spindle(event)
            elif isinstance(event, MFunction):
                if self.record is not None:
                    self.record.m_codes.append(event.code)
                if event.code == 0 or (event.code == 1 and self.parts.machine.program.optional_stop):
                    return "stopped"
            elif isinstance(event, ToolSelect):
                self._tool(event)
            elif kind is CycleCall:
                self._cycle(event)  # type: ignore[arg-type]
            elif isinstance(event, Message):
                channel.show_message(event.text)
            elif isinstance(event, ProgramEnd):
                if self.record is not None and event.code and event.code not in self.record.m_codes:
                    self.record.m_codes.append(event.code)
                return self._end()

    def _cycle(self, call: CycleCall) -> None:
        if not call.simulated:
            self.not_simulated[call.name] = self.not_simulated.get(call.name, 0) + 1
        if self.record is not None and call.note:
            self.record.note = f"{self.record.note}; {call.note}" if self.record.note else call.note

    def _drop_programmable_frame(self) -> None:
        """Reset and program end delete the programmable frame (MD20110 RESET_MODE as delivered,
        UNCONFIRMED); the settable frame stays selected."""
        from nckemu.emulator.machine.nck.frame_math import IDENTITY_FRAME

        self.parts.frames.set_programmable(self.channel.number, IDENTITY_FRAME)

    # ------------------------------------------------------------------ events
    def _end(self) -> str:
        self.ended = True
        self._drop_programmable_frame()
        self._finish_record(self.t_s)
        return "ended"

    def _begin_block(self, block: Block) -> None:
        self._finish_record(self.t_s)
        self.block_start_s = self.t_s
        self.channel.show_block(block)
        if self.channel.block_listeners:
            self.record = BlockRecord(self.t_s, block.program, block.line, block.number, block.text, block.depth)

    def _finish_record(self, end_s: float) -> None:
        record, self.record = self.record, None
        if record is None:
            return
        record.end_s = end_s
        record.positions_mm = {name: self.parts.axes.positions_mm[number] for name, number in self.axes.items()
                               if name in self.env.axes}
        record.spindle_rpm = self._spindle_rpm(end_s)
        for listener in self.channel.block_listeners:
            listener(record)

    def _overrides(self) -> Overrides:
        state = self.channel.state
        spindle = state.spindles.get(1)
        return Overrides(state.feed_override_pct, state.rapid_override_pct,
                         spindle.override_pct if spindle is not None else 100.0)

    def _start_path(self, event: Move | Arc, until_s: float) -> bool:
        state = self.channel.state
        feed = event.feed
        feed_move = feed is not None
        if (state.feed_override_pct <= 0.0 if feed_move else state.rapid_override_pct <= 0.0):
            # override 0: the block waits (time passes) until the override opens again
            self._pending = event
            self.t_s = max(self.t_s, until_s)
            return False
        start_s = self.t_s
        if feed_move and self._wait_for_spindle:
            start_s = max(start_s, self._spindle_ready_s)
        positions, axes = self.parts.axes.positions_mm, self.axes
        targets = event.target_mm
        if not axes.keys() >= targets.keys():  # names as the interpreter wrote them: ours are upper case
            targets = {self._axis_name(axis): value for axis, value in targets.items()}
        moving, deltas = self._check_travel(targets, positions)
        arc = law = None
        if event.__class__ is Move and event.css is None and not event.thread:
            # the common case: the planner's straight move on the deltas, no records built
            spindle_rpm = self._spindle_rpm(start_s) if event.feed_mode == "G95" else 0.0
            duration_s, feed_mm_min, _, law = self.planner.straight(
                deltas, feed, event.feed_mode, event.exact_stop, state.feed_override_pct,
                state.rapid_override_pct, spindle_rpm, event.fgroup)
        else:
            spindle_rpm = self._spindle_rpm(start_s)
            start_mm = {name: positions[number] for name, number in axes.items()}
            if event.__class__ is Move:
                if targets is not event.target_mm:
                    event = replace(event, target_mm=targets)
                timed = self.planner.move(start_mm, event, self._overrides(), spindle_rpm)
            else:
                centre = event.centre_mm
                if targets is not event.target_mm or not all(axis in axes for axis in centre):
                    centre = {self._axis_name(axis): value for axis, value in centre.items()}
                    event = replace(event, target_mm=targets, centre_mm=centre)
                timed = self.planner.arc(start_mm, event, self._overrides(), spindle_rpm)
                arc = timed.arc
                if arc is not None:  # both plane axes turn, named in the block or not
                    moving += [(axes[name], positions[axes[name]], positions[axes[name]])
                               for name in (arc.first, arc.second) if name not in targets and name in axes]
            duration_s, feed_mm_min, law = timed.duration_s, timed.feed_mm_min, timed.law
            if event.css is not None and timed.law is not None:
                if not self._spindle_rpm(start_s):  # G96 feeds per revolution: a standing spindle feeds nothing
                    duration_s = math.inf
                else:
                    self._follow_cutting_speed(event, start_s, start_s + duration_s)
        if duration_s == math.inf:
            raise ProgramAlarm(ALARM_FEED_ZERO, "programmed path velocity is zero (F0, or G95 with the "
                                                "spindle standing)", program=state.program,
                               line=state.line_number, block=state.block_number)
        self._motion = _Motion(start_s, start_s + duration_s, moving, feed_mm_min, law, arc)
        if self.record is not None:
            self.record.feed_mm_min = feed or 0.0
        self.channel.set_commanded_feed(feed if feed_move else 0.0)
        return True

    def _axis_name(self, axis: str) -> str:
        name = axis.upper()
        if name not in self.axes:
            raise ProgramAlarm(12550, f"axis {axis} is not an axis of this channel", program=self.channel.state.program,
                               line=self.channel.state.line_number, block=self.channel.state.block_number)
        return name

    def _check_travel(self, targets: dict[str, float], positions: dict[int, float]
                      ) -> tuple[list[tuple[int, float, float]], list[tuple[str, float]]]:
        """(number, start, target) of every axis ``targets`` names and (name, target - start) of those that
        move, after the software limit switches: a target beyond an axis' travel is the NCK's alarm before
        anything moves. One pass: the channel calls this for every block."""
        travel = self._travel
        moving = []
        deltas = []
        for name, value in targets.items():
            number, low_mm, high_mm, checked = travel[name]
            if checked and not low_mm <= value <= high_mm:
                spec = self.parts.axes.specs[number]
                state = self.channel.state
                raise ProgramAlarm(self.parts.machine.program.travel_alarm,
                                   f"axis {spec.name}: {value:.3f} mm beyond its travel {spec.travel_min_mm:g}.."
                                   f"{spec.travel_max_mm:g} mm (software limit switch; travel_mm of axis "
                                   f"{spec.name} in the machine file moves it)",
                                   program=state.program, line=state.line_number, block=state.block_number)
            start = positions[number]
            moving.append((number, start, value))
            delta = value - start
            if delta > EPSILON_MM or delta < -EPSILON_MM:
                deltas.append((name, delta))
        return moving, deltas

    def _move_axes(self, t_s: float, caught_up: bool = False) -> None:
        motion = self._motion
        if motion is None or not motion.axes:
            return
        if t_s <= motion.start_s:
            return
        if not caught_up:
            self.parts.axes.catch_up(self._numbers)
        span = motion.end_s - motion.start_s
        if span <= 0 or t_s >= motion.end_s:
            self._arrive(motion)
            return
        law = motion.law
        if law is None:
            fraction = (t_s - motion.start_s) / span
        else:
            if law.__class__ is tuple:
                law = motion.law = time_law(law)
            fraction = law.fraction(t_s - motion.start_s)  # type: ignore[union-attr]
        positions = self.parts.axes.positions_mm
        if motion.arc is not None:
            axes = self.axes
            for name, value in motion.arc.position(fraction).items():
                number = axes.get(name)
                if number is not None:
                    positions[number] = value
            return
        for number, start, target in motion.axes:
            positions[number] = start + (target - start) * fraction

    def _arrive(self, motion: _Motion) -> None:
        """Every axis of ``motion`` at its target (checked against the travel when the motion began;
        the compensation caught up when this cycle began: :meth:`advance`)."""
        positions = self.parts.axes.positions_mm
        for number, _, target in motion.axes:
            positions[number] = target

    def _spindle_rpm(self, t_s: float) -> float:
        spindle = self.channel.state.spindles.get(1)
        if spindle is None:
            return 0.0
        if spindle.ramp is not None:
            return spindle.ramp.rpm_at(t_s)
        return 0.0 if spindle.direction == TURN_STOPPED else spindle.commanded_rpm * spindle.override_pct / 100.0

    def _follow_cutting_speed(self, event: Move | Arc, start_s: float, end_s: float) -> None:
        """G96: the spindle's speed goes from the speed at the block's start radius to the one at its end
        (linear in time: what the faces show meanwhile; the block's time integrates the true law)."""
        css = event.css
        assert css is not None
        spindle = self.channel.state.spindles.get(css.spindle)
        if spindle is None:
            return
        axis = self.axes.get(css.axis)
        if axis is None:
            return
        limit = self.planner.limits.spindle_max_rpm
        begin_rpm = css_rpm(css, self.parts.axes.positions_mm[axis], limit)
        end_rpm = css_rpm(css, event.target_mm.get(css.axis, self.parts.axes.positions_mm[axis]), limit)
        spindle.commanded_rpm = end_rpm
        if spindle.direction != TURN_STOPPED:
            scale = spindle.override_pct / 100.0
            spindle.ramp = SpindleRamp(begin_rpm * scale, min(end_rpm * scale, limit), start_s, end_s)

    def _spindle(self, command: SpindleCommand) -> None:
        spindle = self.channel.state.spindles.get(command.spindle)
        if spindle is None:
            return  # a machine without that spindle: S and M3 are taken and change nothing
        if command.css is not None:
            axis = self.axes.get(command.css.axis)
            position = self.parts.axes.positions_mm[axis] if axis is not None else 0.0
            spindle.commanded_rpm = css_rpm(command.css, position, self.planner.limits.spindle_max_rpm)
        elif command.speed_rpm is not None:
            limit = self.planner.limits.spindle_max_rpm
            spindle.commanded_rpm = min(abs(command.speed_rpm), limit)
            if abs(command.speed_rpm) > limit:
                where = f" in {self.record.number or f'line {self.record.line}'}" if self.record is not None else ""
                note = (f"S{abs(command.speed_rpm):g}{where} held at {limit:g} rpm by MD35100 SPIND_VELO_LIMIT "
                        f"of spindle {command.spindle}")
                if note not in self.notes:
                    self.notes.append(note)
        if command.direction is not None:
            spindle.direction = _DIRECTIONS[command.direction]
        target = 0.0 if spindle.direction == TURN_STOPPED else \
            self.planner.spindle_target_rpm(spindle.commanded_rpm, self._overrides())
        self._spindle_ready_s = max(self._spindle_ready_s, self._ramp_spindle(spindle, target, self.t_s))

    def _ramp_spindle(self, spindle: Spindle, target_rpm: float, t_s: float) -> float:
        current = spindle.ramp.rpm_at(t_s) if spindle.ramp is not None else 0.0
        end_s = t_s + self.planner.spindle_ramp_s(current, target_rpm)
        spindle.ramp = SpindleRamp(current, target_rpm, t_s, end_s)
        return end_s

    def _tool(self, event: ToolSelect) -> None:
        number = ident = None
        if event.tool is not None:
            number = self.env._tool_number(event.tool)
            ident = self.parts.tools.idents.get(number, str(event.tool) if isinstance(event.tool, str) else "")
        self.channel.set_tool(number, ident or "", event.edge)


