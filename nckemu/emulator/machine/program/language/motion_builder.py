"""The motions of a block: where its axis words go (frames, units, diameter, polar coordinates) and the
canonical event they make (a rapid or feed move, a circle or helix, a thread), with the feed rules of the
modal state (FGROUP, G96) on it.

:class:`MotionBuilder` is the interpreter's motion job, split from it: it reads the interpreter's modal
state, work position, feed and tool length, and writes the work position a block reaches.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Any, Protocol

from nckemu.emulator.machine.frame_math import GEOMETRY, Frame

from ..motions import (
    ALARM_CIRCLE_END_POINT,
    ALARM_FEED_ZERO,
    ALARM_NAME_NOT_DEFINED,
    ALARM_SYNTAX,
    Arc,
    Event,
    Move,
    Positioning,
    ProgramAlarm,
)
from . import framing
from .alarms import VALUE_LIMIT, out_of_range
from .expressions import number
from .feedrules import THREAD_MOTIONS, TRANSVERSE_AXIS

if TYPE_CHECKING:
    from .modal import ModalState


class MotionSource(Protocol):
    """What the motion job reads and keeps of the interpreter (the Interpreter is it): named here, so that
    the job does not import the interpreter that imports it."""

    modal: ModalState
    feed_mm: float
    spindle_speed: dict[int, float]
    tool_length_mm: float
    work_pos: dict[str, float]
    stale_mm: dict[str, float]

    def machine_now(self) -> dict[str, float]: ...

    def is_rotary(self, axis: str) -> bool: ...

    def axis_name(self, value: Any) -> str: ...

INCH_MM = 25.4
# The circle end-point tolerance: MD21000 CIRCLE_ERROR_CONST (mm) and MD21010 CIRCLE_ERROR_FACTOR
# (share of the radius); the larger applies. Defaults as we remember them, UNCONFIRMED.
CIRCLE_ERROR_CONST_MM = 0.01
CIRCLE_ERROR_FACTOR = 0.001

# the axes of each working plane: first, second, infeed
PLANES = {"G17": ("X", "Y", "Z"), "G18": ("Z", "X", "Y"), "G19": ("Y", "Z", "X")}
CENTRE_WORD = {"X": "I", "Y": "J", "Z": "K"}


class MotionBuilder:
    """The motion job of ``it`` (the interpreter, as a :class:`MotionSource`)."""

    def __init__(self, it: MotionSource) -> None:
        self.it = it

    def polar(self, axis_words: list, address: dict, flags: dict) -> list:
        """Polar coordinates (polar.py): a G110/G111/G112 block sets the pole and moves nothing; AP=/RP=
        become the end point of the plane's axes (and a circle's centre is the pole)."""
        modal = self.it.modal
        first, second, _ = PLANES[modal.plane]
        unit = INCH_MM if modal.inch_geometry else 1.0
        wrote_polar = "AP" in address or "RP" in address
        polar = modal.polar.with_words(address, unit)
        code = flags.get("pole")
        if code:
            written = {axis: float(number(raw)) * unit for axis, raw, _ in axis_words if axis in (first, second)}
            position = (self.it.work_pos.get(first, 0.0), self.it.work_pos.get(second, 0.0))
            modal.polar = polar.new_pole(code, written, (first, second), position, wrote_polar)
            return [word for word in axis_words if word[0] not in (first, second)]
        modal.polar = polar
        end_first, end_second = polar.point_mm()
        words = [word for word in axis_words if word[0] not in (first, second)]
        words += [(first, end_first / unit, "AC"), (second, end_second / unit, "AC")]
        if modal.motion in (2, 3) and not any(word in address for word in ("I", "J", "K", "CR")):
            address[CENTRE_WORD[first]] = (polar.pole_mm[0] / unit, "AC")
            address[CENTRE_WORD[second]] = (polar.pole_mm[1] / unit, "AC")
        return words

    def framed_motion(self, axis_words: list, address: dict, flags: dict, chain: Frame) -> Event | list[Event]:
        """A move or circle through a frame that rotates, scales or mirrors: the end point (and centre)
        worked out in the work system, then taken through the frame chain and the tool length."""
        work_pos = self.it.work_pos
        unit_mm = INCH_MM if self.it.modal.inch_geometry else 1.0
        start = dict(work_pos)
        now = self.it.machine_now()
        programmed: dict[str, float] = {}
        for axis, raw, mode in axis_words:
            value = raw if raw.__class__ is float else float(number(raw))
            if not -VALUE_LIMIT <= value <= VALUE_LIMIT:
                raise out_of_range(axis, value)
            unit = unit_mm if not self.it.is_rotary(axis) else 1.0
            incremental = mode == "IC" or (mode is None and not self.it.modal.absolute)
            work = (work_pos[axis] + value * unit) if incremental else value * unit
            programmed[axis] = work / unit
            work_pos[axis] = work
        moving = chain.coupled(set(programmed)) & set(work_pos)
        work_targets = {axis: work_pos[axis] for axis in moving}
        for axis in moving:
            self.it.stale_mm.pop(axis, None)
        tool = {PLANES[self.it.modal.plane][2]: self.it.tool_length_mm} if self.it.tool_length_mm else {}
        exact_stop = self.it.modal.exact_stop or bool(flags.get("g9"))
        if self.it.modal.motion > 1:
            if self.it.feed_mm <= 0:
                raise ProgramAlarm(ALARM_FEED_ZERO, "programmed path velocity less than or equal to zero (no F)")
            saved_shift, self.it.modal.shift = self.it.modal.shift, {}
            try:
                first, second, _ = PLANES[self.it.modal.plane]
                # a circle starts where the tool is: that point in the work system of this frame
                infeed = PLANES[self.it.modal.plane][2]
                if infeed in now:
                    now[infeed] -= self.it.tool_length_mm
                here = chain.inverse_apply({axis: now[axis] for axis in now if axis in GEOMETRY})
                plane_start = {axis: here[axis] for axis in (first, second) if axis in here}
                arc = self.arc(work_targets, programmed, plane_start, address, {}, exact_stop)
            finally:
                self.it.modal.shift = saved_shift
            framed = framing.framed_arc(arc, {**start, **plane_start}, chain, tool)
            if framed.__class__ is list:  # chords of a circle the frame tilts out of the machine's planes
                return [self.with_feed_rules(chord) for chord in framed]  # type: ignore[union-attr]
            return self.with_feed_rules(framed)  # type: ignore[arg-type]
        targets = chain.apply(work_targets)
        for axis, length in tool.items():
            if axis in targets:
                targets[axis] += length
        if self.it.modal.motion == 0:
            return Move(targets, None, self.it.modal.feed_mode, exact_stop, programmed)  # type: ignore[arg-type]
        if self.it.modal.motion in THREAD_MOTIONS:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"G{self.it.modal.motion} in a rotated, scaled or mirrored frame "
                                                       "is not supported by the emulator")
        if self.it.feed_mm <= 0:
            raise ProgramAlarm(ALARM_FEED_ZERO, "programmed path velocity less than or equal to zero (no F)")
        return self.with_feed_rules(Move(targets, self.it.feed_mm, self.it.modal.feed_mode, exact_stop,  # type: ignore[arg-type]
                                          programmed))

    def motion(self, axis_words: list, address: dict, flags: dict) -> Event | list[Event]:
        suppress = bool(flags.get("supa"))
        if self.it.modal.chain is not None and not suppress:
            return self.framed_motion(axis_words, address, flags, self.it.modal.chain)
        shift = self.it.modal.shift
        work_pos = self.it.work_pos
        inch = self.it.modal.inch_geometry
        absolute = self.it.modal.absolute
        targets: dict[str, float] = {}
        programmed: dict[str, float] = {}
        stale = self.it.stale_mm
        if stale:  # axes a frame change left where the old frames put them
            now = self.it.machine_now()
            start_machine = {axis: now[axis] for axis in PLANES[self.it.modal.plane][:2] if axis in now}
            for axis, _, _ in axis_words:
                stale.pop(axis, None)
        else:
            start_machine = {axis: work_pos[axis] + shift.get(axis, 0.0) for axis in PLANES[self.it.modal.plane][:2]
                             if axis in work_pos}
        rules = self.it.modal.feed_rules
        for axis, raw, mode in axis_words:
            value = raw if raw.__class__ is float else float(number(raw))
            if not -VALUE_LIMIT <= value <= VALUE_LIMIT:
                raise out_of_range(axis, value)
            unit = INCH_MM if inch and not self.it.is_rotary(axis) else 1.0
            incremental = mode == "IC" or (mode is None and not absolute)
            value = rules.radius_of(axis, value, incremental)
            offset = shift.get(axis, 0.0)
            if suppress:
                machine = (work_pos[axis] + offset + value * unit) if incremental else value * unit
                work = machine - offset
                programmed[axis] = rules.programmed_of(axis, machine / unit)
            else:
                work = (work_pos[axis] + value * unit) if incremental else value * unit
                machine = work + offset
                programmed[axis] = rules.programmed_of(axis, work / unit)
            work_pos[axis] = work
            targets[axis] = machine
        exact_stop = self.it.modal.exact_stop or bool(flags.get("g9"))
        motion = self.it.modal.motion
        if motion == 0:
            return Move(targets, None, self.it.modal.feed_mode, exact_stop, programmed)  # type: ignore[arg-type]
        if motion in THREAD_MOTIONS:
            return self.thread(targets, programmed, address, exact_stop)
        if self.it.feed_mm <= 0:
            raise ProgramAlarm(ALARM_FEED_ZERO, "programmed path velocity less than or equal to zero (no F)")
        if motion == 1:
            return self.with_feed_rules(Move(targets, self.it.feed_mm, self.it.modal.feed_mode, exact_stop,  # type: ignore[arg-type]
                                              programmed))
        return self.with_feed_rules(self.arc(targets, programmed, start_machine, address, flags, exact_stop))

    def positioning(self, words: list[tuple[str, str, Any, str | None]],
                    settings: dict[tuple[str, str], Any]) -> list[Event]:
        """``POS[U]=..``/``POSA``/``POSP`` as :class:`Positioning` events: each end point in the work system
        like an axis word's (G90/G91, IC/AC, inch), through the work offset and tool length, at the axis'
        FA when the program set one (in the feed's unit), else at its MD32060 (the channel's)."""
        modal, work_pos = self.it.modal, self.it.work_pos
        events: list[Event] = []
        for kind, axis, raw, mode in words:
            if modal.chain is not None and axis in GEOMETRY:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{kind}[{axis}] in a rotated, scaled or mirrored frame "
                                                           "is not supported by the emulator")
            rotary = self.it.is_rotary(axis)
            unit = INCH_MM if modal.inch_geometry and not rotary else 1.0
            value = raw if raw.__class__ is float else float(number(raw))
            if not -VALUE_LIMIT <= value <= VALUE_LIMIT:
                raise out_of_range(f"{kind}[{axis}]", value)
            incremental = mode == "IC" or (mode is None and not modal.absolute)
            work = (work_pos.get(axis, 0.0) + value * unit) if incremental else value * unit
            work_pos[axis] = work
            self.it.stale_mm.pop(axis, None)
            feed = settings.get(("FA", axis))
            feed_mm_min = float(number(feed)) if feed is not None else 0.0
            if modal.inch_feed and not rotary:
                feed_mm_min *= INCH_MM
            events.append(Positioning(axis, work + modal.shift.get(axis, 0.0),
                                      feed_mm_min if feed_mm_min > 0.0 else None, work / unit))
        return events

    def with_feed_rules(self, motion: Move | Arc) -> Move | Arc:
        """The feed group and G96 on a motion at feed (nothing to add in the common case)."""
        rules = self.it.modal.feed_rules
        if rules.fgroup is None and not rules.constant_speed:
            return motion
        return replace(motion, fgroup=rules.fgroup,
                       css=rules.css(self.it.modal.shift.get(TRANSVERSE_AXIS, 0.0)) if motion.feed_mode == "G95" else None)

    def thread(self, targets: dict, programmed: dict, address: dict, exact_stop: bool) -> Move:
        """G33: feed per revolution at the pitch; G331/G332 (tapping): the pitch at the programmed S.
        The feed override does not act on either (Move.thread)."""
        self.it.modal.feed_rules = self.it.modal.feed_rules.with_pitch(address, INCH_MM if self.it.modal.inch_geometry else 1.0)
        pitch = self.it.modal.feed_rules.pitch_mm
        if self.it.modal.motion == 33:
            return Move(targets, pitch, "G95", exact_stop, programmed, thread=True)
        speed = abs(self.it.spindle_speed.get(1, 0.0))
        if speed <= 0.0:
            raise ProgramAlarm(ALARM_FEED_ZERO, f"G{self.it.modal.motion}: tapping without a spindle speed (S)")
        return Move(targets, pitch * speed, "G94", exact_stop, programmed, thread=True)

    def fgroup_axes(self, args: list) -> list[str]:
        """FGROUP's arguments as channel axis names (each written as a bare axis name)."""
        names = []
        for arg in args:
            lvalue = getattr(arg, "lvalue", None)
            if arg is None or lvalue is None or lvalue[0] != "VAR" or lvalue[2]:
                raise ProgramAlarm(ALARM_SYNTAX, "FGROUP takes channel axis names: FGROUP(X, Y, C)")
            names.append(self.it.axis_name(lvalue[1]))
        return names

    def arc(self, targets: dict, programmed: dict, start: dict, address: dict, flags: dict,
             exact_stop: bool) -> Arc:
        if "AR" in address or "AP" in address or "RP" in address:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, "AR/AP/RP circles are not supported by the emulator")
        first, second, _ = PLANES[self.it.modal.plane]
        if first not in start or second not in start:
            raise ProgramAlarm(ALARM_CIRCLE_END_POINT, f"{self.it.modal.plane}: the plane's axes are not in this channel")
        unit = INCH_MM if self.it.modal.inch_geometry else 1.0
        start_first, start_second = start[first], start[second]
        end_first, end_second = targets.get(first, start_first), targets.get(second, start_second)
        clockwise = self.it.modal.motion == 2
        if "CR" in address:
            radius = float(number(address["CR"])) * unit
            centre = _centre_from_radius(start_first, start_second, end_first, end_second, radius, clockwise)
        else:
            first_word = address.get(CENTRE_WORD.get(first, ""))
            second_word = address.get(CENTRE_WORD.get(second, ""))
            if first_word is None and second_word is None:
                raise ProgramAlarm(ALARM_CIRCLE_END_POINT, "circle without centre (I, J, K) or radius (CR=)")
            supa = bool(flags.get("supa"))
            centre = (self.centre(first_word, first, start_first, unit, supa),
                      self.centre(second_word, second, start_second, unit, supa))
            radius_start = math.hypot(start_first - centre[0], start_second - centre[1])
            radius_end = math.hypot(end_first - centre[0], end_second - centre[1])
            tolerance = max(CIRCLE_ERROR_CONST_MM, CIRCLE_ERROR_FACTOR * max(radius_start, radius_end))
            if abs(radius_start - radius_end) > tolerance:
                raise ProgramAlarm(ALARM_CIRCLE_END_POINT,
                                   f"error in end point of circle (radii {radius_start:.4f} and {radius_end:.4f} mm)")
        turns = int(number(address["TURN"])) if "TURN" in address else 0
        if turns < 0:
            raise ProgramAlarm(ALARM_SYNTAX, f"TURN={turns}: the number of full turns is not negative")
        return Arc(targets, {first: centre[0], second: centre[1]}, clockwise, self.it.modal.plane,  # type: ignore[arg-type]
                   self.it.feed_mm, self.it.modal.feed_mode, turns, exact_stop, programmed)  # type: ignore[arg-type]

    def centre(self, word: tuple | None, axis: str, start: float, unit: float, supa: bool) -> float:
        """One centre coordinate (machine mm) from I/J/K: incremental from the start, or =AC(...)."""
        if word is None:
            return start
        value, mode = word
        offset = (value if value.__class__ is float else float(number(value))) * unit
        if mode == "AC":
            return offset + (0.0 if supa else self.it.modal.shift.get(axis, 0.0))
        return start + offset


def _centre_from_radius(start_first: float, start_second: float, end_first: float, end_second: float,
                        radius: float, clockwise: bool) -> tuple[float, float]:
    dx = end_first - start_first
    dy = end_second - start_second
    chord = math.hypot(dx, dy)
    size = abs(radius)
    if chord == 0 or size == 0 or chord > 2 * size + CIRCLE_ERROR_CONST_MM:
        raise ProgramAlarm(ALARM_CIRCLE_END_POINT, f"error in end point of circle (CR={radius:.4f} mm)")
    height = math.sqrt(max(size * size - chord * chord / 4, 0.0))
    # counter-clockwise with the short arc (CR > 0): centre on the left of the chord
    side = 1.0 if (not clockwise) == (radius > 0) else -1.0
    return (start_first + dx / 2 - side * height * dy / chord,
            start_second + dy / 2 + side * height * dx / chord)
