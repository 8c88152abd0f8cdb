"""Machine axes: commanded positions, travel limits and whether an axis is referenced."""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable

from nckemu.emulator.machine.machine_file import Axis, Machine
from nckemu.errors import NckItemError, NckObjectDoesNotExist

_AXIS_REF = re.compile(r"^AX(\d+)$", re.IGNORECASE)


class Axes:
    """Positions as commanded; ``before_change(axis)`` lets the compensation catch up first."""

    def __init__(self, machine: Machine, before_change: Callable[[int], None]) -> None:
        self.machine = machine
        self._before_change = before_change
        self.specs: dict[int, Axis] = {axis.number: axis for axis in machine.axes}
        self.positions_mm = {axis.number: axis.position_mm for axis in machine.axes}
        self.referenced = {axis.number: axis.referenced for axis in machine.axes}
        self._on_unreferenced: list[Callable[[int], None]] = []

    def check(self, axis: int) -> None:
        if axis not in self.positions_mm:
            raise NckObjectDoesNotExist(f"machine axis {axis} does not exist")

    def on_unreferenced(self, callback: Callable[[int], None]) -> None:
        self._on_unreferenced.append(callback)

    def set_position(self, axis: int, position_mm: float) -> None:
        self.check(axis)
        spec = self.specs[axis]
        if not spec.rotary and not spec.travel_min_mm <= position_mm <= spec.travel_max_mm:
            raise NckItemError(f"axis {spec.name}: {position_mm} mm outside its travel "
                               f"{spec.travel_min_mm}..{spec.travel_max_mm}",
                               return_code=self.machine.settings.limit_violation_return_code)
        self._before_change(axis)
        self.positions_mm[axis] = position_mm

    def catch_up(self, axes: Iterable[int]) -> None:
        """Let the compensation catch up on ``axes`` now; until the clock moves on, a caller that has
        checked positions against the travel may then write ``positions_mm`` directly (a program run
        moves its axes many times within one cycle of the machine)."""
        for axis in axes:
            self._before_change(axis)

    def position_mm(self, axis: int) -> float:
        self.check(axis)
        return self.positions_mm[axis]

    def set_referenced(self, axis: int, referenced: bool) -> None:
        self.check(axis)
        self._before_change(axis)
        self.referenced[axis] = referenced
        if not referenced:
            for callback in self._on_unreferenced:
                callback(axis)

    def number(self, reference: str) -> int | None:
        """``AX4`` or a machine axis name to the axis number (None if there is no such axis)."""
        match = _AXIS_REF.match(reference)
        if match:
            number = int(match.group(1))
            return number if number in self.positions_mm else None
        for axis in self.machine.axes:
            if axis.name.upper() == reference.upper():
                return axis.number
        return None
