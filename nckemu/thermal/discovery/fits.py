"""The fits: one candidate, or a move of two, beside the current design, cross-validated and fitted."""

from __future__ import annotations

import math

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.model.terms import Term

from . import explain
from .admission import Admission
from .library import Candidate
from .records import Baseline, Evaluation, Move, Path
from .settings import Settings


def cancelling(full: np.ndarray, coefficients: np.ndarray, y: np.ndarray, named: tuple[Term, ...],
               new: tuple[Term, ...], settings: Settings) -> str:
    """Do a new term and a named one (or the two of a move) cancel each other in the joint fit? Their
    contributions (coefficient x column, the named terms' and the new ones' the last columns of
    ``full``) together leave less than ``cancelling_share`` of the larger alone, and the larger moves
    the structure more than the whole error to explain does (RMS of ``y``): two large opposite terms on
    sensors that rise together, which a machine does not have (on fl_thermal ch5 two lags of
    neighbouring sensors at +20 and -15 um/K, each moving 8 and 5.5 um against an error of 5.7 um).
    Two correlated sensors of opposite signs that each stay within the error (3 um/K of one, -1.5 of
    the other) pass. The words of the worst such pair; empty when none is."""
    if not settings.cancelling_share or not named:
        return ""
    terms = named + new
    columns = full[:, -len(terms):] * coefficients[-len(terms):]
    sizes = np.sqrt(np.mean(np.square(columns), axis=0))
    scale = float(np.sqrt(np.mean(np.square(y))))
    worst: tuple[float, str] = (math.inf, "")
    for j in range(len(named), len(terms)):
        for i in range(j):
            larger = max(float(sizes[i]), float(sizes[j]))
            if larger <= scale or larger == 0:
                continue
            left = float(np.sqrt(np.mean(np.square(columns[:, i] + columns[:, j])))) / larger
            if left < settings.cancelling_share and left < worst[0]:
                worst = (left, f"{explain.label_with_time_constants(terms[i])} {coefficients[-len(terms) + i]:+.3g} "
                               f"and {explain.label_with_time_constants(terms[j])} {coefficients[-len(terms) + j]:+.3g} "
                               f"cancel each other (each moves the structure by up to {larger:.2f} um RMS, more "
                               f"than the {scale:.2f} um to explain; together {left:.0%} of the larger)")
    return worst[1]


def fold_wins(cv: stats.CrossValidation, base_cv: stats.CrossValidation, runs_with: np.ndarray | None) -> int:
    """The folds (of the runs that have the columns: ``runs_with``) whose held-out RMS drops."""
    counted = runs_with if runs_with is not None else [True] * len(cv.fold_rms_um)
    return sum(after < before for after, before, count in zip(cv.fold_rms_um, base_cv.fold_rms_um, counted,
                                                              strict=True) if count)


def without_noise_um(cv: stats.CrossValidation, noise: np.ndarray, coefficients: np.ndarray) -> float:
    """Held-out RMS less what the features' sensor noise carries. Errors in variables: noise n in the
    features adds mean((n @ b)^2) to the squared error of the fitted model's prediction, independent
    of the gauge's noise and of the physics."""
    carried = float(np.mean(np.square(noise @ coefficients)))
    return math.sqrt(max(cv.rms_um ** 2 - carried, 0.0))


class Fits:
    def __init__(self, y: np.ndarray, baseline: Baseline, admission: Admission) -> None:
        self.y = y
        self.baseline = baseline
        self.admission = admission

    def evaluate(self, design: np.ndarray, noise: np.ndarray, candidate: Candidate,
                 base_cv: stats.CrossValidation, named: tuple[Term, ...] = ()) -> Evaluation:
        """``named``: the terms the search named so far, the last columns of ``design`` (whether the
        candidate cancels one of them)."""
        full = np.column_stack([design, candidate.feature])
        cv = self.baseline.cross_validate(full, self.y, self.baseline.folds)
        result = stats.fit(full, self.y)
        wins = fold_wins(cv, base_cv, candidate.runs_with)
        ranked = without_noise_um(cv, np.column_stack([noise, candidate.noise]), result.coefficients)
        return Evaluation(candidate, cv, result.t_value(full.shape[1] - 1), float(result.coefficients[-1]), wins,
                          ranked, cancelling=cancelling(full, result.coefficients, self.y, named,
                                                        (candidate.term,), self.admission.settings))

    def evaluate_pair(self, path: Path, a: Evaluation, b: Evaluation) -> Move:
        full = np.column_stack([path.design, a.candidate.feature, b.candidate.feature])
        cv = self.baseline.cross_validate(full, self.y, self.baseline.folds)
        result = stats.fit(full, self.y)
        columns = full.shape[1]
        runs_with = None
        if a.candidate.runs_with is not None or b.candidate.runs_with is not None:
            everywhere = np.ones(len(cv.fold_rms_um), dtype=bool)
            runs_with = (everywhere if a.candidate.runs_with is None else a.candidate.runs_with) \
                & (everywhere if b.candidate.runs_with is None else b.candidate.runs_with)
        noise = np.column_stack([path.noise, a.candidate.noise, b.candidate.noise])
        move = Move((a, b), cv, (result.t_value(columns - 2), result.t_value(columns - 1)),
                    (float(result.coefficients[-2]), float(result.coefficients[-1])),
                    fold_wins(cv, path.base_cv, runs_with), without_noise_um(cv, noise, result.coefficients), runs_with)
        # The two of the move count as named for each other: a pair that cancels is refused too.
        move.cancelling = cancelling(full, result.coefficients, self.y, (*path.added, a.candidate.term),
                                     (b.candidate.term,), self.admission.settings)
        # Without one effect the move is the other alone: its share is what the move loses then.
        lost = [max(self.admission.heldout_gain(move.cv, other.cv, runs_with), 0.0) for other in (b, a)]
        total = sum(lost)
        move.shares = (lost[0] / total, lost[1] / total) if total > 0 else (0.5, 0.5)
        return move
