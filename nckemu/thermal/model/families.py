"""The families of effects, one entry each: what a family's terms are, and everything that follows
from it in one place.

An entry owns the family's parameters (the model file's vocabulary), its feature on a recording, the
bounds a machine can have, the simpler families it extends, the column whose one time constant
discovery searches (where a second time constant and a measured partner are searched), how discovery
proposes its candidates,
its place among the detectable sizes (the registry's order) and its form in a PLC program (the name
of one of ``PLC_FORMS``, which ``plcsim/stlgen.py`` writes as STL, or None with the reason). A new
family is one ``register(Family(...))``; ``tests/thermal/discovery/test_families.py`` shows a toy one
reaching the candidates, the detectable sizes and the STL generator.

Candidate generation sees discovery through ``CandidateSource`` (the library of a round), so this
module needs nothing of discovery.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from nckemu.errors import NckConfigError
from nckemu.thermal.recordings.recording import Recording

from .lags import asymmetric_lag, first_order_lag
from .structure import Structure

# The PLC forms plcsim/stlgen.py knows how to write (one emitter each).
PLC_FORMS = ("constant", "linear", "square", "difference", "lag", "asymmetric_lag", "skin_core",
             "position_slope", "speed_square")
# Forms with a filter state that starts settled on the first cycle.
STATEFUL_PLC_FORMS = ("lag", "asymmetric_lag", "skin_core")

TIME_CONSTANT_RANGE_S = (60.0, 48 * 3600.0)


class CandidateSource(Protocol):
    """What a family's candidate generator may ask of the round (discovery's library)."""

    def sensors(self) -> list[str]: ...

    def has_spindle(self) -> bool: ...

    def has_positions(self) -> bool: ...

    def needs_offset(self) -> bool: ...

    def modelled(self, effect: str, sensor: str) -> bool: ...

    def t_ref(self, sensor: str) -> float: ...

    def lag_column(self, sensor: str, tau_s: float) -> np.ndarray: ...

    def transient_column(self, sensor: str, tau_s: float) -> np.ndarray: ...

    def best_time_constant(self, column: Callable[[float], np.ndarray], key: tuple[str, str],
                           away_from: tuple[float, ...] = ()) -> tuple[float, float, int] | None: ...

    def named_time_constants(self, effect: str, sensor: str) -> tuple[float, ...] | None: ...

    def best_searched(self, kind: str, count: int) -> list[str]: ...

    def best_asymmetric_lag(self, sensor: str) -> tuple[float, float, float, int] | None: ...


# Proposed terms: (effect, parameters, values tried to find it: each a hypothesis the selector counts).
Generator = Callable[[CandidateSource, set[str]], Iterable[tuple[str, dict[str, Any], int]]]
Feature = Callable[[Recording, str, dict[str, Any]], np.ndarray]


@dataclass(frozen=True)
class Family:
    effect: str
    coefficient: str                    # the parameter that scales the feature
    required: tuple[str, ...]           # other parameters the feature needs
    optional: dict[str, Any]            # parameters with a default
    complexity: int                     # for resolving equivalent explanations: simpler wins
    description: str
    feature: Feature | None             # what the coefficient multiplies (None: gain_error)
    candidates: Generator | None = None  # how discovery proposes terms of this family
    plc_form: str | None = None
    plc_refusal: str = ""               # why a family without a PLC form has none
    extends: tuple[str, ...] = ()       # simpler families of the same sensor it contains
    time_constants: tuple[str, ...] = ()  # parameters that are time constants (s)
    # The library column ("lag", "transient") whose one time constant discovery searches: the family a
    # second time constant or a measured partner is searched for (issue 42). None: not such a family.
    searched_column: str | None = None
    coefficient_range: tuple[float, float] | None = None
    uses_spindle: bool = False
    uses_position: bool = False
    # Extra checks of a model file's table: (message, field) when it is wrong.
    check: Callable[[dict[str, Any]], tuple[str, str] | None] | None = None
    default_coefficient: float = 0.0
    # Where a round lists this family's candidates: by stage, then by sensor, then in registry order
    # (0: without a sensor; 1: one sensor; 2: sensor pairs; 3..: searched time constants). The order
    # decides only how ties and equivalent explanations are listed.
    stage: int = 1
    # What a machine can have (issue 51, docs/thermal.md): the coefficient's size as a multiple of the
    # structure's expansion over its length (um/K; per metre for a slope), None: no such bound; and
    # whether a room sensor may carry it (the room acts through the structure, never as hysteresis).
    size_in_structures: float | None = None
    per_metre: bool = False
    room_may_carry: bool = True

    def present_key(self, parameters: dict[str, Any]) -> str:
        """What a found term rules out of later rounds: the family, or the family of that sensor (pair)."""
        if "sensor" in self.required or "sensors" in self.required:
            return f"{self.effect}:{parameters.get('sensor') or '-'.join(parameters.get('sensors', []))}"
        return self.effect

    def bounded(self, parameters: dict[str, Any], coefficient: float) -> bool:
        """Parameters a machine can have."""
        low, high = TIME_CONSTANT_RANGE_S
        if self.time_constants:
            return all(low <= float(parameters[key]) <= high for key in self.time_constants)
        if self.coefficient_range is not None:
            return self.coefficient_range[0] <= coefficient <= self.coefficient_range[1]
        return math.isfinite(coefficient)


    def cannot_have(self, parameters: dict[str, Any], coefficient: float, structure: Structure) -> str:
        """Why a machine of ``structure`` cannot have this term ("" when it can)."""
        sensor = parameters.get("sensor")
        if not self.room_may_carry and isinstance(sensor, str) and structure.is_room(sensor):
            return (f"{sensor} is the room: it acts through the structure (a lag), never as {self.effect} of "
                    f"the air")
        if self.size_in_structures is None or not math.isfinite(coefficient):
            return ""
        limit = self.size_in_structures * (structure.expansion_um_per_m_K if self.per_metre else structure.um_per_K)
        if abs(coefficient) <= limit:
            return ""
        unit = "um/(m K)" if self.per_metre else "um/K"
        what = f"a metre of {structure.material.replace('_', ' ')}" if self.per_metre else \
            structure.words().split(" at ")[0]
        return (f"{abs(coefficient):.3g} {unit} is more than {limit:.3g} {unit}, {self.size_in_structures:g} x what "
                f"{what} can expand per kelvin")


_REGISTRY: dict[str, Family] = {}


def register(family: Family) -> Family:
    if family.effect in _REGISTRY:
        raise ValueError(f"family {family.effect!r} is registered already")
    if family.plc_form is not None and family.plc_form not in PLC_FORMS:
        raise ValueError(f"family {family.effect!r}: unknown PLC form {family.plc_form!r} (known: {', '.join(PLC_FORMS)})")
    _REGISTRY[family.effect] = family
    return family


def unregister(effect: str) -> None:
    _REGISTRY.pop(effect, None)


@contextmanager
def registered(family: Family) -> Iterator[Family]:
    """A family for the length of a block (tests)."""
    register(family)
    try:
        yield family
    finally:
        unregister(family.effect)


def families() -> list[Family]:
    """Every family, in the order the detectable sizes list them."""
    return list(_REGISTRY.values())


def names() -> list[str]:
    return list(_REGISTRY)


def family(effect: str) -> Family:
    try:
        return _REGISTRY[effect]
    except KeyError:
        raise NckConfigError(f"unknown effect {effect!r} (known: {', '.join(_REGISTRY)})") from None


def known(effect: object) -> bool:
    return isinstance(effect, str) and effect in _REGISTRY


def one_time_constant_family(effect: str) -> Family | None:
    """The family with one searched time constant that ``effect`` is or extends (a hysteresis: the
    lag), or None."""
    for candidate in (effect, *family(effect).extends):
        if known(candidate) and family(candidate).searched_column is not None:
            return family(candidate)
    return None


# ---------------------------------------------------------------------- features
def _deviation(recording: Recording, p: dict[str, Any]) -> np.ndarray:
    return recording.sensor(p["sensor"]) - float(p.get("t_ref_C", 20.0))


def _spindle(recording: Recording, _axis: str, _p: dict[str, Any]) -> np.ndarray:
    if recording.spindle_rpm is None:
        raise NckConfigError("centrifugal_growth needs a spindle_rpm column", path=recording.source)
    return (recording.spindle_rpm / 1000.0) ** 2


def _position(recording: Recording, axis: str, p: dict[str, Any]) -> np.ndarray:
    if axis not in recording.positions_mm:
        raise NckConfigError(f"position_dependent_expansion needs a pos_{axis}_mm column", path=recording.source)
    return (recording.positions_mm[axis] - float(p.get("p0_mm", 0.0))) / 1000.0 * _deviation(recording, p)


def _transient(recording: Recording, _axis: str, p: dict[str, Any]) -> np.ndarray:
    # The skin (the sensor) against the core (the sensor through a first-order lag of tau_s): a fast
    # and a slow response of opposite sign, zero once the structure has evened out.
    sensor = recording.sensor(p["sensor"])
    return sensor - first_order_lag(recording.t_s, sensor, float(p["tau_s"]))


def _two_sensors(table: dict[str, Any]) -> tuple[str, str] | None:
    if not isinstance(table["sensors"], list) or len(table["sensors"]) != 2:
        return "sensors must name two sensors [a, b]", "sensors"
    return None


# ---------------------------------------------------------------------- candidates
def _once(effect: str, parameters: dict[str, Any]) -> Generator:
    def generate(source: CandidateSource, present: set[str]) -> Iterator[tuple[str, dict[str, Any], int]]:
        if effect not in present:
            yield effect, dict(parameters), 1
    return generate


def _offset_candidates(source: CandidateSource, present: set[str]) -> Iterator[tuple[str, dict[str, Any], int]]:
    if "offset" not in present and source.needs_offset():
        yield "offset", {"value_um": 0.0}, 1


def _spindle_candidates(source: CandidateSource, present: set[str]) -> Iterator[tuple[str, dict[str, Any], int]]:
    if source.has_spindle():
        yield from _once("centrifugal_growth", {"coeff_um_per_krpm2": 0.0})(source, present)


def _per_sensor(effect: str, coefficient: str, *, not_modelled: bool = False, positions: bool = False,
                extra: dict[str, Any] | None = None) -> Generator:
    def generate(source: CandidateSource, present: set[str]) -> Iterator[tuple[str, dict[str, Any], int]]:
        if positions and not source.has_positions():
            return
        for sensor in source.sensors():
            if f"{effect}:{sensor}" in present or (not_modelled and source.modelled(effect, sensor)):
                continue
            yield effect, {"sensor": sensor, "t_ref_C": source.t_ref(sensor), **(extra or {}), coefficient: 0.0}, 1
    return generate


def _gradient_candidates(source: CandidateSource, present: set[str]) -> Iterator[tuple[str, dict[str, Any], int]]:
    for a, b in itertools.combinations(source.sensors(), 2):
        if f"thermal_gradient:{a}-{b}" not in present:
            yield "thermal_gradient", {"sensors": [a, b], "coeff_um_per_K": 0.0}, 1


def _second_time_constant(source: CandidateSource, present: set[str], effect: str, sensor: str
                          ) -> tuple[float, ...] | None:
    """The time constants a sensor's ``effect`` already has (its next one is searched away from them),
    or None when it may have no other: a sensor is named at most at two time constants (a fast skin
    and a slow core, issue 42), and only when discovery allows a second one."""
    if f"{effect}:{sensor}" not in present:
        return ()
    named = source.named_time_constants(effect, sensor)
    return named if named is not None and len(named) == 1 else None


def _lag_candidates(source: CandidateSource, present: set[str]) -> Iterator[tuple[str, dict[str, Any], int]]:
    """The best time constant per sensor (grid in-sample)."""
    for sensor in source.sensors():
        away = _second_time_constant(source, present, "thermal_lag", sensor)
        if away is None:
            continue
        found = source.best_time_constant(lambda tau, sensor=sensor: source.lag_column(sensor, tau), ("lag", sensor),
                                          away)
        if found is not None:
            yield "thermal_lag", {"sensor": sensor, "t_ref_C": source.t_ref(sensor), "tau_s": found[1],
                                  "coeff_um_per_K": 0.0}, found[2]


def _transient_candidates(source: CandidateSource, present: set[str]) -> Iterator[tuple[str, dict[str, Any], int]]:
    """Skin-core: the sensor less its own lag, the time constant picked the same way."""
    for sensor in source.sensors():
        away = _second_time_constant(source, present, "transient_gradient", sensor)
        if away is None:
            continue
        found = source.best_time_constant(lambda tau, sensor=sensor: source.transient_column(sensor, tau),
                                          ("transient", sensor), away)
        if found is not None:
            yield "transient_gradient", {"sensor": sensor, "tau_s": found[1], "coeff_um_per_K": 0.0}, found[2]


def _hysteresis_candidates(source: CandidateSource, present: set[str]) -> Iterator[tuple[str, dict[str, Any], int]]:
    """The asymmetric variant for the two sensors whose lag fits best."""
    for sensor in source.best_searched("lag", 2):
        if f"heating_cooling_hysteresis:{sensor}" in present:
            continue
        found = source.best_asymmetric_lag(sensor)
        if found is not None:
            yield "heating_cooling_hysteresis", {"sensor": sensor, "t_ref_C": source.t_ref(sensor),
                                                 "tau_heat_s": found[1], "tau_cool_s": found[2],
                                                 "coeff_um_per_K": 0.0}, found[3]


# ---------------------------------------------------------------------- the built-in families
for _family in (
    Family("offset", "value_um", (), {}, 0, "a constant",
           lambda r, _a, _p: np.ones_like(r.t_s), _offset_candidates, plc_form="constant", stage=0),
    Family("time_drift", "um_per_h", (), {}, 1, "a slow drift proportional to time",
           lambda r, _a, _p: (r.t_s - r.t_s[0]) / 3600.0, _once("time_drift", {"um_per_h": 0.0}),
           plc_refusal="the PLC cannot know how long the machine has drifted (no physical input carries it)",
           stage=0),
    Family("temperature", "coeff_um_per_K", ("sensor",), {"t_ref_C": 20.0}, 1, "linear in one sensor",
           lambda r, _a, p: _deviation(r, p), _per_sensor("temperature", "coeff_um_per_K", not_modelled=True),
           plc_form="linear", size_in_structures=1.0),
    Family("gain_error", "gain", (), {}, 1,
           "the model's shape is right, its scale is not (recorded = gain x model)", None,
           coefficient_range=(0.2, 5.0), default_coefficient=1.0),
    Family("quadratic_temperature", "coeff_um_per_K2", ("sensor",), {"t_ref_C": 20.0}, 2,
           "curvature in one sensor", lambda r, _a, p: _deviation(r, p) ** 2,
           _per_sensor("quadratic_temperature", "coeff_um_per_K2"), plc_form="square"),
    Family("thermal_gradient", "coeff_um_per_K", ("sensors",), {}, 2, "bending from the difference of two sensors",
           lambda r, _a, p: r.sensor(p["sensors"][0]) - r.sensor(p["sensors"][1]), _gradient_candidates,
           plc_form="difference", check=_two_sensors, stage=2, size_in_structures=1.5),
    Family("centrifugal_growth", "coeff_um_per_krpm2", (), {}, 2,
           "spindle growth with the square of the speed, without lag", _spindle, _spindle_candidates,
           plc_form="speed_square", uses_spindle=True, stage=0),
    Family("position_dependent_expansion", "slope_um_per_m_per_K", ("sensor",), {"t_ref_C": 20.0, "p0_mm": 0.0}, 2,
           "expansion growing with the distance from P0 (tan beta)", _position,
           _per_sensor("position_dependent_expansion", "slope_um_per_m_per_K", not_modelled=True, positions=True,
                       extra={"p0_mm": 0.0}),
           plc_form="position_slope", uses_position=True, size_in_structures=1.5, per_metre=True),
    Family("thermal_lag", "coeff_um_per_K", ("sensor", "tau_s"), {"t_ref_C": 20.0}, 3,
           "the structure follows a sensor through a first-order lag",
           lambda r, _a, p: first_order_lag(r.t_s, r.sensor(p["sensor"]), float(p["tau_s"]))
           - float(p.get("t_ref_C", 20.0)),
           _lag_candidates, plc_form="lag", extends=("temperature",), time_constants=("tau_s",), stage=3,
           searched_column="lag", size_in_structures=1.0),
    Family("heating_cooling_hysteresis", "coeff_um_per_K", ("sensor", "tau_heat_s", "tau_cool_s"), {"t_ref_C": 20.0}, 4,
           "different lags while heating and while cooling",
           lambda r, _a, p: asymmetric_lag(r.t_s, r.sensor(p["sensor"]), float(p["tau_heat_s"]),
                                           float(p["tau_cool_s"])) - float(p.get("t_ref_C", 20.0)),
           _hysteresis_candidates, plc_form="asymmetric_lag", extends=("temperature", "thermal_lag"),
           time_constants=("tau_heat_s", "tau_cool_s"), stage=5, size_in_structures=1.0, room_may_carry=False),
    # Two responses of one sensor (more than a lag): beside the sensor's own temperature it spans what
    # its lag spans, and then the lag, the simpler, is named. Its time constant going to infinity
    # leaves the sensor's temperature (less its value at the start, which an offset holds).
    Family("transient_gradient", "coeff_um_per_K", ("sensor", "tau_s"), {}, 4,
           "bending while heat crosses a structure (skin-core): a sensor minus its own lagged value, "
           "rising with the sensor, then straightening as the structure evens out",
           _transient, _transient_candidates, plc_form="skin_core", extends=("temperature",),
           time_constants=("tau_s",), stage=4, searched_column="transient", size_in_structures=1.5),
):
    register(_family)
