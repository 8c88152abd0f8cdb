"""The channel's axes as a program moves them: the names a program uses (channel and machine axis
names), the motion limits the planner plans with, the travel a target must stay within, and where the
axes are at an instant of the segment under way.

:class:`ChannelGeometry` is the axis side of a program run (program_run.py's :class:`ProgramRun`
consumes the interpreter's events and hands the motions here); it reads the state the channel shows
only to name the block in an alarm.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from typing import TYPE_CHECKING

from nckemu.emulator.machine.nck.geometric_axes import channel_axis_name
from nckemu.emulator.machine.program.motions import ProgramAlarm
from nckemu.emulator.machine.program.planner import (
    EPSILON_MM,
    ArcPath,
    AxisLimits,
    LawArgs,
    MotionLimits,
    TimeLaw,
    time_law,
)

if TYPE_CHECKING:
    from nckemu.emulator.machine.nck.channel import ChannelState
    from nckemu.emulator.machine.nck.parts import NckParts

ALARM_NOT_AN_AXIS = 12550  # an axis name the channel does not have


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


@dataclass(slots=True)
class PathMotion:
    """The segment the channel runs: positions at an instant come from its time law and its geometry."""

    start_s: float
    end_s: float
    # (machine axis number, position at the start, target) of every axis the block moves
    axes: list[tuple[int, float, float]]
    feed_mm_min: float
    # share of the path behind at a time since start_s (None: linear in time; a tuple: its arguments)
    law: TimeLaw | LawArgs | None = None
    arc: ArcPath | None = None     # a circle or helix (by channel axis name); None: a straight line


class ChannelGeometry:
    """The channel's path axes on the machine: their names, their travel, and their positions along
    the segment under way (written into the NCK's axis positions, which every face reads)."""

    def __init__(self, parts: NckParts, shown: ChannelState) -> None:
        self.axes = channel_axes(parts)
        self._parts_axes = parts.axes
        self._shown = shown   # the block the channel shows, named in an alarm
        self._travel_alarm = parts.machine.program.travel_alarm
        specs = parts.axes.specs
        # What each move needs of an axis, looked up once: (number, travel min, travel max, checked),
        # checked False for a rotary axis (no software limit switches).
        self._travel = {name: (number, specs[number].travel_min_mm, specs[number].travel_max_mm,
                               not specs[number].rotary)
                        for name, number in self.axes.items()}
        self.numbers = sorted(set(self.axes.values()))

    def catch_up(self) -> None:
        """The compensation of the channel's axes brought up to now (once a cycle, not once a move)."""
        self._parts_axes.catch_up(self.numbers)

    def positions_by_name(self, names: Collection[str]) -> dict[str, float]:
        """The machine positions of the channel's axes among ``names`` (a block table's row)."""
        positions = self._parts_axes.positions_mm
        return {name: positions[number] for name, number in self.axes.items() if name in names}

    def axis_name(self, axis: str) -> str:
        name = axis.upper()
        if name not in self.axes:
            shown = self._shown
            raise ProgramAlarm(ALARM_NOT_AN_AXIS, f"axis {axis} is not an axis of this channel", program=shown.program,
                               line=shown.line_number, block=shown.block_number)
        return name

    def check_travel(self, targets: dict[str, float], positions: dict[int, float]
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
                spec = self._parts_axes.specs[number]
                shown = self._shown
                raise ProgramAlarm(self._travel_alarm,
                                   f"axis {spec.name}: {value:.3f} mm beyond its travel {spec.travel_min_mm:g}.."
                                   f"{spec.travel_max_mm:g} mm (software limit switch; travel_mm of axis "
                                   f"{spec.name} in the machine file moves it)",
                                   program=shown.program, line=shown.line_number, block=shown.block_number)
            start = positions[number]
            moving.append((number, start, value))
            delta = value - start
            if delta > EPSILON_MM or delta < -EPSILON_MM:
                deltas.append((name, delta))
        return moving, deltas

    def move(self, motion: PathMotion | None, t_s: float, caught_up: bool = False) -> None:
        """The axes of ``motion`` where its time law puts them at ``t_s`` (at the target once it ends)."""
        if motion is None or not motion.axes:
            return
        if t_s <= motion.start_s:
            return
        if not caught_up:
            self._parts_axes.catch_up(self.numbers)
        span = motion.end_s - motion.start_s
        if span <= 0 or t_s >= motion.end_s:
            self.arrive(motion)
            return
        law = motion.law
        if law is None:
            fraction = (t_s - motion.start_s) / span
        else:
            if law.__class__ is tuple:
                law = motion.law = time_law(law)
            fraction = law.fraction(t_s - motion.start_s)  # type: ignore[union-attr]
        positions = self._parts_axes.positions_mm
        if motion.arc is not None:
            axes = self.axes
            for name, value in motion.arc.position(fraction).items():
                number = axes.get(name)
                if number is not None:
                    positions[number] = value
            return
        for number, start, target in motion.axes:
            positions[number] = start + (target - start) * fraction

    def arrive(self, motion: PathMotion) -> None:
        """Every axis of ``motion`` at its target (checked against the travel when the motion began;
        the compensation caught up when this cycle began: ProgramRun.advance)."""
        self.arrive_axes(motion.axes)

    def arrive_axes(self, axes: list[tuple[int, float, float]]) -> None:
        """Every axis of a motion's (number, start, target) list at its target (as :meth:`arrive`)."""
        positions = self._parts_axes.positions_mm
        for number, _, target in axes:
            positions[number] = target
