"""The admission tests: every guard against false discovery (docs/thermal.md) with its figure, on one
effect or on a move of two as a whole, and the choices among those that pass (equivalent
explanations resolved to the simplest, a time constant earning its place)."""

from __future__ import annotations

import math

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.model.terms import Term

from . import selection_words as words
from . import shapes
from .library import Library, bounded, extends, time_constants
from .records import Baseline, Evaluation, Guard, Move, Path
from .run_figures import RunFigures
from .settings import Settings


def runs_improve(before_ms: np.ndarray, after_ms: np.ndarray, level: float, min_share: float,
                 min_runs: int = 10) -> bool:
    """Do the runs improve, as paired samples (each run's held-out mean squared error before and
    after)? The one-sided Wilcoxon signed-rank test at ``level``; with fewer than ``min_runs`` runs
    (a few days of data: the test could hardly reach the level with one run not improving), or too
    few to reach it at all, ``min_share`` of the runs must improve."""
    before_ms, after_ms = np.asarray(before_ms), np.asarray(after_ms)
    if not paired_test_applies(len(before_ms), level, min_runs):
        return int(np.sum(after_ms < before_ms)) >= math.ceil(min_share * len(before_ms))
    return stats.paired_improvement_p(before_ms, after_ms) <= level


def paired_test_applies(runs: int, level: float, min_runs: int) -> bool:
    """Enough runs for the paired test: at least ``min_runs``, and enough to reach ``level`` at all."""
    return runs >= min_runs and 0.5 ** runs <= level


def t_critical(alpha: float, tests: int, dof: int) -> float:
    """Two-sided Student-t at ``alpha`` / ``tests`` (Bonferroni): short records need the t tail."""
    from scipy.stats import t as student_t

    return float(student_t.isf(alpha / (2 * max(tests, 1)), max(dof, 1)))


class Admission:
    def __init__(self, library: Library, settings: Settings, baseline: Baseline) -> None:
        self.library = library
        self.settings = settings
        self.baseline = baseline
        self.runs = RunFigures(library, settings, baseline)
        # Several runs: how many candidates of the round reach the runs' paired test (its correction).
        self.paired_tests = 1

    @property
    def per_run(self) -> bool:
        return len(self.library.problem.runs) > 1

    @property
    def paired_runs(self) -> bool:
        """Enough runs for the runs' paired test (``runs_improve``) to carry admission."""
        return len(self.library.problem.runs) >= max(self.settings.runs_test_min, 2)

    @property
    def bar(self) -> float:
        """The relative drop of the held-out figure an effect must reach: ``min_improvement``; with
        enough runs for the paired test, ``runs_min_improvement`` (the test carries the evidence that
        the bar carries for blocks of one record; the bar keeps out what is too small to matter)."""
        s = self.settings
        return s.runs_min_improvement if self.paired_runs else s.min_improvement

    def heldout_gain(self, cv: stats.CrossValidation, base_cv: stats.CrossValidation,
                     runs_with: np.ndarray | None = None) -> float:
        """The relative drop of the held-out figure admission rests on: pooled RMS for one recording;
        with several runs, the median over runs of each run's held-out RMS (the few largest runs
        dominate a pooled figure)."""
        return self.heldout_figures(cv, base_cv, runs_with)[2]

    def runs_guard(self, cv: stats.CrossValidation, base_cv: stats.CrossValidation,
                   runs_with: np.ndarray | None) -> Guard:
        """Several runs: the runs' held-out mean squared errors, before and after, as pairs. The
        paired test (``stats.paired_improvement_p``) at ``runs_alpha`` / ``paired_tests``: a term that
        helps most runs a little and a few a lot passes, one that helps one run a lot and hurts many
        does not. With fewer than ``runs_test_min`` runs (or too few to reach the level at all) the
        share of runs that improve decides, as for the blocks of one run (``runs_improve``)."""
        s = self.settings
        before = np.square(np.asarray(base_cv.fold_rms_um))
        after = np.square(np.asarray(cv.fold_rms_um))
        if runs_with is not None:
            before, after = before[runs_with], after[runs_with]
        level = s.runs_alpha / max(self.paired_tests, 1)
        passes = runs_improve(before, after, level, s.min_fold_share, s.runs_test_min)
        if not paired_test_applies(len(before), level, s.runs_test_min):
            improved, need = int(np.sum(after < before)), math.ceil(s.min_fold_share * len(before))
            return Guard("runs improved", passes, words.improved_words(improved, len(before), "runs", need))
        p = stats.paired_improvement_p(before, after)
        return Guard("paired test", passes, words.paired_test_words(p, level, s.runs_alpha, self.paired_tests))

    def heldout_figures(self, cv: stats.CrossValidation, base_cv: stats.CrossValidation,
                        runs_with: np.ndarray | None = None) -> tuple[float, float, float, str]:
        """(before, after, relative drop, what the figure is): the held-out figure admission rests on
        (``heldout_gain``), for words that must follow it."""
        if self.per_run:
            (before, after), figure = self.runs.run_medians(cv, base_cv, runs_with), words.MEDIAN_OVER_RUNS
        else:
            # Beat both the current model (refitted) and the model exactly as given: refitting a right
            # model on autocorrelated data can make it worse, and a candidate must not win by undoing that.
            before, after, figure = min(base_cv.rms_um, self.baseline.given_heldout_um), cv.rms_um, words.HELD_OUT
        return before, after, 1.0 - after / before if before > 0 else 0.0, figure

    def guards(self, cv: stats.CrossValidation, fold_wins: int, runs_with: np.ndarray | None,
               t_values: tuple[float, ...], terms: tuple[Term, ...], base_cv: stats.CrossValidation,
               t_crit: float, *, paired: bool = True, cancels: str = "", weigh: bool = True) -> list[Guard]:
        """Every guard's figure and verdict, on a single effect or on a move of two as a whole; the
        held-out bar is the last. Admission and its words both read these (words follow the figures).
        ``paired=False`` leaves out the runs' paired test (to count the candidates it is corrected over).
        ``cancels``: why the terms cancel a named one (``fits.cancelling``): what a machine cannot have.
        ``weigh=False``: the held-out bar unweighed by the term's parameters (what the paired test is
        corrected over must not depend on the weighing)."""
        s = self.settings
        out: list[Guard] = []
        if self.per_run:
            if paired:
                out.append(self.runs_guard(cv, base_cv, runs_with))
        else:
            folds = len(base_cv.fold_rms_um)
            need = math.ceil(s.min_fold_share * folds)
            out.append(Guard("blocks improved", fold_wins >= need, words.improved_words(fold_wins, folds, "blocks", need)))
        counted = len(base_cv.fold_rms_um) if runs_with is None else int(np.sum(runs_with))
        judged_by_pairs = self.per_run and counted >= s.runs_test_min
        if not (judged_by_pairs and s.runs_replace_t_test):
            # Only where the runs' paired test judges this candidate (enough runs have its columns).
            out.append(Guard("t-test", all(abs(t) >= t_crit for t in t_values), words.t_test_words(t_values, t_crit)))
        physical = all(bounded(term) for term in terms)
        cannot = "; ".join([why for term in terms
                            if (why := term.spec.cannot_have(term.parameters, term.coefficient, s.structure))]
                           + ([cancels] if cancels else []))
        out.append(Guard("physical", physical and not cannot, words.physical_words(physical, cannot)))
        if self.per_run:  # ... and it must not leave the worst run worse
            figures = self.runs.run_figures(cv, base_cv, runs_with)
            limit = (1 + s.equivalence) * figures.worst_before_um
            # No run made worse in silence (issue 51): none beyond the harm tolerance either.
            counted = np.ones(len(cv.fold_rms_um), dtype=bool) if runs_with is None else np.asarray(runs_with)
            harmed = [self.library.problem.runs[i].name for i in self.runs.harms_runs(
                self.runs.reference_folds(base_cv), cv.fold_rms_um) if counted[i]]
            out.append(Guard("worst run", figures.worst_after_um <= limit, words.worst_run_words(
                figures.worst_run, figures.worst_before_um, figures.worst_after_um, limit, "")))
            # A term that harms runs is first tried fitted apart over two groups of runs (the search's
            # fit_apart: issue 42's light days, on which its sensor tells a coolant pump's cycling more
            # than the structure); refused when it cannot be only with Settings.run_harm_refuses.
            out.append(Guard(words.HARM, not harmed or not s.run_harm_refuses,
                             words.harm_guard_words(harmed, s.run_harm_share, s.run_harm_floor_um,
                                                    s.run_harm_refuses)))
        before_um, after_um, gain, figure = self.heldout_figures(cv, base_cv, runs_with)
        # A candidate only a few runs can judge (its columns missing in the others) clears the bar of a few.
        bar = self.bar if judged_by_pairs or not self.per_run else s.min_improvement
        if judged_by_pairs and s.runs_bar_per_parameter and len(terms) == 1 and weigh:
            # The paired test is corrected over candidates, not over the values of a time constant
            # tried (as the t-test was): each parameter of the term buys its own share (a move of two
            # is judged over either of its terms alone instead).
            bar = shapes.parameter_bar(bar, shapes.parameters_of(terms[0]))
        out.append(Guard("held-out", gain >= bar,
                         words.heldout_words(figure, before_um, after_um, gain, bar, self.bar, terms), round(gain, 4)))
        return out

    def judge(self, cv: stats.CrossValidation, fold_wins: int, runs_with: np.ndarray | None,
              t_values: tuple[float, ...], terms: tuple[Term, ...], base_cv: stats.CrossValidation,
              t_crit: float, *, paired: bool = True, cancels: str = "") -> tuple[bool, bool]:
        """(passes every guard, passes every guard but the held-out bar and still lowers the held-out
        figure by ``likely_min_improvement``)."""
        return self.verdict(self.guards(cv, fold_wins, runs_with, t_values, terms, base_cv, t_crit, paired=paired,
                                        cancels=cancels))

    def verdict(self, found: list[Guard]) -> tuple[bool, bool]:
        """``judge``'s answer from the guards' figures."""
        rest = all(g.passes for g in found[:-1])
        held_out = found[-1]
        return held_out.passes and rest, rest and held_out.gain >= self.settings.likely_min_improvement

    def _guards(self, evaluation: Evaluation, base_cv: stats.CrossValidation, t_crit: float,
                paired: bool = True, weigh: bool = True) -> tuple[bool, bool]:
        """(passes every guard, passes every guard but the held-out bar)."""
        return self.verdict(self.guards_of(evaluation, base_cv, t_crit, paired=paired, weigh=weigh))

    def guards_of(self, evaluation: Evaluation, base_cv: stats.CrossValidation, t_crit: float,
                  paired: bool = True, weigh: bool = True) -> list[Guard]:
        term = evaluation.candidate.term.with_coefficient(evaluation.coefficient)
        return self.guards(evaluation.cv, evaluation.fold_wins, evaluation.candidate.runs_with,
                           (evaluation.t_value,), (term,), base_cv, t_crit, paired=paired,
                           cancels=evaluation.cancelling, weigh=weigh)

    def passes(self, evaluation: Evaluation, base_cv: stats.CrossValidation, t_crit: float) -> bool:
        return self._guards(evaluation, base_cv, t_crit)[0]

    def count_paired_tests(self, evaluations: list[Evaluation], base_cv: stats.CrossValidation,
                           t_crit: float) -> None:
        """The runs' paired test is corrected over the candidates that reach it: those that pass every
        other guard, the held-out bar included, unweighed by their parameters. Weighed, a stricter bar
        left fewer candidates to correct over, and a weak single term then passed the paired test in a
        round where, corrected as before, none did and a move of two was found (``fl_thermal`` ch5 cut
        into 14 runs: one gradient at -29 um/K and nothing after it, median over runs 2.984 um against
        1.190 um)."""
        if self.per_run:
            self.paired_tests = max(1, sum(self._guards(e, base_cv, t_crit, paired=False, weigh=False)[0]
                                           for e in evaluations))

    def margin(self, *evaluations: Evaluation) -> float:
        """Held-out RMS within this share is "as good": a time constant is picked on the whole record,
        so the held-out RMS of an effect that has one is optimistic; one more share per time constant."""
        return self.settings.equivalence * (1 + max(time_constants(e.candidate.term) for e in evaluations))

    def equivalent(self, passing: list[Evaluation], fitting: list[Evaluation] = ()  # type: ignore[assignment]
                   ) -> tuple[Evaluation, float, list[Evaluation]]:
        """The best candidate on held-out RMS without the sensors' noise, its margin, and the candidates
        within that margin of it.

        Removing the noise may make up for it within the margin of equivalence, not beyond. Near-collinear
        effects (a gradient of two sensors and a lag of a third all follow the spindle's load) fit the
        shape alike, and then the sensors' noise is all the record tells them apart by. A candidate
        that predicts the gauge worse than another as measured, and whose features carry more of the
        noise than the pair's margin (a large coefficient on raw readings: held-out RMS with / without
        the noise), ranks where it does on the correction, not on the record: it is set aside, also
        against ``fitting`` candidates that were held back only by what a machine can have or by the bar
        for their extra parameters (they still show what the record carries). The best as measured of
        ``passing`` always stays."""
        def carried(e: Evaluation) -> float:
            return e.cv.rms_um / e.ranked_rms_um if e.ranked_rms_um > 0 else math.inf

        against = passing + [e for e in fitting if e not in passing]
        pool = [e for e in passing
                if not any(other.cv.rms_um < e.cv.rms_um
                           and carried(e) > (1 + self.margin(e, other)) * carried(other) for other in against)] \
            or [min(passing, key=lambda e: e.cv.rms_um)]
        best = min(pool, key=lambda e: e.ranked_rms_um)
        margin = self.margin(best)
        return best, margin, [e for e in pool if e.ranked_rms_um <= best.ranked_rms_um * (1 + margin)]

    def time_constant_guard(self, evaluation: Evaluation, evaluations: list[Evaluation],
                            passing: list[Evaluation]) -> Guard | None:
        """Has an effect with a time constant earned it over the simpler effect of its sensor, when that
        simpler one does not pass on its own? Within the held-out bar of it, the time constant adds
        nothing the data show (a lag of 4 min of a sensor averaged over 5 is the sensor): neither is
        named, and the round goes on as if nothing passed (a pair may). A simpler one that passes is
        ``parsimonious``'s to pick. Judged on the figure the bar is on: with several runs the median
        over runs of held-out RMS, on one record held-out RMS without the sensors' noise. None when the
        effect extends nothing among the round's candidates."""
        # extends first: it is cheap, and `not in` compares evaluations field by field against every one
        # that passes (a million comparisons in one discovery of FL_THERMAL's sixteen sensors).
        simpler = [e for e in evaluations if extends(evaluation.candidate.term, e.candidate.term) and e not in passing]
        if not simpler:
            return None

        def figure(e: Evaluation) -> float:
            return float(np.median(e.cv.fold_rms_um)) if self.per_run else e.ranked_rms_um

        other = min(simpler, key=figure)
        gain = 1.0 - figure(evaluation) / figure(other) if figure(other) > 0 else 0.0
        what = words.MEDIAN_OVER_RUNS if self.per_run else words.WITHOUT_NOISE
        return Guard("time constant", gain >= self.bar, words.time_constant_words(
            other.candidate.label, what, figure(other), figure(evaluation), gain, self.bar), round(gain, 4))

    def earned(self, evaluation: Evaluation, evaluations: list[Evaluation], passing: list[Evaluation]) -> bool:
        guard = self.time_constant_guard(evaluation, evaluations, passing)
        return guard is None or guard.passes

    def parsimonious(self, chosen: Evaluation, passing: list[Evaluation]) -> Evaluation:
        """An effect that extends a simpler one of the same sensor by a time constant (a lag extends a
        plain temperature term, an asymmetric lag a lag) must earn that parameter as an effect earns
        its place: by the held-out bar (``bar``) over the simpler one, or the simpler wins."""
        while True:
            simpler = [e for e in passing if extends(chosen.candidate.term, e.candidate.term)
                       and chosen.ranked_rms_um > (1 - self.bar) * e.ranked_rms_um]
            if not simpler:
                return chosen
            chosen = min(simpler, key=lambda e: e.ranked_rms_um)

    def withdrawal_bar(self, term: Term, extra_parameters: int = 0) -> float:
        """What a named term must still be worth at the end: the held-out bar, weighed by its
        parameters as admission weighs them (``Settings.runs_bar_per_parameter``); a term fitted apart
        over groups of runs has ``extra_parameters`` (its other group's coefficient)."""
        if not self.settings.withdraw_per_parameter:
            return self.bar
        return shapes.parameter_bar(self.bar, shapes.parameters_of(term) + extra_parameters)

    def move_passes(self, path: Path, move: Move, t_crit: float, *, over: Evaluation | None = None,
                    paired: bool = True) -> bool:
        """A move passes every guard as a whole and clears the held-out bar over either of its effects
        alone, and over ``over`` (the effect the round chose, which the move would replace)."""
        return self.judge(move.cv, move.fold_wins, move.runs_with, move.t_values, move.terms, path.base_cv,
                          t_crit, paired=paired, cancels=move.cancelling)[0] \
            and all(self.heldout_gain(move.cv, other.cv, move.runs_with) >= self.bar
                    for other in ((over, *move.alone) if over is not None else move.alone))
