"""Terms and the model file (TOML): a sum of named terms for one axis.

Every term is ``coefficient × feature(recording)``: the feature carries the physics (a lag filter,
a square of the speed, a sensor difference...), the coefficient its size. ``gain_error`` is the one
exception: it multiplies the sum of all other terms. The families of effects, each with its feature,
are the registry's (``families.py``).
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from nckemu.errors import NckConfigError
from nckemu.textfile import read_text
from nckemu.thermal.recordings.recording import Recording

from .families import Family, family, known, names
from .structure import Structure, parse_structure, render_structure


@dataclass
class Term:
    effect: str
    parameters: dict[str, Any] = field(default_factory=dict)

    @property
    def spec(self) -> Family:
        return family(self.effect)

    @property
    def coefficient(self) -> float:
        return float(self.parameters.get(self.spec.coefficient, self.spec.default_coefficient))

    def with_coefficient(self, value: float) -> Term:
        return Term(self.effect, {**self.parameters, self.spec.coefficient: float(value)})

    def feature(self, recording: Recording, axis: str) -> np.ndarray:
        """What the coefficient multiplies (not defined for gain_error)."""
        feature = self.spec.feature
        if feature is None:
            raise NckConfigError(f"no feature for effect {self.effect!r}")
        return feature(recording, axis, self.parameters)


@dataclass
class ThermalModel:
    axis: str
    terms: list[Term]
    source: str = "<model>"
    # What the machine's structure allows a discovered term to be (None: discovery's default).
    structure: Structure | None = None

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
    if not known(effect):
        raise NckConfigError(f"unknown effect {effect!r} (known: {', '.join(names())})", path=source,
                             field=f"{where}.effect")
    spec = family(effect)
    allowed = {"effect", spec.coefficient, *spec.required, *spec.optional}
    for key in table:
        if key not in allowed:
            raise NckConfigError(f"{effect} has no parameter {key!r} (it takes {', '.join(sorted(allowed - {'effect'}))})",
                                 path=source, field=f"{where}.{key}")
    for key in spec.required:
        if key not in table:
            raise NckConfigError(f"{effect} needs {key!r}", path=source, field=f"{where}.{key}")
    wrong = spec.check(table) if spec.check is not None else None
    if wrong is not None:
        raise NckConfigError(wrong[0], path=source, field=f"{where}.{wrong[1]}")
    parameters = {**spec.optional, **{k: v for k, v in table.items() if k != "effect"}}
    for key in spec.time_constants:
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
    structure = parse_structure(data["structure"], source) if "structure" in data else None
    return ThermalModel(axis, terms, source, structure)


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
    if model.structure is not None:
        lines += ["", *render_structure(model.structure)]
    for term in model.terms:
        lines += ["", "[[term]]"]
        note = comments(term) if comments else ""
        lines.append(f'effect = "{term.effect}"' + (f"  # {note}" if note else ""))
        for key, value in term.parameters.items():
            lines.append(f"{key} = {_toml_value(value)}")
    return "\n".join(lines) + "\n"
