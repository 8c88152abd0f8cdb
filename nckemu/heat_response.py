"""A sensor's heat response as a machine file writes it (``[[sensor.response]]``): the one piece of
math the twin (emulator/machine/heat.py) and the heat fit (thermal/heat) share.

A sensor reads its base value (``temperature_C`` or its profile) plus the sum of its terms. Each term
is a steady rise ``K`` per unit of what drives it, reached through a first-order lag ``tau_s``
(0: at once):

- ``spindle_rpm``: the spindle's speed as (rpm/1000)^power (bearing friction is not linear in speed);
  K is in K per krpm^power; power 0: running at any speed (K while it turns);
- ``path_m_min``: the axes' path speed in m/min (K per m/min);
- ``sensor``: another sensor's temperature less ``from_C``, its value at rest (K per K): the room
  through a reference sensor, or heat passed on from a neighbour;
- any other name: a recorded input, e.g. a coolant switch 0/1 (K when on).

The lag holds the input of the new sample over the step before it (``x += (1 - e^(-dt/tau)) (u - x)``),
as ``thermal.model.lags.first_order_lag`` does, so a series simulated step by step here equals the fit's
filtered columns. Nothing here knows the emulator or the recordings: it imports only the error hierarchy.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from nckemu.errors import NckConfigError

SPINDLE = "spindle_rpm"
PATH = "path_m_min"
SENSOR = "sensor"
RUNNING_RPM = 0.5   # below this the spindle stands
TERM_KEYS = frozenset({"input", "K", "tau_s", "power", "sensor", "from_C", "name"})


@dataclass(frozen=True)
class HeatTerm:
    input: str
    K: float
    tau_s: float = 0.0
    power: float = 1.0
    sensor: str = ""
    from_C: float = 0.0
    name: str = ""

    def drive(self, inputs: Mapping[str, float], sensors_C: Mapping[str, float]) -> float:
        """What drives the term now (before its gain and lag)."""
        if self.input == SPINDLE:
            return spindle_drive_value(inputs.get(SPINDLE, 0.0), self.power)
        if self.input == SENSOR:
            return sensors_C.get(self.sensor, self.from_C) - self.from_C
        return inputs.get(self.input, 0.0)

    def drive_series(self, inputs: Mapping[str, np.ndarray], sensors_C: Mapping[str, np.ndarray],
                     count: int) -> np.ndarray:
        if self.input == SPINDLE:
            rpm = inputs.get(SPINDLE)
            return np.zeros(count) if rpm is None else spindle_drive(np.asarray(rpm), self.power)
        if self.input == SENSOR:
            return sensors_C[self.sensor] - self.from_C
        values = inputs.get(self.input)
        return np.zeros(count) if values is None else np.asarray(values, dtype=float)

    def unit(self) -> str:
        if self.input == SPINDLE and self.power == 0:
            return "K while running"
        return {SPINDLE: f"K per krpm^{self.power:g}", PATH: "K per m/min", SENSOR: "K per K"}.get(
            self.input, f"K per unit of {self.input}")

    def words(self) -> str:
        """The term in a line: ``spindle +9.13 K while running, tau 37 min``."""
        lag = f", tau {self.tau_s / 3600:.2f} h" if self.tau_s >= 3600 else \
            f", tau {self.tau_s / 60:.0f} min" if self.tau_s > 0 else ", no lag"
        name = self.name or self.input
        if self.input == SPINDLE:
            law = "while running" if self.power == 0 else f"per krpm^{self.power:.2f}"
            return f"{name} {self.K:+.3g} K {law}{lag}"
        if self.input == SENSOR:
            return f"{name} {self.sensor} {self.K:.3g} K/K{lag}"
        return f"{name} {self.K:+.3g} {self.unit()}{lag}"

    def to_table(self) -> dict[str, Any]:
        table: dict[str, Any] = {"name": self.name, "input": self.input, "K": round(float(self.K), 6),
                                 "tau_s": round(float(self.tau_s), 1)}
        if self.input == SPINDLE:
            table["power"] = round(float(self.power), 3)
        if self.input == SENSOR:
            table["sensor"] = self.sensor
            table["from_C"] = round(float(self.from_C), 4)
        return table


def parse_terms(rows: object, where: str, source: str) -> tuple[HeatTerm, ...]:
    """The ``[[sensor.response]]`` tables of one sensor, checked; NckConfigError naming the field."""
    if not isinstance(rows, list):
        raise NckConfigError("expected [[sensor.response]] tables", path=source, field=f"{where}response")
    terms = []
    for index, row in enumerate(rows):
        at = f"{where}response[{index}]."
        if not isinstance(row, dict):
            raise NckConfigError("expected a table", path=source, field=at.rstrip("."))
        unknown = sorted(set(row) - TERM_KEYS)
        if unknown:
            raise NckConfigError(f"unknown key {unknown[0]!r} (keys: {', '.join(sorted(TERM_KEYS))})",
                                 path=source, field=f"{at}{unknown[0]}")
        name = row.get("input")
        if not isinstance(name, str) or not name:
            raise NckConfigError(f"expected {SPINDLE}, {PATH}, {SENSOR} or a recorded input's name",
                                 path=source, field=f"{at}input")
        numbers = {}
        for key, default in (("K", None), ("tau_s", 0.0), ("power", 1.0), ("from_C", 0.0)):
            value = row.get(key, default)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise NckConfigError("expected a number", path=source, field=f"{at}{key}")
            numbers[key] = float(value)
        if numbers["tau_s"] < 0:
            raise NckConfigError("expected a time constant >= 0 s", path=source, field=f"{at}tau_s")
        if not 0.0 <= numbers["power"] <= 5.0:
            raise NckConfigError("expected a power 0..5 (0: running at any speed)", path=source, field=f"{at}power")
        sensor = row.get("sensor", "")
        if name == SENSOR and (not isinstance(sensor, str) or not sensor):
            raise NckConfigError("expected the name of the sensor that drives this term", path=source,
                                 field=f"{at}sensor")
        label = row.get("name", "")
        if not isinstance(label, str):
            raise NckConfigError("expected a name", path=source, field=f"{at}name")
        terms.append(HeatTerm(name, numbers["K"], numbers["tau_s"], numbers["power"], str(sensor),
                              numbers["from_C"], label))
    return tuple(terms)


def spindle_drive(rpm: np.ndarray, power: float) -> np.ndarray:
    """(|rpm|/1000)^power; power 0: 1 while the spindle turns at all, 0 at standstill."""
    speed = np.abs(rpm)
    if power == 0:
        return (speed > RUNNING_RPM).astype(float)
    return (speed / 1000.0) ** power


def spindle_drive_value(rpm: float, power: float) -> float:
    """:func:`spindle_drive` of one speed, in floats: the twin steps it every cycle, where numpy's
    per-call cost was an eighth of a straight-move program's run (the same C ``pow``, the same value)."""
    speed = abs(float(rpm))
    if power == 0:
        return 1.0 if speed > RUNNING_RPM else 0.0
    return (speed / 1000.0) ** power


def lag_weight(dt_s: float, tau_s: float) -> float:
    """How far a first-order lag moves towards its input over ``dt_s``."""
    return 1.0 if tau_s <= 0 else 1.0 - math.exp(-dt_s / tau_s)


class ResponseState:
    """The lag states of one sensor's terms, stepped once a cycle; ``rise_K`` is what they add."""

    def __init__(self, terms: Sequence[HeatTerm]) -> None:
        self.terms = tuple(terms)
        self.states = [0.0] * len(self.terms)
        self._gains_K = tuple(term.K for term in self.terms)
        # whether a term reads another sensor (else the sensors' temperatures are not needed)
        self.reads_sensors = any(term.input == SENSOR for term in self.terms)
        # the lag weights of the last step's dt (a machine steps at its fixed cycle)
        self._weights_dt_s: float | None = None
        self._weights: list[float] = []

    def settle(self, inputs: Mapping[str, float], sensors_C: Mapping[str, float]) -> None:
        self.states = [term.drive(inputs, sensors_C) for term in self.terms]

    def step(self, dt_s: float, inputs: Mapping[str, float], sensors_C: Mapping[str, float]) -> None:
        if dt_s != self._weights_dt_s:
            self._weights = [lag_weight(dt_s, term.tau_s) for term in self.terms]
            self._weights_dt_s = dt_s
        states, weights = self.states, self._weights
        for index, term in enumerate(self.terms):
            states[index] += weights[index] * (term.drive(inputs, sensors_C) - states[index])

    @property
    def rise_K(self) -> float:
        return sum(map(operator.mul, self._gains_K, self.states))


def simulate(t_s: np.ndarray, inputs: Mapping[str, np.ndarray], base_C: Mapping[str, float],
             responses: Mapping[str, Sequence[HeatTerm]],
             recorded_C: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Every sensor with a response over ``t_s`` as the twin steps it, starting settled on the first
    sample's inputs; a sensor without one reads ``recorded_C`` (the room as recorded) or its base."""
    count = len(t_s)
    recorded_C = recorded_C or {}
    out: dict[str, np.ndarray] = {name: np.asarray(values, dtype=float) for name, values in recorded_C.items()
                                  if name not in responses}
    for name, value in base_C.items():
        if name not in responses and name not in out:
            out[name] = np.full(count, float(value))
    for name in responses:
        out[name] = np.full(count, float(base_C.get(name, 0.0)))
    if count == 0:
        return out
    states = {name: ResponseState(terms) for name, terms in responses.items()}
    now_C = {name: float(values[0]) for name, values in out.items()}
    first = {key: float(values[0]) for key, values in inputs.items()}
    for name, state in states.items():   # in order: a neighbour settles on what its source settled to
        state.settle(first, now_C)
        out[name][0] = base_C.get(name, 0.0) + state.rise_K
        now_C[name] = float(out[name][0])
    for k in range(1, count):
        dt_s = float(t_s[k] - t_s[k - 1])
        at = {key: float(values[k]) for key, values in inputs.items()}
        for name, values in out.items():
            if name not in states:
                now_C[name] = float(values[k])
        for name, state in states.items():
            state.step(dt_s, at, now_C)
            value = base_C.get(name, 0.0) + state.rise_K
            out[name][k] = value
            now_C[name] = value
    return out
