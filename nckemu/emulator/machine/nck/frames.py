"""Work offsets: the settable frames (G500, G54..G57, ...) of each channel and the active one.

The settable frames the NCK stores are translations. A running program's whole frame (settable
frame and programmable frame with rotation, scale and mirror: :class:`~.frame_math.Frame`) is handed to the
channel's :class:`Frames` so that the work positions every face reads follow it. Modules FU (settable frames, 0x12) and
FA (active frames, 0x13) address one axis of one frame in column 1, linShift: line = frame index *
numMachAxes + axis (A2 for the 802D sl; IOT's 828D read FU column 1, lines 4..6 = frame 1 of three
axes). The active frames of FA are indexed 0 ACTFRAME (resulting), 1 IFRAME (settable), 2 PFRAME
(programmable), 3 EXTFRAME (external), 4 TOTFRAME (= ACTFRAME + EXTFRAME), 5 ACTBFRAME (basic frames),
6..12 system frames (A2). IFRAME carries the settable frame's translation, PFRAME the translation a
running program has programmed (TRANS, ATRANS, CYCLE800's), ACTFRAME and TOTFRAME their sum; the
others are zero (their rotations and scales have no linShift row).
"""

from __future__ import annotations

from collections.abc import Callable

from nckemu.emulator.machine.frame_math import GEOMETRY, IDENTITY_FRAME, Frame
from nckemu.emulator.machine.machine_file import Machine
from nckemu.errors import NckAddressOutOfRange

ACTFRAME, IFRAME, PFRAME, EXTFRAME, TOTFRAME = 0, 1, 2, 3, 4
MAX_ACTIVE_FRAME_INDEX = 12   # "the max. frame index is 12" (A2)
_CARRY_SETTABLE = (ACTFRAME, IFRAME, TOTFRAME)


class Frames:
    """Settable frames of each channel; channel 1 starts with the machine file's work offsets."""

    def __init__(self, machine: Machine, channels: int) -> None:
        # Channel axes in order of their machine axis number: every machine axis is in channel 1
        # (as for the channel axis names, MD20080).
        self.axis_numbers = [axis.number for axis in sorted(machine.axes, key=lambda axis: axis.number)]
        offsets = machine.work_offsets
        self.count = offsets.count
        self.shifts_mm: dict[int, list[dict[int, float]]] = {
            channel: [dict(offsets.shifts_mm.get(index, {})) if channel == 1 else {} for index in range(self.count)]
            for channel in range(1, channels + 1)}
        self.active = {channel: offsets.active if channel == 1 else 0 for channel in range(1, channels + 1)}
        # The frames a running program has programmed on the settable frame (TRANS, ROT, SCALE,
        # MIRROR and the cycles' frames): the work positions every face reads take them off too.
        self.programmable: dict[int, Frame] = {}
        self._names = {axis.number: axis.name.rstrip("0123456789").upper() or axis.name.upper()
                       for axis in machine.axes if not axis.spindle}
        self._geometry: dict[str, int] = {}
        for axis in sorted(machine.axes, key=lambda axis: axis.number):
            name = self._names.get(axis.number)
            if name in GEOMETRY and name not in self._geometry:
                self._geometry[name] = axis.number

    def _frame_and_axis(self, line: int, frames: int) -> tuple[int, int]:
        """The frame index and machine axis number of a linShift line."""
        axes = len(self.axis_numbers)
        if axes == 0:
            raise NckAddressOutOfRange("the channel has no axes")
        frame, axis_index = divmod(line - 1, axes)
        if frame >= frames:
            raise NckAddressOutOfRange(f"line {line} is frame {frame}; there are frames 0..{frames - 1}")
        return frame, self.axis_numbers[axis_index]

    def settable_shift_mm(self, channel: int, line: int) -> float:
        frame, axis = self._frame_and_axis(line, self.count)
        return self.shifts_mm[channel][frame].get(axis, 0.0)

    def set_settable_shift(self, channel: int, line: int, value_mm: float) -> None:
        frame, axis = self._frame_and_axis(line, self.count)
        self.shifts_mm[channel][frame][axis] = value_mm

    def active_shift_mm(self, channel: int, axis: int) -> float:
        """The translation the active settable frame gives machine axis ``axis``."""
        return self.shifts_mm[channel][self.active[channel]].get(axis, 0.0)

    def actual_frame_shift_mm(self, channel: int, line: int) -> float:
        """FA linShift: IFRAME the settable frame's translation, PFRAME the programmed frame's,
        ACTFRAME and TOTFRAME the chain's (the programmed translation turned and scaled by nothing
        below it: the settable frame is a translation)."""
        frame, axis = self._frame_and_axis(line, MAX_ACTIVE_FRAME_INDEX + 1)
        programmed = self.programmable.get(channel)
        name = self._names.get(axis, "")
        own = programmed.translation.get(name, 0.0) if programmed is not None else 0.0
        if frame == PFRAME:
            return own
        if frame == IFRAME:
            return self.active_shift_mm(channel, axis)
        return self.active_shift_mm(channel, axis) + own if frame in _CARRY_SETTABLE else 0.0

    def select(self, channel: int, index: int) -> None:
        """G500 (0), G54 (1) ...: the settable frame that becomes active."""
        if not 0 <= index < self.count:
            raise NckAddressOutOfRange(f"no settable frame {index} (0..{self.count - 1})")
        self.active[channel] = index

    def set_programmable(self, channel: int, frame: Frame) -> None:
        """The frame a program put on the settable frame (identity: none); the work positions follow."""
        if frame == IDENTITY_FRAME:
            self.programmable.pop(channel, None)
        else:
            self.programmable[channel] = frame

    def work_position_mm(self, channel: int, axis: int, machine_mm: Callable[[int], float]) -> float:
        """Machine axis ``axis`` in the work coordinate system: the machine position (``machine_mm`` of
        an axis number) less the active settable frame, then through the programmable frame."""
        frame = self.programmable.get(channel)
        if frame is None:
            return machine_mm(axis) - self.active_shift_mm(channel, axis)
        name = self._names.get(axis, "")
        if frame.rotated and name in self._geometry:
            point = {geometry: machine_mm(number) - self.active_shift_mm(channel, number)
                     for geometry, number in self._geometry.items()}
        else:
            point = {name: machine_mm(axis) - self.active_shift_mm(channel, axis)}
        return frame.inverse_apply(point)[name]

