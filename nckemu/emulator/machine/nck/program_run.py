"""One run of a part program on a channel: the interpreter's events, one at a time, finished in
simulated time by the planner.

:class:`ProgramRun` asks the interpreter for the next event only when the last one has finished in
simulated time (a move has arrived, a dwell has passed), so the interpreter's reads (``$AA_IM``,
``$AC_TIME``, R parameters) see the machine as the block sees it on a control. :meth:`ProgramRun.advance`
runs up to a simulated time and at most a number of blocks, so an endless loop never holds the cycle.
It is the event consumer of three parts: :class:`~nckemu.emulator.machine.nck.nck_environment.NckEnvironment`
answers what the interpreter may ask of the NCK (R parameters, positions, work offsets, tool lengths,
system variables, subprograms), :class:`~nckemu.emulator.machine.nck.run_geometry.ChannelGeometry`
moves the channel's axes along the planner's segments. What the channel reports (the block, the
message, the feed, the tool) the run tells the channel, which alone writes its state.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace
from typing import TYPE_CHECKING

from nckemu.emulator.machine.nck.nck_environment import NckEnvironment  # noqa: F401 (also imported from here)
from nckemu.emulator.machine.nck.run_geometry import (  # noqa: F401 (also imported from here)
    ChannelGeometry,
    PathMotion,
    channel_axes,
    motion_limits,
    path_axis_names,
)
from nckemu.emulator.machine.program.block_record import BlockRecord
from nckemu.emulator.machine.program.motions import (
    ALARM_FEED_ZERO,
    Arc,
    AxesWait,
    Block,
    CycleCall,
    Dwell,
    Event,
    Message,
    MFunction,
    Move,
    Positioning,
    ProgramAlarm,
    ProgramEnd,
    SpindleCommand,
    ToolSelect,
)
from nckemu.emulator.machine.program.planner import (
    S_PER_MIN,
    ArcPath,
    Overrides,
    Planner,
    SpindleRamp,
    css_rpm,
    ramp_time_s,
)

if TYPE_CHECKING:
    from nckemu.emulator.machine.nck.channel import Channel, Spindle
    from nckemu.emulator.machine.nck.parts import NckParts

TURN_STOPPED, TURN_CW, TURN_CCW = 0, 1, 2
_DIRECTIONS = {"M3": TURN_CW, "M4": TURN_CCW, "M5": TURN_STOPPED}


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
        self.geometry = ChannelGeometry(parts, channel.state)
        self.axes = self.geometry.axes
        self._wait_for_spindle = parts.machine.program.wait_for_spindle
        self.env = NckEnvironment(channel, parts, lambda: self.t_s - self.block_start_s, lambda: self.t_s)
        self.interpreter = Interpreter(self.env, path, text)
        self._events: Iterator[Event] = self.interpreter.events()
        self._pending: Event | None = None   # a move held by an override of 0, dispatched again next cycle
        self._motion: PathMotion | None = None
        # positioning axes under way (POS, POSA), by machine axis number: each its own motion beside the path
        self._positioning: dict[int, PathMotion] = {}
        self._paused_at: float | None = None
        self._spindle_ready_s = self.t_s
        self.blocks = 0
        # standard cycles without a motion model: name -> calls (each counted 0 s)
        self.not_simulated: dict[str, int] = {}
        self.record: BlockRecord | None = None
        self.ended = False
        # What the run did other than programmed, said once each (a speed MD35100 held lower).
        self.notes: list[str] = []

    def programs_in_use(self) -> frozenset[str]:
        """The main program and the subprograms called and not returned from (not to be replaced)."""
        return self.interpreter.programs_in_use()

    # ------------------------------------------------------------------ time
    def pause(self, now_s: float) -> None:
        if self._paused_at is None:
            self._move_axes(now_s)
            self._paused_at = now_s

    def _move_axes(self, now_s: float) -> None:
        """The path's and the positioning axes' motions where they are at ``now_s`` (pause, reset)."""
        for motion in (self._motion, *self._positioning.values()):
            self.geometry.move(motion, now_s)

    def resume(self, now_s: float) -> None:
        if self._paused_at is None:
            return
        shift = max(0.0, now_s - self._paused_at)
        self._paused_at = None
        self.t_s += shift
        self.block_start_s += shift
        self._spindle_ready_s += shift
        for motion in (self._motion, *self._positioning.values()):
            if motion is not None:
                motion.start_s += shift
                motion.end_s += shift

    def close(self, now_s: float) -> None:
        """Reset or end: motion stops where it is, the spindle runs down, the interpreter is closed."""
        if self._paused_at is None:
            self._move_axes(now_s)
        self._motion = None
        self._positioning.clear()
        self._finish_record(now_s)
        self._drop_programmable_frame()
        close = getattr(self._events, "close", None)
        if close is not None:
            close()
        for line, spindle in self.channel.state.spindles.items():
            if spindle.ramp is not None or spindle.direction != TURN_STOPPED:
                self._ramp_spindle(line, spindle, 0.0, now_s)
                self.channel.command_spindle(line, direction=TURN_STOPPED)

    def advance(self, until_s: float, max_blocks: int) -> str:
        """Execute up to ``until_s``: 'running', 'waiting' (feed override 0), 'stopped' (M0/M1) or 'ended'."""
        if self._paused_at is not None or self.ended:
            return "ended" if self.ended else "running"
        blocks = 0
        channel = self.channel
        self.geometry.catch_up()  # once a cycle, not once a move: the clock stands meanwhile
        if self._positioning:
            self._move_positioning(until_s)
        while True:
            motion = self._motion
            if motion is not None:
                if motion.end_s > until_s:
                    self.geometry.move(motion, until_s, caught_up=True)
                    channel.set_path_feed(motion.feed_mm_min if until_s >= motion.start_s else 0.0)
                    return "running"
                self.geometry.arrive(motion)
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
                self._motion = PathMotion(self.t_s, self.t_s + timed.duration_s, [], 0.0)
            elif isinstance(event, SpindleCommand):
                self._spindle(event)
            elif isinstance(event, MFunction):
                if self.record is not None:
                    self.record.m_codes.append(event.code)
                self.parts.nck_io.m_function(event.code, self.t_s)  # the PLC's answers (machine file)
                if event.code == 0 or (event.code == 1 and self.parts.machine.program.optional_stop):
                    return "stopped"
            elif isinstance(event, ToolSelect):
                self._tool(event)
            elif kind is CycleCall:
                self._cycle(event)  # type: ignore[arg-type]
            elif isinstance(event, Message):
                channel.show_message(event.text)
            elif kind is Positioning:
                self._start_positioning(event)  # type: ignore[arg-type]
            elif kind is AxesWait:
                self._hold_for_axes(event, {self.axes[self.geometry.axis_name(axis)]  # type: ignore[attr-defined]
                                            for axis in event.axes} or None)  # type: ignore[attr-defined]
            elif isinstance(event, ProgramEnd):
                if self._positioning and self._hold_for_axes(event, None):
                    continue  # the program ends when its positioning axes have arrived
                if self.record is not None and event.code and event.code not in self.record.m_codes:
                    self.record.m_codes.append(event.code)
                return self._end()

    # ------------------------------------------------------------------ positioning axes
    def _start_positioning(self, event: Positioning) -> None:
        """POS/POSA: the axis starts for its end point on its own trapezoid at FA (or MD32060), within
        its MD32000/MD32300; an axis still under way from an earlier POSA is waited for first."""
        name = self.geometry.axis_name(event.axis)
        number = self.axes[name]
        if self._hold_for_axes(event, {number}):
            return
        moving, deltas = self.geometry.check_travel({name: event.target_mm}, self.parts.axes.positions_mm)
        if not deltas:
            return
        length_mm = abs(deltas[0][1])
        limits = self.planner.limits.axis(name)
        feed_mm_min = event.feed_mm_min
        if feed_mm_min is None:
            feed_mm_min = float(self.parts.store.active_value("POS_AX_VELO", number))
        feed_mm_min = min(feed_mm_min, limits.max_velocity_mm_min)
        if feed_mm_min <= 0.0:
            state = self.channel.state
            raise ProgramAlarm(ALARM_FEED_ZERO, f"positioning axis {name} without a velocity (FA and MD32060 "
                               "are 0)", program=state.program, line=state.line_number, block=state.block_number)
        speed_mm_s, accel_mm_s2 = feed_mm_min / S_PER_MIN, limits.accel_mm_s2
        duration_s = ramp_time_s(length_mm, speed_mm_s, accel_mm_s2, 2)
        self._positioning[number] = PathMotion(self.t_s, self.t_s + duration_s, moving, feed_mm_min,
                                               (length_mm, speed_mm_s, accel_mm_s2, True, True))

    def _hold_for_axes(self, event: Event, numbers: set[int] | None) -> bool:
        """True when ``event`` must wait for positioning axes (``numbers``; None: all) still under way: the
        run waits until the last arrives and then takes ``event`` again. False when none is moving now
        (those arrived are put at their end points)."""
        end_s = max((motion.end_s for number, motion in self._positioning.items()
                     if numbers is None or number in numbers), default=-math.inf)
        if end_s > self.t_s:
            self._pending = event
            self._motion = PathMotion(self.t_s, end_s, [], 0.0)
            return True
        self._move_positioning(self.t_s)
        return False

    def _move_positioning(self, t_s: float) -> None:
        """The positioning axes where their motions put them at ``t_s``; those arrived are done."""
        for number, motion in list(self._positioning.items()):
            self.geometry.move(motion, t_s, caught_up=True)
            if motion.end_s <= t_s:
                del self._positioning[number]

    def _cycle(self, call: CycleCall) -> None:
        if not call.simulated:
            self.not_simulated[call.name] = self.not_simulated.get(call.name, 0) + 1
        if self.record is not None and call.note:
            self.record.add_note(call.note)

    def _note_arc_middle(self, arc: ArcPath) -> None:
        """A block table's row shows where a block ends; for a circle or helix its note adds the point
        half-way along it, so that a table of rows says which way round the path went."""
        assert self.record is not None
        middle = arc.position(0.5)
        order = {name: index for index, name in enumerate(self.axes)}
        words = " ".join(f"{name}{middle[name]:.4f}" for name in sorted(middle, key=lambda n: order.get(n, len(order))))
        note = f"through {words} at its middle"
        self.record.add_note(note)

    def _drop_programmable_frame(self) -> None:
        """Reset and program end delete the programmable frame (MD20110 RESET_MODE as delivered,
        UNCONFIRMED); the settable frame stays selected."""
        from nckemu.emulator.machine.frame_math import IDENTITY_FRAME

        self.parts.frames.set_programmable(self.channel.number, IDENTITY_FRAME)

    # ------------------------------------------------------------------ events
    def _end(self) -> str:
        self.ended = True
        self._drop_programmable_frame()
        self._finish_record(self.t_s)
        return "ended"

    def _begin_block(self, block: Block) -> None:
        if self.record is not None:
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
        record.positions_mm = self.geometry.positions_by_name(self.env.axes)
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
        if feed_move and self._wait_for_spindle and self._spindle_ready_s > start_s:
            start_s = self._spindle_ready_s
        positions, axes = self.parts.axes.positions_mm, self.axes
        targets = event.target_mm
        if not axes.keys() >= targets.keys():  # names as the interpreter wrote them: ours are upper case
            targets = {self.geometry.axis_name(axis): value for axis, value in targets.items()}
        if self._positioning and self._hold_for_axes(event, {axes[name] for name in targets}):
            return True  # an axis of the block still runs as a positioning axis (POSA): the block waits
        moving, deltas = self.geometry.check_travel(targets, positions)
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
                    centre = {self.geometry.axis_name(axis): value for axis, value in centre.items()}
                    event = replace(event, target_mm=targets, centre_mm=centre)
                timed = self.planner.arc(start_mm, event, self._overrides(), spindle_rpm)
                arc = timed.arc
                if arc is not None and self.record is not None:
                    self._note_arc_middle(arc)
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
        end_s = start_s + duration_s
        if self.record is not None:
            self.record.feed_mm_min = feed or 0.0
        self.channel.set_commanded_feed(feed if feed_move else 0.0)
        if end_s <= until_s:
            # It ends within this cycle (most blocks of a CAM program): the axes arrive now, as the next
            # turn of advance's loop would have them, without a segment made and dropped.
            self.geometry.arrive_axes(moving)
            self.t_s = end_s
            self.channel.set_path_feed(0.0)
        else:
            self._motion = PathMotion(start_s, end_s, moving, feed_mm_min, law, arc)
        return True

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
        self.channel.command_spindle(css.spindle, rpm=end_rpm)
        if spindle.direction != TURN_STOPPED:
            scale = spindle.override_pct / 100.0
            self.channel.ramp_spindle(css.spindle, SpindleRamp(begin_rpm * scale, min(end_rpm * scale, limit),
                                                               start_s, end_s))

    def _spindle(self, command: SpindleCommand) -> None:
        spindle = self.channel.state.spindles.get(command.spindle)
        if spindle is None:
            return  # a machine without that spindle: S and M3 are taken and change nothing
        if command.css is not None:
            axis = self.axes.get(command.css.axis)
            position = self.parts.axes.positions_mm[axis] if axis is not None else 0.0
            self.channel.command_spindle(command.spindle,
                                         rpm=css_rpm(command.css, position, self.planner.limits.spindle_max_rpm))
        elif command.speed_rpm is not None:
            limit = self.planner.limits.spindle_max_rpm
            self.channel.command_spindle(command.spindle, rpm=min(abs(command.speed_rpm), limit))
            if abs(command.speed_rpm) > limit:
                where = f" in {self.record.number or f'line {self.record.line}'}" if self.record is not None else ""
                note = (f"S{abs(command.speed_rpm):g}{where} held at {limit:g} rpm by MD35100 SPIND_VELO_LIMIT "
                        f"of spindle {command.spindle}")
                if note not in self.notes:
                    self.notes.append(note)
        if command.direction is not None:
            self.channel.command_spindle(command.spindle, direction=_DIRECTIONS[command.direction])
        target = 0.0 if spindle.direction == TURN_STOPPED else \
            self.planner.spindle_target_rpm(spindle.commanded_rpm, self._overrides())
        self._spindle_ready_s = max(self._spindle_ready_s,
                                    self._ramp_spindle(command.spindle, spindle, target, self.t_s))

    def _ramp_spindle(self, line: int, spindle: Spindle, target_rpm: float, t_s: float) -> float:
        current = spindle.ramp.rpm_at(t_s) if spindle.ramp is not None else 0.0
        end_s = t_s + self.planner.spindle_ramp_s(current, target_rpm)
        self.channel.ramp_spindle(line, SpindleRamp(current, target_rpm, t_s, end_s))
        return end_s

    def _tool(self, event: ToolSelect) -> None:
        number = ident = None
        if event.tool is not None:
            number = self.env.tool_number(event.tool)
            ident = self.parts.tools.idents.get(number, str(event.tool) if isinstance(event.tool, str) else "")
        self.channel.set_tool(number, ident or "", event.edge)


