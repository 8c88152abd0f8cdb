"""Temperature sensors: a machine file's fixed value or profile over time, or a value a test set."""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Callable

from nckemu.emulator.machine.clock import Clock
from nckemu.emulator.machine.machine_file import Machine, Sensor
from nckemu.errors import NckObjectDoesNotExist


def profile_value_C(points: tuple[tuple[float, float], ...], times_s: list[float], t_s: float) -> float:
    """The profile at ``t_s``: linear between points (whose times rise strictly), end values held."""
    index = bisect_left(times_s, t_s)
    if index == 0:
        return points[0][1]
    if index == len(points):
        return points[-1][1]
    (t0, c0), (t1, c1) = points[index - 1], points[index]
    return c0 + (c1 - c0) * (t_s - t0) / (t1 - t0)


class Sensors:
    def __init__(self, machine: Machine, clock: Clock) -> None:
        self.machine = machine
        self.clock = clock
        self._override_C: dict[str, float] = {}
        # What a running program's heat adds to each sensor (emulator/machine/heat.py), K.
        self.heat_C: dict[str, float] = {}
        self._times_s = {sensor.name: [t_s for t_s, _c in sensor.profile] for sensor in machine.sensors}

    def _sensor(self, name: str) -> Sensor:
        for sensor in self.machine.sensors:
            if sensor.name == name:
                return sensor
        raise NckObjectDoesNotExist(f"no sensor {name!r}")

    def temperature_C(self, name: str) -> float:
        return self.temperature_reader(name)()

    def temperature_reader(self, name: str) -> Callable[[], float]:
        """A function of no arguments giving what ``temperature_C(name)`` gives at the time of the
        call, with the sensor looked up once (a polled sensor word reads it on every job)."""
        sensor = self._sensor(name)
        overrides, heat = self._override_C, self.heat_C
        if not sensor.profile:
            fixed_C = sensor.temperature_C

            def fixed() -> float:
                override_C = overrides.get(name)
                return fixed_C + heat.get(name, 0.0) if override_C is None else override_C

            return fixed
        points, times_s, now_s = sensor.profile, self._times_s[name], self.clock.now_s

        def over_time() -> float:
            override_C = overrides.get(name)
            return profile_value_C(points, times_s, now_s()) + heat.get(name, 0.0) if override_C is None \
                else override_C

        return over_time

    def set_temperature(self, name: str, temperature_C: float) -> None:
        self._sensor(name)
        self._override_C[name] = temperature_C
