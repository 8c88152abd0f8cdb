"""Temperature sensors: a machine file's fixed value or profile over time, or a value a test set."""

from __future__ import annotations

from nckemu.errors import NckObjectDoesNotExist

from ..clock import Clock
from ..machine import Machine


class Sensors:
    def __init__(self, machine: Machine, clock: Clock) -> None:
        self.machine = machine
        self.clock = clock
        self._override_C: dict[str, float] = {}

    def temperature_C(self, name: str) -> float:
        for sensor in self.machine.sensors:
            if sensor.name == name:
                break
        else:
            raise NckObjectDoesNotExist(f"no sensor {name!r}")
        if name in self._override_C:
            return self._override_C[name]
        if not sensor.profile:
            return sensor.temperature_C
        t_s = self.clock.now_s()
        points = sensor.profile
        if t_s <= points[0][0]:
            return points[0][1]
        for (t0, c0), (t1, c1) in zip(points, points[1:], strict=False):
            if t_s <= t1:
                return c0 + (c1 - c0) * (t_s - t0) / (t1 - t0)
        return points[-1][1]

    def set_temperature(self, name: str, temperature_C: float) -> None:
        self.temperature_C(name)
        self._override_C[name] = temperature_C
