"""The vocabulary of effects and the model file (TOML): a sum of named terms for one axis.

Every term is ``coefficient × feature(recording)``: the feature carries the physics (a lag filter,
a square of the speed, a sensor difference...), the coefficient its size. ``gain_error`` is the one
exception: it multiplies the sum of all other terms.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import lfilter

from nckemu.errors import NckConfigError
from nckemu.textfile import read_text
from nckemu.thermal.recordings.recording import Recording


@dataclass(frozen=True)
class EffectSpec:
    effect: str
    coefficient: str            # the parameter that scales the feature
    required: tuple[str, ...]   # other parameters the feature needs
    optional: dict[str, Any]    # parameters with a default
    complexity: int             # for resolving equivalent explanations: simpler wins
    description: str


EFFECTS: dict[str, EffectSpec] = {spec.effect: spec for spec in (
    EffectSpec("offset", "value_um", (), {}, 0, "a constant"),
    EffectSpec("time_drift", "um_per_h", (), {}, 1, "a slow drift proportional to time"),
    EffectSpec("temperature", "coeff_um_per_K", ("sensor",), {"t_ref_C": 20.0}, 1,
               "linear in one sensor"),
    EffectSpec("gain_error", "gain", (), {}, 1,
               "the model's shape is right, its scale is not (recorded = gain x model)"),
    EffectSpec("position_dependent_expansion", "slope_um_per_m_per_K", ("sensor",),
               {"t_ref_C": 20.0, "p0_mm": 0.0}, 2, "expansion growing with the distance from P0 (tan beta)"),
    EffectSpec("quadratic_temperature", "coeff_um_per_K2", ("sensor",), {"t_ref_C": 20.0}, 2,
               "curvature in one sensor"),
    EffectSpec("thermal_gradient", "coeff_um_per_K", ("sensors",), {}, 2,
               "bending from the difference of two sensors"),
    EffectSpec("centrifugal_growth", "coeff_um_per_krpm2", (), {}, 2,
               "spindle growth with the square of the speed, without lag"),
    EffectSpec("thermal_lag", "coeff_um_per_K", ("sensor", "tau_s"), {"t_ref_C": 20.0}, 3,
               "the structure follows a sensor through a first-order lag"),
    EffectSpec("heating_cooling_hysteresis", "coeff_um_per_K", ("sensor", "tau_heat_s", "tau_cool_s"),
               {"t_ref_C": 20.0}, 4, "different lags while heating and while cooling"),
    # Two responses of one sensor (more than a lag): beside the sensor's own temperature it spans what
    # its lag spans, and then the lag, the simpler, is named.
    EffectSpec("transient_gradient", "coeff_um_per_K", ("sensor", "tau_s"), {}, 4,
               "bending while heat crosses a structure (skin-core): a sensor minus its own lagged value, "
               "rising with the sensor, then straightening as the structure evens out"),
)}


def first_order_lag(t_s: np.ndarray, signal: np.ndarray, tau_s: float) -> np.ndarray:
    """x' = (u - x)/tau with zero-order hold between samples; starts settled at u[0]."""
    if len(signal) == 0:
        return signal.copy()
    dt = np.diff(t_s)
    if len(dt) and float(dt.max() - dt.min()) <= 1e-9 * abs(float(dt[0])):  # uniform sampling
        alpha = 1.0 - math.exp(-dt[0] / tau_s)
        state = lfilter([alpha], [1.0, alpha - 1.0], signal - signal[0])
        return state + signal[0]
    out = np.empty_like(signal)
    out[0] = signal[0]
    weights = 1.0 - np.exp(-dt / tau_s)
    for k in range(1, len(signal)):
        out[k] = out[k - 1] + weights[k - 1] * (signal[k] - out[k - 1])
    return out


def asymmetric_lag(t_s: np.ndarray, signal: np.ndarray, tau_heat_s: float, tau_cool_s: float) -> np.ndarray:
    """A first-order lag whose time constant depends on whether the structure heats or cools."""
    out = np.empty_like(signal)
    if len(signal) == 0:
        return out
    out[0] = signal[0]
    dt = np.diff(t_s)
    heat = 1.0 - np.exp(-dt / tau_heat_s)
    cool = 1.0 - np.exp(-dt / tau_cool_s)
    previous = float(signal[0])
    for k in range(1, len(signal)):
        target = signal[k]
        previous += (heat[k - 1] if target > previous else cool[k - 1]) * (target - previous)
        out[k] = previous
    return out


@dataclass
class Term:
    effect: str
    parameters: dict[str, Any] = field(default_factory=dict)

    @property
    def spec(self) -> EffectSpec:
        return EFFECTS[self.effect]

    @property
    def coefficient(self) -> float:
        return float(self.parameters.get(self.spec.coefficient, 1.0 if self.effect == "gain_error" else 0.0))

    def with_coefficient(self, value: float) -> Term:
        return Term(self.effect, {**self.parameters, self.spec.coefficient: float(value)})

    def feature(self, recording: Recording, axis: str) -> np.ndarray:
        """What the coefficient multiplies (not defined for gain_error)."""
        p = self.parameters
        t = recording.t_s
        if self.effect == "offset":
            return np.ones_like(t)
        if self.effect == "time_drift":
            return (t - t[0]) / 3600.0
        if self.effect == "centrifugal_growth":
            if recording.spindle_rpm is None:
                raise NckConfigError("centrifugal_growth needs a spindle_rpm column", path=recording.source)
            return (recording.spindle_rpm / 1000.0) ** 2
        if self.effect == "thermal_gradient":
            a, b = p["sensors"]
            return recording.sensor(a) - recording.sensor(b)
        temperature = recording.sensor(p["sensor"]) - float(p.get("t_ref_C", 20.0))
        if self.effect == "temperature":
            return temperature
        if self.effect == "quadratic_temperature":
            return temperature ** 2
        if self.effect == "position_dependent_expansion":
            if axis not in recording.positions_mm:
                raise NckConfigError(f"position_dependent_expansion needs a pos_{axis}_mm column",
                                     path=recording.source)
            return (recording.positions_mm[axis] - float(p.get("p0_mm", 0.0))) / 1000.0 * temperature
        sensor = recording.sensor(p["sensor"])
        t_ref = float(p.get("t_ref_C", 20.0))
        if self.effect == "thermal_lag":
            return first_order_lag(t, sensor, float(p["tau_s"])) - t_ref
        if self.effect == "heating_cooling_hysteresis":
            return asymmetric_lag(t, sensor, float(p["tau_heat_s"]), float(p["tau_cool_s"])) - t_ref
        if self.effect == "transient_gradient":
            # The skin (the sensor) against the core (the sensor through a first-order lag of tau_s): a
            # fast and a slow response of opposite sign, zero once the structure has evened out.
            return sensor - first_order_lag(t, sensor, float(p["tau_s"]))
        raise NckConfigError(f"no feature for effect {self.effect!r}")


@dataclass
class ThermalModel:
    axis: str
    terms: list[Term]
    source: str = "<model>"

    @property
    def gain(self) -> float:
        return math.prod(t.coefficient for t in self.terms if t.effect == "gain_error")

    def additive_terms(self) -> list[Term]:
        return [t for t in self.terms if t.effect != "gain_error"]

    def predict_um(self, recording: Recording) -> np.ndarray:
        total = np.zeros_like(recording.t_s)
        for term in self.additive_terms():
            total = total + term.coefficient * term.feature(recording, self.axis)
        return self.gain * total


def _check_term(table: dict[str, Any], index: int, source: str) -> Term:
    where = f"term[{index}]"
    effect = table.get("effect")
    if effect not in EFFECTS:
        raise NckConfigError(f"unknown effect {effect!r} (known: {', '.join(EFFECTS)})", path=source,
                             field=f"{where}.effect")
    spec = EFFECTS[effect]
    allowed = {"effect", spec.coefficient, *spec.required, *spec.optional}
    for key in table:
        if key not in allowed:
            raise NckConfigError(f"{effect} has no parameter {key!r} (it takes {', '.join(sorted(allowed - {'effect'}))})",
                                 path=source, field=f"{where}.{key}")
    for key in spec.required:
        if key not in table:
            raise NckConfigError(f"{effect} needs {key!r}", path=source, field=f"{where}.{key}")
    if effect == "thermal_gradient" and (not isinstance(table["sensors"], list) or len(table["sensors"]) != 2):
        raise NckConfigError("sensors must name two sensors [a, b]", path=source, field=f"{where}.sensors")
    parameters = {**spec.optional, **{k: v for k, v in table.items() if k != "effect"}}
    for key in ("tau_s", "tau_heat_s", "tau_cool_s"):
        if key in parameters and not (isinstance(parameters[key], int | float) and parameters[key] > 0):
            raise NckConfigError(f"{key} must be a positive number of seconds", path=source, field=f"{where}.{key}")
    return Term(effect, parameters)


def parse_model(text: str, source: str = "<model>") -> ThermalModel:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise NckConfigError(f"not valid TOML: {exc}", path=source) from None
    axis = data.get("axis")
    if not isinstance(axis, str) or not axis:
        raise NckConfigError("the model needs axis = \"<name>\"", path=source, field="axis")
    terms = [_check_term(t, i, source) for i, t in enumerate(data.get("term", []))]
    return ThermalModel(axis, terms, source)


def load_model(path: str | Path) -> ThermalModel:
    return parse_model(read_text(path, "a model is TOML text"), str(path))


def _toml_value(value: Any) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, float):
        return repr(round(value, 10))
    return str(value)


def render_model(model: ThermalModel, comments: Callable[[Term], str] | None = None) -> str:
    lines = [f'axis = "{model.axis}"']
    for term in model.terms:
        lines += ["", "[[term]]"]
        note = comments(term) if comments else ""
        lines.append(f'effect = "{term.effect}"' + (f"  # {note}" if note else ""))
        for key, value in term.parameters.items():
            lines.append(f"{key} = {_toml_value(value)}")
    return "\n".join(lines) + "\n"
