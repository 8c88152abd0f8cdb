"""The selector: a forward search that adds one named effect a round, under the guards against
false discovery (docs/thermal.md): held-out RMS, folds improved, an autocorrelation-corrected
t-test Bonferroni-corrected over the round, physical parameters, equivalent explanations resolved
to the simplest, a time constant earning its place, and a common gain named only when physical.

It sees matrices only: the gauge samples ``y``, the baseline's columns, the held-out masks of a
splitter, and the candidate library. Blocks of one run and runs of a machine are alike to it.

Its parts, by job: the records it keeps (``records``), the admission tests (``admission``), the search
(``search``; ``moves`` for moves of two effects; ``fits`` for the fits behind both), the run figures
(``run_figures``) and the words (``selection_words``; ``explain`` for the evidence records). This
module holds the two searches' entry, the choice of a common gain, and what the last round leaves.
"""

from __future__ import annotations

import math

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.model.terms import Term

from . import explain
from . import selection_words as words
from .admission import Admission
from .findings import Alternative, Evidence
from .library import Library
from .records import Baseline, Evaluation, Guard, Path
from .search import Search
from .settings import Settings


class Selector:
    """The two searches (the recalibrated model plus effects, gain x the model plus effects), the choice
    between them, and what the last round of a path leaves for the words."""

    def __init__(self, y: np.ndarray, t_s: np.ndarray, library: Library, settings: Settings,
                 baseline: Baseline) -> None:
        self.y = y
        self.t_s = t_s
        self.library = library
        self.settings = settings
        self.baseline = baseline
        self.admission = Admission(library, settings, baseline)
        self.searcher = Search(y, t_s, library, settings, baseline, self.admission)

    def search(self, gain_mode: bool) -> Path:
        return self.searcher.search(gain_mode)

    # ------------------------------------------------------------------ what regimes and the words read
    @property
    def paired_runs(self) -> bool:
        return self.admission.paired_runs

    @property
    def bar(self) -> float:
        return self.admission.bar

    def heldout_gain(self, cv: stats.CrossValidation, base_cv: stats.CrossValidation,
                     runs_with: np.ndarray | None = None) -> float:
        return self.admission.heldout_gain(cv, base_cv, runs_with)

    def heldout_figures(self, cv: stats.CrossValidation, base_cv: stats.CrossValidation,
                        runs_with: np.ndarray | None = None) -> tuple[float, float, float, str]:
        return self.admission.heldout_figures(cv, base_cv, runs_with)

    def harms_runs(self, before: tuple[float, ...], after: tuple[float, ...]) -> list[int]:
        return self.admission.runs.harms_runs(before, after)

    def guards(self, cv: stats.CrossValidation, fold_wins: int, runs_with: np.ndarray | None,
               t_values: tuple[float, ...], terms: tuple[Term, ...], base_cv: stats.CrossValidation,
               t_crit: float) -> list[Guard]:
        return self.admission.guards(cv, fold_wins, runs_with, t_values, terms, base_cv, t_crit)

    # ------------------------------------------------------------------ the last round
    def near_misses(self, path: Path) -> list[Evaluation]:
        """Candidates of the last round that pass every guard but the held-out bar (and still lower
        held-out RMS by ``likely_min_improvement``), best first."""
        near = [e for e, guards in self.judged(path)
                if all(g.passes for g in guards[:-1]) and not guards[-1].passes
                and guards[-1].gain >= self.settings.likely_min_improvement]
        return sorted(near, key=lambda e: e.ranked_rms_um)

    def judged(self, path: Path) -> list[tuple[Evaluation, list[Guard]]]:
        """Every candidate of the last round with every guard's figure, at the last round's correction
        of the runs' paired test, computed once for the likely term, the closest and their words."""
        if path.judged is None:
            self.admission.paired_tests = path.rejected_paired_tests
            path.judged = [(e, self.guards_with_time_constant(e, path)) for e in path.rejected]
        return path.judged

    def guards_with_time_constant(self, evaluation: Evaluation, path: Path) -> list[Guard]:
        """Every guard of a candidate of the last round (nothing of which passed), the time constant's
        before the held-out bar."""
        guards = self.admission.guards_of(evaluation, path.base_cv, path.rejected_t_critical)
        extra = [] if (found := self.admission.time_constant_guard(evaluation, path.rejected, [])) is None else [found]
        if path.at_limit:
            extra.append(Guard("limit", False, words.limit_words(self.settings.max_effects)))
        return guards[:-1] + extra + [guards[-1]]

    def closest(self, path: Path, count: int = 3) -> list[tuple[Evaluation, list[Guard]]]:
        """The ``count`` candidates of the last round that lowered the held-out figure most, each with
        every guard's figure (what held it back), best first."""
        return sorted(self.judged(path),
                      key=lambda item: -item[1][-1].gain if math.isfinite(item[1][-1].gain) else math.inf)[:count]

    def own_rms(self, design: np.ndarray, feature: np.ndarray) -> float:
        """RMS of the part of ``feature`` that ``design`` does not already hold."""
        if design.shape[1] == 0:
            return stats.rms(feature)
        return stats.rms(feature - design @ stats.least_squares(design, feature))

    # ------------------------------------------------------------------ a common gain
    def gain_eligible(self) -> bool:
        """One common factor on the model as given: physical (``gain_range``), departing from 1 by
        more than ``min_gain_departure`` and 3 standard errors, explaining (>= 90 % of) what
        recalibration explains, and improving held-out RMS in most blocks."""
        s, y, setup = self.settings, self.y, self.baseline
        gain_design = setup.given[:, None]
        gain_fit = stats.fit(gain_design, y)
        gain, gain_se = float(gain_fit.coefficients[0]), float(gain_fit.standard_errors[0])
        gain_cv = setup.cross_validate(gain_design, y, setup.folds)
        explains = (setup.baseline_rms - gain_fit.rms_um) >= 0.9 * (setup.baseline_rms - setup.recalibrated_rms) \
            or setup.base_design.shape[1] <= 1
        wins = sum(g < b for g, b in zip(gain_cv.fold_rms_um, setup.given_cv.fold_rms_um, strict=True))
        setup.gain = (gain, gain_se, gain_cv)
        return (self.gain_physical(gain, gain_se) and explains
                and gain_cv.rms_um <= (1 - s.min_improvement) * setup.baseline_rms
                and wins >= math.ceil(s.min_fold_share * len(setup.folds)))

    def gain_physical(self, gain: float, gain_se: float) -> bool:
        s = self.settings
        return s.gain_range[0] <= gain <= s.gain_range[1] and abs(gain - 1) >= max(s.min_gain_departure, 3 * gain_se)

    def prefer(self, recalibrate: Path, with_gain: Path) -> tuple[Path, str]:
        """A gain error is a claim about a gauge or a scale. It is named only if it stays physical
        once the other effects are in, and explains the mismatch better than recalibrating the model
        and naming the physics does (or as well, when recalibration finds no physics, or when the
        model has a single coefficient, whose refit *is* a gain)."""
        s, setup = self.settings, self.baseline
        final = with_gain.final
        joint_gain, joint_se = (float(final.coefficients[0]), float(final.standard_errors[0])) \
            if final is not None else (math.nan, math.nan)
        cv_gain, cv_recal = with_gain.base_cv.rms_um, recalibrate.base_cv.rms_um
        alternative = Alternative(words.recalibration_label([d.effect for d in recalibrate.discovered]),
                                  round(cv_recal, 4))
        found = [d.effect for d in recalibrate.discovered]
        if not self.gain_physical(joint_gain, joint_se):
            why = words.gain_withdrawn_words(joint_gain, *s.gain_range)
            return recalibrate, explain.recalibration_words(found, setup.calibrated_here, why)
        single = setup.base_design.shape[1] <= 1
        if single or not recalibrate.discovered or cv_gain < (1 - s.equivalence) * cv_recal:
            if not single:  # with one coefficient, recalibration is the same model as the gain
                with_gain.discovered[0].evidence.equivalent = [alternative]
            preferred = words.gain_preferred_words(single, bool(recalibrate.discovered), cv_gain, cv_recal)
            with_gain.discovered[0].evidence.preferred = preferred
            return with_gain, preferred
        why = words.gain_set_aside_words(joint_gain, cv_gain, cv_recal, s.equivalence)
        for record in recalibrate.discovered:
            evidence = record.evidence
            assert isinstance(evidence, Evidence)  # the recalibrated path names no gain
            evidence.note = words.GAIN_SET_ASIDE
        if recalibrate.discovered:
            recalibrate.discovered[0].evidence.equivalent.append(
                Alternative("gain_error", round(cv_gain, 4), gain=round(joint_gain, 5)))
        return recalibrate, explain.recalibration_words(found, setup.calibrated_here, why)
