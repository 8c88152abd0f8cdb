"""What discovery found, as typed records: each finding with its evidence, a term likely but not
proven, and the alternatives weighed against them.

Every figure's name in the JSON (``heldout_rms_before_um`` ...) is spelled here and nowhere else in
the pipeline; ``to_json`` gives the documented layout (docs/thermal.md), key for key.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


def _rounded(parameters: dict[str, Any]) -> dict[str, Any]:
    return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in parameters.items()}


@dataclass
class Alternative:
    """An explanation weighed against the one named: another effect, a gain, or recalibration."""
    effect: str
    heldout_rms_um: float
    heldout_rms_without_sensor_noise_um: float | None = None
    gain: float | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"effect": self.effect}
        if self.gain is not None:
            out["gain"] = self.gain
        out["heldout_rms_um"] = self.heldout_rms_um
        if self.heldout_rms_without_sensor_noise_um is not None:
            out["heldout_rms_without_sensor_noise_um"] = self.heldout_rms_without_sensor_noise_um
        return out


@dataclass
class AdmissionRuns:
    """Several runs: each run's held-out figure before and after the admitted effect, in a few numbers."""
    median_before_um: float
    median_after_um: float
    runs_improved: int
    runs: int
    worst_before_um: float
    worst_after_um: float
    worst_run: str

    def to_json(self) -> dict[str, Any]:
        return {"median_before_um": self.median_before_um, "median_after_um": self.median_after_um,
                "runs_improved": self.runs_improved, "runs": self.runs, "worst_before_um": self.worst_before_um,
                "worst_after_um": self.worst_after_um, "worst_run": self.worst_run}


@dataclass
class MoveAlternative:
    effects: str
    heldout_rms_um: float

    def to_json(self) -> dict[str, Any]:
        return {"effects": self.effects, "heldout_rms_um": self.heldout_rms_um}


@dataclass
class MoveEvidence:
    """Two effects admitted as one move: the move's figures and this effect's share of it."""
    terms: list[str]
    heldout_rms_after_um: float
    alone_heldout_rms_um: list[float]
    shares: list[float]
    equivalent: list[MoveAlternative]
    why: str
    share: float

    def to_json(self) -> dict[str, Any]:
        return {"terms": self.terms, "heldout_rms_after_um": self.heldout_rms_after_um,
                "alone_heldout_rms_um": self.alone_heldout_rms_um, "shares": self.shares,
                "equivalent": [m.to_json() for m in self.equivalent], "why": self.why, "share": self.share}


@dataclass
class RegimeGroup:
    """A group of runs a term was fitted on apart (issue 51): its runs, its coefficient and both
    models' figures on them (the median over its runs of held-out RMS before, with one coefficient for
    all runs, and with one per group; its worst run)."""
    runs_words: str
    runs: list[str]
    coefficient: float
    median_before_um: float
    median_one_coefficient_um: float
    median_after_um: float
    worst_after_um: float
    apart: bool                     # the group that follows the other relation

    def to_json(self) -> dict[str, Any]:
        return {"runs_words": self.runs_words, "runs": self.runs, "coefficient": self.coefficient,
                "median_before_um": self.median_before_um,
                "median_one_coefficient_um": self.median_one_coefficient_um,
                "median_after_um": self.median_after_um, "worst_after_um": self.worst_after_um, "apart": self.apart}


@dataclass
class Window:
    t_start_s: float
    t_end_s: float

    def to_json(self) -> dict[str, Any]:
        return {"t_start_s": self.t_start_s, "t_end_s": self.t_end_s}


@dataclass
class Evidence:
    """Why one effect was admitted: held-out figures, the t-test, folds, where it acts, the
    alternatives and which was preferred."""
    heldout_rms_before_um: float
    heldout_rms_after_um: float
    heldout_rms_without_sensor_noise_um: float
    t_value_ar1_corrected: float | None
    t_critical: float
    folds_improved: str
    window: Window | None
    equivalent: list[Alternative]
    why: str
    resolved_to_simpler: str | None = None
    preferred: str = ""
    move: MoveEvidence | None = None
    runs: AdmissionRuns | None = None
    note: str | None = None
    # A sensor named at two time constants in two rounds: this one's share of what the two improve.
    twin_share: float | None = None
    # Fitted on a group of runs apart (issue 51): the group, its coefficient and both models' figures.
    regime: RegimeGroup | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "heldout_rms_before_um": self.heldout_rms_before_um, "heldout_rms_after_um": self.heldout_rms_after_um,
            "heldout_rms_without_sensor_noise_um": self.heldout_rms_without_sensor_noise_um,
            "t_value_ar1_corrected": self.t_value_ar1_corrected, "t_critical": self.t_critical,
            "folds_improved": self.folds_improved, "window": self.window.to_json() if self.window else None,
            "equivalent": [e.to_json() for e in self.equivalent], "why": self.why}
        if self.resolved_to_simpler is not None:
            out["resolved_to_simpler"] = self.resolved_to_simpler
        out["preferred"] = self.preferred
        if self.move is not None:
            out["move"] = self.move.to_json()
        if self.runs is not None:
            out["runs"] = self.runs.to_json()
        if self.note is not None:
            out["note"] = self.note
        if self.twin_share is not None:
            out["twin_share"] = self.twin_share
        if self.regime is not None:
            out["regime"] = self.regime.to_json()
        return out


@dataclass
class GainEvidence:
    """Why a common gain on the model as given was named."""
    heldout_rms_before_um: float
    heldout_rms_after_um: float
    baseline_rms_um: float
    gain_se: float
    equivalent: list[Alternative]
    why: str
    preferred: str | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "heldout_rms_before_um": self.heldout_rms_before_um, "heldout_rms_after_um": self.heldout_rms_after_um,
            "baseline_rms_um": self.baseline_rms_um, "gain_se": self.gain_se,
            "equivalent": [e.to_json() for e in self.equivalent], "why": self.why}
        if self.preferred is not None:
            out["preferred"] = self.preferred
        return out


@dataclass
class Finding:
    """One effect the model left out, with its parameters and the evidence for it."""
    effect: str
    parameters: dict[str, Any]
    evidence: Evidence | GainEvidence

    def to_json(self) -> dict[str, Any]:
        return {"effect": self.effect, "parameters": self.parameters, "evidence": self.evidence.to_json()}


@dataclass
class LikelyEvidence:
    heldout_rms_before_um: float
    heldout_rms_after_um: float
    heldout_improvement: float
    heldout_bar: float
    t_value_ar1_corrected: float | None
    t_critical: float
    folds_improved: str
    why: str

    def to_json(self) -> dict[str, Any]:
        return {"heldout_rms_before_um": self.heldout_rms_before_um, "heldout_rms_after_um": self.heldout_rms_after_um,
                "heldout_improvement": self.heldout_improvement, "heldout_bar": self.heldout_bar,
                "t_value_ar1_corrected": self.t_value_ar1_corrected, "t_critical": self.t_critical,
                "folds_improved": self.folds_improved, "why": self.why}


@dataclass
class Likely:
    """A term that passes every guard but the held-out bar: "likely, not proven", with its figures."""
    effect: str
    label: str
    parameters: dict[str, Any]
    evidence: LikelyEvidence
    status: str = "likely, not proven"

    def to_json(self) -> dict[str, Any]:
        return {"effect": self.effect, "label": self.label, "parameters": self.parameters, "status": self.status,
                "evidence": self.evidence.to_json()}


@dataclass
class GuardFigure:
    """How a candidate stands against one guard: its figure in words, and whether it passes."""
    guard: str
    passes: bool
    figure: str

    def to_json(self) -> dict[str, Any]:
        return {"guard": self.guard, "passes": self.passes, "figure": self.figure}


@dataclass
class Closest:
    """A candidate of the last round that came close, with every guard's figure: what stopped it."""
    effect: str
    label: str
    parameters: dict[str, Any]
    guards: list[GuardFigure]

    @property
    def held_back_by(self) -> list[str]:
        return [g.guard for g in self.guards if not g.passes]

    def to_json(self) -> dict[str, Any]:
        return {"effect": self.effect, "label": self.label, "parameters": self.parameters,
                "held_back_by": self.held_back_by, "guards": [g.to_json() for g in self.guards]}


@dataclass
class Withdrawn:
    """A term named in an early round and withdrawn at the end: later terms explain what it did."""
    effect: str
    label: str
    parameters: dict[str, Any]
    why: str

    def to_json(self) -> dict[str, Any]:
        return {"effect": self.effect, "label": self.label, "parameters": _rounded(self.parameters), "why": self.why}


def finding(effect: str, parameters: dict[str, Any], evidence: Evidence | GainEvidence) -> Finding:
    """A finding with its parameters rounded as the JSON gives them."""
    return Finding(effect, _rounded(parameters), evidence)


__all__ = ["AdmissionRuns", "Alternative", "Closest", "Evidence", "Finding", "GainEvidence", "GuardFigure", "Likely",
           "LikelyEvidence", "MoveAlternative", "MoveEvidence", "RegimeGroup", "Window", "Withdrawn", "finding"]
