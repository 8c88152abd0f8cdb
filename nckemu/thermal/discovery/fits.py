"""The fits: one candidate, or a move of two, beside the current design, cross-validated and fitted."""

from __future__ import annotations

import math

import numpy as np

from nckemu.thermal import stats

from .admission import Admission
from .library import Candidate
from .records import Baseline, Evaluation, Move, Path


class Fits:
    def __init__(self, y: np.ndarray, baseline: Baseline, admission: Admission) -> None:
        self.y = y
        self.baseline = baseline
        self.admission = admission

    def evaluate(self, design: np.ndarray, noise: np.ndarray, candidate: Candidate,
                 base_cv: stats.CrossValidation) -> Evaluation:
        full = np.column_stack([design, candidate.feature])
        cv = self.baseline.cross_validate(full, self.y, self.baseline.folds)
        result = stats.fit(full, self.y)
        counted = candidate.runs_with if candidate.runs_with is not None else [True] * len(cv.fold_rms_um)
        wins = sum(after < before for after, before, count in zip(cv.fold_rms_um, base_cv.fold_rms_um, counted,
                                                                  strict=True) if count)
        # Errors in variables: noise n in the features adds mean((n @ b)^2) to the squared error of
        # the fitted model's prediction, independent of the gauge's noise and of the physics.
        carried = float(np.mean(np.square(np.column_stack([noise, candidate.noise]) @ result.coefficients)))
        ranked = math.sqrt(max(cv.rms_um ** 2 - carried, 0.0))
        return Evaluation(candidate, cv, result.t_value(full.shape[1] - 1), float(result.coefficients[-1]), wins,
                          ranked)

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
        counted = runs_with if runs_with is not None else [True] * len(cv.fold_rms_um)
        wins = sum(after < before for after, before, count in zip(cv.fold_rms_um, path.base_cv.fold_rms_um, counted,
                                                                  strict=True) if count)
        noise = np.column_stack([path.noise, a.candidate.noise, b.candidate.noise])
        carried = float(np.mean(np.square(noise @ result.coefficients)))
        move = Move((a, b), cv, (result.t_value(columns - 2), result.t_value(columns - 1)),
                    (float(result.coefficients[-2]), float(result.coefficients[-1])), wins,
                    math.sqrt(max(cv.rms_um ** 2 - carried, 0.0)), runs_with)
        # Without one effect the move is the other alone: its share is what the move loses then.
        lost = [max(self.admission.heldout_gain(move.cv, other.cv, runs_with), 0.0) for other in (b, a)]
        total = sum(lost)
        move.shares = (lost[0] / total, lost[1] / total) if total > 0 else (0.5, 0.5)
        return move
