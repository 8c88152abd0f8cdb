"""The run figures: with several runs, each run's held-out RMS before and after a candidate (its own
offset fitted on it, everything else on the other runs), what admission reads of them (the medians,
how many runs improve, the worst run) and which runs a candidate leaves worse than tolerated; after
the search, which runs the final model leaves worse than before discovery (``made_worse``) and what
those runs share (``shared_traits``), so that no run is made worse in silence (issue 51)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

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
        """The runs ``after`` leaves worse than ``before`` beyond the harm tolerance (``harmed``)."""
        return harmed(before, after, self.settings)


def harmed(before: Sequence[float], after: Sequence[float], settings: Settings) -> list[int]:
    """The runs ``after`` leaves worse than ``before`` by more than ``run_harm_share`` and by more
    than ``run_harm_floor_um``: the one harm tolerance, for admission and for the final report."""
    return [index for index, (b, a) in enumerate(zip(before, after, strict=True))
            if a > b * (1 + settings.run_harm_share) and a > b + settings.run_harm_floor_um]


def made_worse(rows: list[dict[str, Any]], settings: Settings,
               explained_by: dict[str, str]) -> list[dict[str, Any]]:
    """Marks each run row with whether the final model leaves it worse than before discovery beyond
    the harm tolerance, and returns those runs (name, before, after). A run that a group of runs
    fitted apart holds (``explained_by``: a run's name to the group's words, only the group that
    follows the other relation) is explained, not made worse in silence: its group is named with its
    own figures, so the row says ``worse_in_group`` instead of ``made_worse``."""
    worse = set(harmed([r["heldout_rms_before_um"] for r in rows], [r["heldout_rms_after_um"] for r in rows],
                       settings))
    out = []
    for index, row in enumerate(rows):
        group = explained_by.get(row["name"]) if index in worse else None
        row["made_worse"] = index in worse and group is None
        if group is not None:
            row["worse_in_group"] = group
        if row["made_worse"]:
            out.append({"run": row["name"], "before_um": row["heldout_rms_before_um"],
                        "after_um": row["heldout_rms_after_um"]})
    return out


def consecutive(names: list[str], groups: np.ndarray) -> bool:
    """Is the smaller group (``groups == 1``) one stretch of runs in name order (a date range, as runs
    are named by date)? A grouping found from the data alone is named only then (regimes.py): signs
    that scatter over the runs are what noise gives, and a held-out run's group must be one a user can
    know beforehand (its date); a cycle type is the user's to give (``--group-by``)."""
    order = np.argsort(names, kind="stable")
    positions = np.flatnonzero(groups[order] == 1)
    return len(positions) > 0 and int(positions[-1] - positions[0]) == len(positions) - 1


def shared_traits(rows: list[dict[str, Any]], median_after_um: float) -> list[str]:
    """What the runs made worse share, from what the discovery already has, in a few words each
    (never more than the data say; empty when nothing holds): (a) quiet runs, whose error before was
    below the model's median held-out residual over runs, so that the model's own typical error is
    larger than theirs; (b) a stretch of consecutive runs in name order (runs are named by date);
    (c) one signal their residual follows where they still fail (the mismatch analysis)."""
    worse = [r for r in rows if r.get("made_worse")]
    if not worse:
        return []
    one = len(worse) == 1
    traits = []
    if all(r["heldout_rms_before_um"] < median_after_um for r in worse):
        traits.append((f"a quiet run (its error before, {worse[0]['heldout_rms_before_um']:.3f} um, was" if one else
                       "quiet runs (their error before was")
                      + f" below the model's median residual over runs, {median_after_um:.3f} um)")
    names = [r["name"] for r in rows]
    if not one and consecutive(names, np.array([int(bool(r.get("made_worse"))) for r in rows])):
        ordered = sorted(r["name"] for r in worse)
        traits.append(f"the {len(worse)} consecutive runs {ordered[0]} .. {ordered[-1]}")
    signals = {r.get("follows_signal") for r in worse}
    if len(signals) == 1 and None not in signals:
        correlations = ", ".join(f"{r['follows_r']:+.2f}" for r in worse)
        traits.append(f"{'its residual follows' if one else 'their residuals follow'} {signals.pop()} where "
                      f"{'it still fails' if one else 'they still fail'} (r = {correlations})")
    return traits
