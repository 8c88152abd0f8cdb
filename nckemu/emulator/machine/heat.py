"""The heat a running program makes: each sensor answers the spindle's speed and the axes' motion.

A sensor with a fitted response (``[[sensor.response]]``, written by `nckemu machine fit`; the terms
and their math are nckemu/heat_response.py, shared with the fit) rises by the sum of its terms: the
spindle's speed to a power (or running at all), the path speed, another sensor (the room, a
neighbour), each through its own lag. A sensor without one keeps the first-order response of the
older keys (``heat_time_constant_s``) towards a rise of ``heat_spindle_K_per_krpm`` per 1000 rpm of the
spindle plus ``heat_axes_K_per_m_min`` per m/min of path speed, on top of its fixed value or profile
(assumed defaults, docs/programs.md). A recorded input a term names (a coolant switch) reads 0 here:
a program drives only the spindle and the axes. Only what a
program drives heats: a recording's spindle speed or a test's values do not (a recording brings its
own temperatures). The inputs are taken at each cycle and held over it, so the rise is exact for
inputs that change at cycle boundaries and within a cycle's sampling otherwise.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from nckemu.emulator.machine.machine_file import Machine
from nckemu.heat_response import PATH, SPINDLE, ResponseState

if TYPE_CHECKING:
    from nckemu.emulator.machine.nck.model import NckModel

M_PER_MM = 0.001


class Heat:
    def __init__(self, machine: Machine, nck: NckModel) -> None:
        self.machine = machine
        self.nck = nck
        self._last_s: float | None = None
        self._inputs = (0.0, 0.0)   # spindle rpm and path speed in m/min over the last cycle
        # The fitted responses' lag states, by sensor; their rise is what they add to the sensor.
        self._responses = {sensor.name: ResponseState(sensor.response) for sensor in machine.sensors
                           if sensor.response}
        self._reads_sensors = any(state.reads_sensors for state in self._responses.values())
        self._plain_sensors = [sensor for sensor in machine.sensors if sensor.name not in self._responses]

    def inputs(self) -> tuple[float, float]:
        """The program-driven spindle speed (rpm) and path speed (m/min) now."""
        spindle_rpm = 0.0
        path_m_min = 0.0
        for channel in self.nck.channels.values():
            for line, spindle in channel.state.spindles.items():
                if spindle.ramp is not None and spindle.measured_rpm is None:
                    spindle_rpm += abs(channel.spindle_speed_rpm(line))
            if channel.run is not None:
                path_m_min += channel.state.path_feed_mm_min * M_PER_MM
        return spindle_rpm, path_m_min

    @property
    def warm(self) -> bool:
        """Whether any sensor still carries heat of a program (it decays in the cycle)."""
        return any(abs(value) > 1e-6 for value in self.nck.sensors.heat_C.values())

    def thermal_error_um(self, axis: int) -> float:
        """The error the heat makes on machine axis ``axis`` now (its thermal_um_per_K)."""
        spec = self.machine.axis(axis)
        if spec is None:
            return 0.0
        heat = self.nck.sensors.heat_C
        return sum(k * heat.get(name, 0.0) for name, k in spec.thermal_um_per_K.items())

    def measured_error_um(self, axis: int) -> float:
        """What a gauge reads on ``axis``: the heat's error less what the compensation moves the axis by."""
        sign = self.machine.settings.compensation_sign
        return self.thermal_error_um(axis) + sign * self.nck.compensation_mm(axis) * 1000.0

    def step(self, t_s: float) -> None:
        last, self._last_s = self._last_s, t_s
        if last is None or t_s <= last:
            self._inputs = self.inputs()
            return
        dt_s = t_s - last
        spindle_rpm, path_m_min = self._inputs
        heat = self.nck.sensors.heat_C
        if self._responses:
            drives = {SPINDLE: spindle_rpm, PATH: path_m_min}
            # the sensors' temperatures only where a term reads another sensor (a reading costs)
            now_C = {sensor.name: self.nck.sensor_temperature_C(sensor.name) for sensor in self.machine.sensors} \
                if self._reads_sensors else {}
            for name, state in self._responses.items():
                state.step(dt_s, drives, now_C)
                heat[name] = state.rise_K
        for sensor in self._plain_sensors:
            target_K = sensor.heat_spindle_K_per_krpm * spindle_rpm / 1000.0 + sensor.heat_axes_K_per_m_min * path_m_min
            now_K = heat.get(sensor.name, 0.0)
            if target_K == 0.0 and now_K == 0.0:
                continue
            decay = math.exp(-dt_s / sensor.heat_time_constant_s)
            heat[sensor.name] = target_K + (now_K - target_K) * decay
        self._inputs = self.inputs()
