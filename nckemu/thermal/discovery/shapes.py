"""Shapes: terms of one sensor that together are a known form, named as that form (issue 51).

A sensor's temperature with its own lag spans exactly what the sensor's transient at that time
constant and its temperature span: ``a (T - T_ref) + b (lag(T) - T_ref) = (a + b)(T - T_ref) -
b (T - lag(T))``. The second form says what an engineer can act on: a transient (heat crossing a
structure, ``-b`` um/K, gone once the structure has evened out) and a static part (``a + b`` um/K);
and when the static part earns nothing, the transient alone is the form with fewer parameters.

Pure functions of terms: the selector does the fitting.
"""

from __future__ import annotations

from nckemu.thermal.model.terms import Term

from .library import time_constants


def parameters_of(term: Term) -> int:
    """What a term costs: its coefficient and each of its time constants."""
    return 1 + time_constants(term)


def parameter_bar(bar: float, parameters: int) -> float:
    """The held-out drop ``parameters`` parameters must buy when one must buy ``bar``: each earns its
    share of what is left, ``1 - (1 - bar)^parameters`` (5 % each: 9.75 % for a lag, 14.3 % for a
    hysteresis)."""
    return 1.0 - (1.0 - bar) ** max(parameters, 1)


def temperature_with_lag(terms: list[Term]) -> list[tuple[int, int]]:
    """(index of temperature(s), index of thermal_lag(s)) for every sensor named with both: a
    transient and a static part in another basis."""
    out = []
    for lag_index, lag in enumerate(terms):
        if lag.effect != "thermal_lag":
            continue
        sensor = lag.parameters.get("sensor")
        for index, term in enumerate(terms):
            if term.effect == "temperature" and term.parameters.get("sensor") == sensor:
                out.append((index, lag_index))
                break
    return out


def as_transient(lag: Term) -> Term:
    """The transient of a lag's sensor at the lag's time constant (its coefficient: to be fitted)."""
    return Term("transient_gradient", {"sensor": lag.parameters["sensor"], "tau_s": float(lag.parameters["tau_s"]),
                                       "coeff_um_per_K": 0.0})


def shape_words(sensor: str, tau_s: float, lag_um_per_K: float, temperature_um_per_K: float) -> str:
    """Why a temperature and its own lag are named as a transient with a static part."""
    return (f"temperature({sensor}) {temperature_um_per_K:+.3g} um/K with its own lag at {tau_s / 3600:.2g} h "
            f"{lag_um_per_K:+.3g} um/K is one shape: a transient of {sensor} at {tau_s / 3600:.2g} h "
            f"({-lag_um_per_K:+.3g} um/K: heat crossing the structure, gone once it has evened out) and a static "
            f"part ({temperature_um_per_K + lag_um_per_K:+.3g} um/K); named as that shape")
