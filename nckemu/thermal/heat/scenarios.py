"""Machines whose heat physics is concealed in a generated recording, for the heat fit to find again
(tests and bench). Each family hides one piece of physics on one sensor; every recording also has a
room sensor (``ambient``), a switched coolant that only the ``coolant`` family's sensor answers, and a
``cabinet`` sensor that answers nothing: the nulls.

The truth is returned beside the recording: per sensor, the terms as ``HeatTerm`` (the twin's own
form), so a test compares what the fit names with what was hidden.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from nckemu.heat_response import SENSOR, SPINDLE, HeatTerm, simulate

from .table import HeatRun

FAMILIES = ("speed_power", "two_time_constants", "ambient_lag", "coolant", "neighbour")
SPEEDS_RPM = (0.0, 0.0, 2000.0, 4000.0, 6000.0, 8000.0, 10000.0, 12000.0)
STEP_S = 60.0


@dataclass
class Scenario:
    family: str
    seed: int
    run: HeatRun
    truth: dict[str, tuple[HeatTerm, ...]]
    subject: str          # the sensor that carries the family's physics


def _blocks(rng: np.random.Generator, count: int, shortest: int, longest: int, values: list[float]) -> np.ndarray:
    out = np.empty(count)
    k = 0
    while k < count:
        length = int(rng.integers(shortest, longest + 1))
        out[k:k + length] = values[int(rng.integers(len(values)))]
        k += length
    return out


def generate(family: str, seed: int, hours: float = 30.0) -> Scenario:
    rng = np.random.default_rng([50, FAMILIES.index(family), seed])
    t_s = np.arange(0.0, hours * 3600.0 + 1, STEP_S)
    count = len(t_s)
    rpm = _blocks(rng, count, 40, 120, list(SPEEDS_RPM))
    coolant = _blocks(rng, count, 30, 90, [0.0, 1.0])
    phase = rng.uniform(0, 2 * math.pi)
    ambient = 20.0 + rng.uniform(1.5, 3.0) * np.sin(2 * math.pi * t_s / 86400.0 + phase)
    ambient += np.cumsum(rng.normal(0.0, 0.01, count))
    truth: dict[str, tuple[HeatTerm, ...]] = {}
    base = {"ambient": float(ambient[0]), "cabinet": 22.0}
    rise_K = rng.uniform(6.0, 15.0)            # a spindle bearing at full speed (12000 rpm)
    if family == "speed_power":
        subject, power = "bearing", 1.6
        truth[subject] = (HeatTerm(SPINDLE, rise_K / 12.0 ** power, rng.uniform(1200, 3600), power, name="spindle"),)
    elif family == "two_time_constants":
        subject = "housing"
        skin = rng.uniform(0.3, 0.6)
        truth[subject] = (HeatTerm(SPINDLE, skin * rise_K / 12.0, rng.uniform(600, 1200), 1.0, name="spindle skin"),
                          HeatTerm(SPINDLE, (1 - skin) * rise_K / 12.0, rng.uniform(7200, 14400), 1.0,
                                   name="spindle core"))
    elif family == "ambient_lag":
        subject = "column"
        truth[subject] = (HeatTerm(SENSOR, rng.uniform(0.6, 1.0), rng.uniform(1800, 7200), sensor="ambient",
                                   from_C=base["ambient"], name="ambient"),)
    elif family == "coolant":
        subject = "table"
        truth[subject] = (HeatTerm(SPINDLE, 0.4 * rise_K / 12.0, rng.uniform(1200, 2400), 1.0, name="spindle"),
                          HeatTerm("coolant", -rng.uniform(1.0, 3.0), rng.uniform(600, 1800), name="coolant"))
    else:
        subject = "frame"
        truth["head"] = (HeatTerm(SPINDLE, rise_K / 12.0 ** 1.3, rng.uniform(1200, 2400), 1.3, name="spindle"),)
        truth[subject] = (HeatTerm(SENSOR, rng.uniform(0.3, 0.6), rng.uniform(3600, 7200), sensor="head",
                                   from_C=20.0, name="neighbour"),)
    for name in truth:
        base[name] = 20.0
    inputs = {SPINDLE: rpm, "coolant": coolant}
    sensors = simulate(t_s, inputs, base, truth, {"ambient": ambient})
    noise = {name: rng.uniform(0.02, 0.05) for name in sensors}
    recorded = {name: values + rng.normal(0.0, noise[name], count) for name, values in sensors.items()}
    return Scenario(family, seed, HeatRun(f"{family}_{seed:02d}", t_s, recorded, inputs), truth, subject)


def within(found: float, true: float, share: float = 0.25) -> bool:
    return abs(found - true) <= share * abs(true)


def _rise(term: HeatTerm, rpm: float = 12000.0) -> float:
    """A spindle term's steady rise at ``rpm`` (K): what K and the power mean together."""
    return term.K * (1.0 if term.power == 0 else (rpm / 1000.0) ** term.power)


def _matches(found: HeatTerm, true: HeatTerm) -> bool:
    if found.input != true.input or found.sensor != true.sensor or not within(found.tau_s, true.tau_s):
        return False
    if true.input == SPINDLE:
        return within(found.power, true.power) and within(_rise(found), _rise(true))
    return within(found.K, true.K)


def judged(scenario: Scenario, found: dict[str, list[HeatTerm]]) -> tuple[bool, list[str]]:
    """(the hidden physics named with every parameter within 25 %, what was named that should not be):
    the subject's true terms each matched by one found term; the cabinet named nothing, and no sensor but
    the coolant family's answers the coolant."""
    terms = found.get(scenario.subject, [])
    named = all(any(_matches(f, t) for f in terms) for t in scenario.truth[scenario.subject])
    false = [f"cabinet: {t.words()}" for t in found.get("cabinet", [])]
    for sensor, sensor_terms in found.items():
        for term in sensor_terms:
            if term.input == "coolant" and not any(t.input == "coolant" for t in scenario.truth.get(sensor, ())):
                false.append(f"{sensor}: {term.words()}")
    return named, false
