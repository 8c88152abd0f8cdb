"""Runs a standard cycle call inside the interpreter: the steps of :mod:`.cycles` become the
interpreter's own moves (through frames, tool length and units), dwells and spindle commands; a
pattern (HOLES1, HOLES2, CYCLE801) goes to each position at rapid and runs the modal cycle there;
CYCLE800 positions the rotary axes and sets the swivel frame; CYCLE832 records its tolerance.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any, Protocol

from nckemu.emulator.machine.frame_math import IDENTITY_FRAME, Frame, rotation_rpy

from ..motions import (
    ALARM_NAME_NOT_DEFINED,
    CycleCall,
    Dwell,
    Event,
    MFunction,
    ProgramAlarm,
    SpindleCommand,
)
from . import cycles
from .expressions import Names, evaluate, number

if TYPE_CHECKING:
    from .modal import ModalState
    from .motion_builder import MotionBuilder

log = logging.getLogger(__name__)
_PLANES = {"G17": ("X", "Y", "Z"), "G18": ("Z", "X", "Y"), "G19": ("Y", "Z", "X")}


class CycleHost(Protocol):
    """What the cycles read and set of the interpreter (the Interpreter is it): named here, so that this
    module does not import the interpreter that imports it."""

    path: str
    modal: ModalState
    feed_mm: float
    work_pos: dict[str, float]
    spindle_speed: dict[int, float]
    names: Names          # the cycle's parameters are expressions
    paths: MotionBuilder  # the motion job: a cycle's steps become the interpreter's own moves

    @property
    def modal_call(self) -> Any: ...

    def set_swivel_frame(self, frame: Frame) -> None: ...


def is_standard_cycle(name: str) -> bool:
    return name in cycles.KNOWN or cycles.is_shop_step(name)


class CycleRunner:
    """The standard cycles of one interpreter (what CYCLE832 and CYCLE800 set is kept here)."""

    def __init__(self, interpreter: CycleHost) -> None:
        self.interpreter = interpreter  # the Interpreter that owns this runner
        self.tolerance_mm: float | None = None

    def call(self, name: str, args: list | None) -> list[Event]:
        """The events of ``name(args)`` at the tool's position (the caller found no program of that name)."""
        if name in cycles.DRILLING:
            values = self._numbers(name, args)
            return [CycleCall(name), *self._run(cycles.drilling(name, values, self._context()))]
        if name in cycles.PATTERNS:
            return [CycleCall(name), *self._pattern(name, self._numbers(name, args))]
        if name == cycles.SWIVEL:
            return [CycleCall(name), *self._swivel(self._lenient(args))]
        if name == "CYCLE832":
            values = self._lenient(args)
            tolerance = float(values[0]) if values and isinstance(values[0], int | float) else 0.0
            self.tolerance_mm = tolerance
            if tolerance > 0:  # the cycle switches on continuous-path mode G642 with that tolerance
                self.interpreter.modal.exact_stop = False
            return [CycleCall(name, note=f"CYCLE832 tolerance {tolerance:g} mm")]
        if name in cycles.MOTIONLESS:
            return [CycleCall(name)]
        log.info("%s: %s is a standard cycle the emulator does not simulate (0 s counted)",
                 self.interpreter.path, name)
        return [CycleCall(name, simulated=False, note=f"{name} not simulated")]

    # --- parameters --------------------------------------------------------------------------------
    def _numbers(self, name: str, args: list | None) -> list[float | None]:
        out: list[float | None] = []
        for arg in args or ():
            if arg is None:
                out.append(None)
                continue
            value = evaluate(arg, self.interpreter.names)
            if isinstance(value, str):
                raise ProgramAlarm(cycles.ALARM_CYCLE_PARAMETER, f"{name}: a text where a number belongs")
            out.append(float(number(value)))
        return out

    def _lenient(self, args: list | None) -> list[Any]:
        """Parameters of a cycle that only records them: a name no program defined (CYCLE832's
        _ROUGH, a swivel data set's name) is taken as unset, as we do not run the cycle's own code."""
        out: list[Any] = []
        for arg in args or ():
            try:
                out.append(None if arg is None else evaluate(arg, self.interpreter.names))
            except ProgramAlarm as alarm:
                if alarm.number != ALARM_NAME_NOT_DEFINED:
                    raise
                out.append(None)
        return out

    def _context(self) -> cycles.Context:
        it = self.interpreter
        first, second, infeed = _PLANES[it.modal.plane]
        unit = 25.4 if it.modal.inch_geometry else 1.0
        position = {axis: value / unit for axis, value in it.work_pos.items()}
        # The interpreter keeps no spindle direction (M3/M4 go to the channel as events): the cycles fall
        # back to M3 where a program gives none.
        return cycles.Context(first, second, infeed, position, it.feed_mm, it.spindle_speed.get(1, 0.0), None)

    # --- steps into events -------------------------------------------------------------------------
    def _run(self, steps: list[cycles.Step]) -> list[Event]:
        it = self.interpreter
        events: list[Event] = []
        saved = (it.modal.motion, it.feed_mm)
        try:
            for step in steps:
                kind = step.__class__
                if kind is cycles.Rapid or kind is cycles.Feed:
                    it.modal.motion = 0 if kind is cycles.Rapid else 1
                    if kind is cycles.Feed:
                        it.feed_mm = step.feed_mm_min or saved[1]  # type: ignore[union-attr]
                    words = [(axis, float(value), "AC") for axis, value in step.target.items()  # type: ignore[union-attr]
                             if axis in it.work_pos]
                    if words:
                        events.append(it.paths.motion(words, {}, {}))  # type: ignore[arg-type]
                elif kind is cycles.Wait:
                    events.append(Dwell(step.seconds, step.revolutions))  # type: ignore[union-attr]
                elif kind is cycles.Spindle:
                    events.append(SpindleCommand(1, step.speed_rpm, step.direction))  # type: ignore[union-attr,arg-type]
                else:
                    events.append(MFunction(0))
        finally:
            it.modal.motion, it.feed_mm = saved
        return events

    def _pattern(self, name: str, values: list[float | None]) -> list[Event]:
        it = self.interpreter
        first, second, _ = _PLANES[it.modal.plane]
        modal = it.modal_call
        cycle = None
        if modal is not None:
            cycle = evaluate(modal[0], it.names)
            cycle = cycle.upper() if isinstance(cycle, str) else None
            if cycle not in cycles.DRILLING:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name} with the modal call of {cycle} (a program, not a "
                                                           "drilling cycle) is not supported by the emulator")
        events: list[Event] = []
        for u, v in cycles.pattern(name, values):
            events += self._run([cycles.Rapid({first: u, second: v})])
            if cycle is not None:
                events += self.call(cycle, modal[1])  # type: ignore[index]
        return events

    def _swivel(self, values: list[Any]) -> list[Event]:
        """CYCLE800: the rotary axes (A about X, B about Y, C about Z, where the machine has them) go
        to the angles at rapid (direct mode's angles taken as about X, Y, Z too; no retraction _FR), then the swivel frame (reference point, rotations, zero point after
        the rotation) lies under the programmable frame. Without angles it is deselected."""
        it = self.interpreter
        rotations = cycles.swivel_rotations(values)
        before, after = cycles.swivel_offsets(values)
        moves: dict[str, float] = {}
        # deselection (no angle) leaves the rotary axes where they are, as the cycle does
        for axis, angle in rotations if any(angle for _, angle in rotations) else ():
            rotary = cycles.ROTARY_FOR[axis]
            if rotary in it.work_pos and abs(it.work_pos[rotary] - angle) > 1e-9:
                moves[rotary] = angle
        events = self._run([cycles.Rapid(moves)]) if moves else []
        frame = IDENTITY_FRAME.then_translate({k: v for k, v in before.items() if v})
        for axis, angle in rotations:
            if angle:
                frame = frame.then_rotate(rotation_rpy({axis: angle}))
        frame = frame.then_translate({k: v for k, v in after.items() if v})
        it.set_swivel_frame(frame)
        return events
