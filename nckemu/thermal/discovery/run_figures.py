"""The run figures: with several runs, each run's held-out RMS before and after a candidate (its own
offset fitted on it, everything else on the other runs), what admission reads of them (the medians,
how many runs improve, the worst run) and which runs a candidate leaves worse than tolerated."""

from __future__ import annotations

import numpy as np

from nckemu.thermal import stats

from .findings import AdmissionRuns
from .library import Library
from .records import Baseline
from .settings import Settings


class RunFigures:
    def __init__(self, library: Library, settings: Settings, baseline: Baseline) -> None:
        self.library = library
        self.settings = settings
        self.baseline = baseline

    def reference_folds(self, base_cv: stats.CrossValidation) -> tuple[float, ...]:
        """Per fold, what a candidate must beat: the current model refitted, or the model exactly as
        given when that predicts held-out data better (as for the pooled reference)."""
        given = self.baseline.given_cv
        return given.fold_rms_um if self.baseline.given_heldout_um < base_cv.rms_um else base_cv.fold_rms_um

    def run_figures(self, cv: stats.CrossValidation, base_cv: stats.CrossValidation,
                    runs_with: np.ndarray | None) -> AdmissionRuns:
        """Several runs: each run's held-out RMS (its own offset fitted on it, everything else on the
        other runs) before and after, over the runs that have the columns: the median, how many
        improve, the worst run."""
        before = np.asarray(self.reference_folds(base_cv))
        after = np.asarray(cv.fold_rms_um)
        counted = np.ones(len(after), dtype=bool) if runs_with is None else np.asarray(runs_with, dtype=bool)
        names = [run.name for run in self.library.problem.runs]
        worst = int(np.flatnonzero(counted)[np.argmax(after[counted])])
        return AdmissionRuns(median_before_um=round(float(np.median(before[counted])), 4),
                             median_after_um=round(float(np.median(after[counted])), 4),
                             runs_improved=int(np.sum(after[counted] < before[counted])), runs=int(counted.sum()),
                             worst_before_um=round(float(np.max(before[counted])), 4),
                             worst_after_um=round(float(after[worst]), 4), worst_run=names[worst])

    def run_medians(self, cv: stats.CrossValidation, base_cv: stats.CrossValidation,
                    runs_with: np.ndarray | None) -> tuple[float, float]:
        """Several runs: the median over the runs that have the columns of each run's held-out RMS,
        before (``reference_folds``) and after."""
        before = np.asarray(self.reference_folds(base_cv))
        after = np.asarray(cv.fold_rms_um)
        if runs_with is not None:
            before, after = before[runs_with], after[runs_with]
        return float(np.median(before)), float(np.median(after))

    def harms_runs(self, before: tuple[float, ...], after: tuple[float, ...]) -> list[int]:
        """The runs ``after`` leaves worse than ``before`` by more than ``run_harm_share`` and by more
        than ``run_harm_floor_um``."""
        s = self.settings
        return [index for index, (b, a) in enumerate(zip(before, after, strict=True))
                if a > b * (1 + s.run_harm_share) and a > b + s.run_harm_floor_um]
