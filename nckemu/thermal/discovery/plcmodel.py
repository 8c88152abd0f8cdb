"""The improved model a PLC can compute: from a discovery against a program's ``sim_`` column.

Discovery with a ``sim_`` baseline names what the program leaves out, but the program's own law is
only a column there. To generate a program that replaces it, the law is read back from that column
in the vocabulary (offset, temperature and position-dependent terms of the sensors the PLC reads):
``program_law``. The generated model is then ``a * law + sum(c_i * effect_i)``, with ``a`` and the
``c_i`` fitted by least squares on the measured rows (or on the training rows of a held-out fold).
A discovered ``gain_error`` is ``a``.

Effects the PLC cannot compute are set aside with the reason (``not_compensable``): ``time_drift``
(the PLC has no notion of how long the machine has drifted), effects of sensors the machine file
does not wire to a PLC input, and ``centrifugal_growth`` unless a spindle speed input is given.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nckemu.errors import NckConfigError
from nckemu.thermal import stats
from nckemu.thermal.model.terms import Term, ThermalModel
from nckemu.thermal.recordings.recording import Recording

from .findings import Finding


@dataclass
class PlcModel:
    model: ThermalModel                      # what the generated program computes (um, error direction)
    program_law: list[Term]                  # the old program's law read from its sim_ column
    program_law_rms_um: float                # how far the law's terms are from that column
    program_scale: float                     # a: the factor on the old law
    not_compensable: list[dict[str, Any]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"terms": [{"effect": t.effect, **t.parameters} for t in self.model.terms],
                "program_law": [{"effect": t.effect, **t.parameters} for t in self.program_law],
                "program_law_rms_um": round(self.program_law_rms_um, 4),
                "program_scale": round(self.program_scale, 6), "not_compensable": self.not_compensable}


def _sensors_of(term: Term) -> list[str]:
    p = term.parameters
    if term.spec.uses_spindle:
        return []
    if "sensors" in p:
        return [str(s) for s in p["sensors"]]
    return [str(p["sensor"])] if "sensor" in p else []


def why_not_compensable(term: Term, plc_sensors: set[str], spindle_input: bool = False) -> str | None:
    if term.spec.plc_refusal:
        return term.spec.plc_refusal
    if term.spec.uses_spindle and not spindle_input:
        return ("no spindle speed: the machine file wires none to the PLC (a [[sensor]] named spindle_rpm) "
                "and has no spindle whose actual speed FB2 GET could read")
    missing = [s for s in _sensors_of(term) if s not in plc_sensors]
    if missing:
        return f"sensor {', '.join(missing)} is not wired to a PLC input in the machine file"
    return None


def read_program_law(recording: Recording, axis: str, plc_sensors: list[str],
                     min_gain: float = 0.3) -> tuple[list[Term], float]:
    """The program's compensation (``sim_<axis>_um``) as offset + temperature (+ position) terms.

    Forward selection: a term joins while it takes at least ``min_gain`` of what is left (the
    column also carries the write rate and the NCK's rate limit, which no term should chase)."""
    if axis not in recording.simulated_um:
        raise NckConfigError(f"no sim_{axis}_um column to read the program's law from", path=recording.source)
    sim = recording.simulated_um[axis]
    rows = np.isfinite(sim)
    candidates = [Term("temperature", {"sensor": s, "t_ref_C": 20.0, "coeff_um_per_K": 0.0}) for s in plc_sensors]
    position = recording.positions_mm.get(axis)
    if position is not None and np.ptp(position[rows]) > 1.0:
        candidates += [Term("position_dependent_expansion", {"sensor": s, "t_ref_C": 20.0, "p0_mm": 0.0,
                                                             "slope_um_per_m_per_K": 0.0}) for s in plc_sensors]
    columns = {id(t): t.feature(recording, axis)[rows] for t in candidates}
    chosen = [Term("offset", {"value_um": 0.0})]
    design = np.ones((int(rows.sum()), 1))
    coefficients = stats.least_squares(design, sim[rows])
    left = stats.rms(sim[rows] - design @ coefficients)
    floor = 1e-6 * max(float(np.max(np.abs(sim[rows]))), 1.0)
    while candidates and left > floor:
        trials = []
        for term in candidates:
            trial = np.column_stack([design, columns[id(term)]])
            fitted = stats.least_squares(trial, sim[rows])
            trials.append((stats.rms(sim[rows] - trial @ fitted), term, trial, fitted))
        best_rms, term, trial, fitted = min(trials, key=lambda item: item[0])
        if best_rms > (1 - min_gain) * left:
            break
        chosen.append(term)
        candidates.remove(term)
        design, coefficients, left = trial, fitted, best_rms
    return [t.with_coefficient(float(c)) for t, c in zip(chosen, coefficients, strict=True)], left


def terms_of(missing_physics: list[Finding]) -> list[Term]:
    return [Term(m.effect, dict(m.parameters)) for m in missing_physics if m.effect != "gain_error"]


def plc_model(recording: Recording, axis: str, found: list[Term], plc_sensors: list[str],
              train: np.ndarray | None = None, spindle_input: bool = False) -> PlcModel:
    """Fit ``a * program law + sum(c_i * effect_i)`` to ``err_<axis>_um`` on the ``train`` rows."""
    law, law_rms = read_program_law(recording, axis, plc_sensors)
    sensors = set(plc_sensors)
    usable: list[Term] = []
    set_aside: list[dict[str, Any]] = []
    for term in found:
        reason = why_not_compensable(term, sensors, spindle_input)
        if reason:
            set_aside.append({"effect": term.effect, "parameters": term.parameters,
                              "why": f"not compensable in the PLC: {reason}"})
        else:
            usable.append(term)
    measured = np.isfinite(recording.errors_um[axis])
    rows = measured if train is None else measured & train
    if rows.sum() < len(usable) + 2:
        raise NckConfigError(f"only {int(rows.sum())} measured rows to fit the program on", path=recording.source)
    law_column = ThermalModel(axis, law).predict_um(recording)
    columns = [law_column] + [t.feature(recording, axis) for t in usable]
    design = np.column_stack([c[rows] for c in columns])
    coefficients = stats.least_squares(design, recording.errors_um[axis][rows])
    scale = float(coefficients[0])
    terms = [t.with_coefficient(t.coefficient * scale) for t in law]
    terms += [t.with_coefficient(float(c)) for t, c in zip(usable, coefficients[1:], strict=True)]
    return PlcModel(ThermalModel(axis, terms, "<for the PLC>"), law, law_rms, scale, set_aside)
