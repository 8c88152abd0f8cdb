"""The selector: a forward search that adds one named effect a round, under the guards against
false discovery (docs/thermal.md): held-out RMS, folds improved, an autocorrelation-corrected
t-test Bonferroni-corrected over the round, physical parameters, equivalent explanations resolved
to the simplest, a time constant earning its place, and a common gain named only when physical.

It sees matrices only: the gauge samples ``y``, the baseline's columns, the held-out masks of a
splitter, and the candidate library. Blocks of one run and runs of a machine are alike to it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.model import families
from nckemu.thermal.model.families import Family
from nckemu.thermal.model.terms import Term

from . import explain, shapes
from .findings import (
    AdmissionRuns,
    Alternative,
    Evidence,
    Finding,
    GainEvidence,
    MoveAlternative,
    MoveEvidence,
    Withdrawn,
    finding,
)
from .library import Candidate, Library, bounded, extends, present_key, time_constants
from .settings import Settings


@dataclass
class Evaluation:
    candidate: Candidate
    cv: stats.CrossValidation
    t_value: float
    coefficient: float
    fold_wins: int
    # Held-out RMS without the sensors' noise carried by the fitted model's features: what candidates
    # are ranked on (held-out RMS itself still decides whether one is admitted at all).
    ranked_rms_um: float
    # RMS of the part of the feature the design does not already hold (for the detectable size).
    own_rms: float = math.nan


@dataclass(frozen=True)
class Guard:
    """One guard against false discovery as a candidate stands against it: its figure in words and
    whether it passes (``gain``: the held-out bar's relative drop)."""
    name: str
    passes: bool
    figure: str
    gain: float = math.nan


@dataclass
class Move:
    """Two effects judged as one move, tried when no single effect passes: physics that comes in pairs
    (a temperature and its lag, two sensors of one gradient) may show only together."""
    alone: tuple[Evaluation, Evaluation]    # each effect on its own, from the round's evaluations
    cv: stats.CrossValidation
    t_values: tuple[float, float]
    coefficients: tuple[float, float]
    fold_wins: int
    ranked_rms_um: float
    runs_with: np.ndarray | None            # runs that have the columns of both (None: all)
    # Each effect's share of what the move improves: how much the held-out figure rises without it.
    shares: tuple[float, float] = (math.nan, math.nan)

    @property
    def terms(self) -> tuple[Term, Term]:
        return (self.alone[0].candidate.term.with_coefficient(self.coefficients[0]),
                self.alone[1].candidate.term.with_coefficient(self.coefficients[1]))

    @property
    def label(self) -> str:
        return " + ".join(e.candidate.label for e in self.alone)


@dataclass
class Baseline:
    """What every search path shares: the baseline's columns, the folds and the baseline's figures."""
    base_design: np.ndarray
    given: np.ndarray
    folds: list[np.ndarray]
    baseline_rms: float
    recalibrated: stats.Fit | None
    recalibrated_rms: float
    given_cv: stats.CrossValidation
    recal_cv: stats.CrossValidation
    calibrated_here: bool
    base_noise: np.ndarray          # sensor noise carried by base_design's columns
    given_noise: np.ndarray         # ... and by the model as given
    # Columns fitted besides the design that every fit carries (one offset per run): degrees of freedom.
    extra_parameters: int = 0
    # How held-out RMS is computed for the folds (several runs: through each fold's normal equations).
    cross_validate: Callable[[np.ndarray, np.ndarray, list[np.ndarray]], stats.CrossValidation] = \
        stats.cross_validate
    gain: tuple[float, float, stats.CrossValidation] = (math.nan, math.nan, stats.CrossValidation(math.nan, ()))

    @property
    def given_heldout_um(self) -> float:
        """The model as given is held-out data only when it was not calibrated on this record."""
        return math.inf if self.calibrated_here else self.baseline_rms

    @property
    def reference_cv(self) -> stats.CrossValidation:
        """The like-for-like baseline: refitted per fold, or as given when that predicts better."""
        return self.recal_cv if self.recal_cv.rms_um <= self.given_heldout_um else self.given_cv


@dataclass
class Path:
    """One line of explanation: the recalibrated model plus effects, or gain x model plus effects."""
    gain_mode: bool
    design: np.ndarray
    base_cv: stats.CrossValidation
    noise: np.ndarray               # sensor noise carried by each column of design
    discovered: list[Finding] = field(default_factory=list)
    added: list[Term] = field(default_factory=list)
    present: set[str] = field(default_factory=set)
    final: stats.Fit | None = None
    # The last round's candidates, none of which passed, and its critical t: what "nothing more"
    # rests on (the smallest detectable effects, a term that is likely but not proven).
    rejected: list[Evaluation] = field(default_factory=list)
    rejected_t_critical: float = math.nan
    rejected_paired_tests: int = 1     # ... and how many candidates the runs' paired test was corrected over
    # Terms named in a round and withdrawn at the end: the terms named after them explain what they did.
    withdrawn: list[Withdrawn] = field(default_factory=list)
    # The search stopped at Settings.max_effects: the last round's candidates were surveyed, not judged.
    at_limit: bool = False
    # Candidates that passed every guard but what a machine can have: (label, term, guards).
    cannot_have: list[tuple[str, Term, list[Guard]]] = field(default_factory=list)
    # The last round's candidates with every guard's figure, judged once (``Selector.judged``).
    judged: list[tuple[Evaluation, list[Guard]]] | None = None


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


CANNOT_HAVE = "fits, but a machine cannot have it"


def percent(share: float) -> str:
    """A share in percent: whole when it is whole (5%), else to a tenth (9.8%)."""
    return f"{share:.0%}" if abs(share * 100 - round(share * 100)) < 1e-9 else f"{share:.1%}"


def per_parameter_words(bar: float, one: float, terms: tuple[Term, ...]) -> str:
    """Where a bar is weighed by the term's parameters, how."""
    if len(terms) != 1 or abs(bar - one) < 1e-12:
        return ""
    return f" ({percent(one)} for each of its {shapes.parameters_of(terms[0])} parameters)"


def t_critical(alpha: float, tests: int, dof: int) -> float:
    """Two-sided Student-t at ``alpha`` / ``tests`` (Bonferroni): short records need the t tail."""
    from scipy.stats import t as student_t

    return float(student_t.isf(alpha / (2 * max(tests, 1)), max(dof, 1)))


class Selector:
    def __init__(self, y: np.ndarray, t_s: np.ndarray, library: Library, settings: Settings,
                 baseline: Baseline) -> None:
        self.y = y
        self.t_s = t_s
        self.library = library
        self.settings = settings
        self.baseline = baseline
        # Several runs: how many candidates of the round reach the runs' paired test (its correction).
        self.paired_tests = 1

    # ------------------------------------------------------------------ one candidate
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

    def heldout_gain(self, cv: stats.CrossValidation, base_cv: stats.CrossValidation,
                     runs_with: np.ndarray | None = None) -> float:
        """The relative drop of the held-out figure admission rests on: pooled RMS for one recording;
        with several runs, the median over runs of each run's held-out RMS (the few largest runs
        dominate a pooled figure)."""
        if self.per_run:
            reference, after = self.run_medians(cv, base_cv, runs_with)
            return 1.0 - after / reference if reference > 0 else 0.0
        # Beat both the current model (refitted) and the model exactly as given: refitting a right
        # model on autocorrelated data can make it worse, and a candidate must not win by undoing that.
        reference_um = min(base_cv.rms_um, self.baseline.given_heldout_um)
        return 1.0 - cv.rms_um / reference_um if reference_um > 0 else 0.0

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
            return Guard("runs improved", passes, f"{improved} of {len(before)} runs improve (at least {need} must)")
        p = stats.paired_improvement_p(before, after)
        return Guard("paired test", passes,
                     f"the runs' paired test gives p = {p:.2g} (level {level:.2g}, {s.runs_alpha:g} over "
                     f"{max(self.paired_tests, 1)} candidate{'s' if self.paired_tests > 1 else ''})")

    def heldout_figures(self, cv: stats.CrossValidation, base_cv: stats.CrossValidation,
                        runs_with: np.ndarray | None = None) -> tuple[float, float, float, str]:
        """(before, after, relative drop, what the figure is): the held-out figure admission rests on
        (``heldout_gain``), for words that must follow it."""
        gain = self.heldout_gain(cv, base_cv, runs_with)
        if self.per_run:
            return (*self.run_medians(cv, base_cv, runs_with), gain, "the median over runs of held-out RMS")
        return min(base_cv.rms_um, self.baseline.given_heldout_um), cv.rms_um, gain, "held-out RMS"

    def guards(self, cv: stats.CrossValidation, fold_wins: int, runs_with: np.ndarray | None,
               t_values: tuple[float, ...], terms: tuple[Term, ...], base_cv: stats.CrossValidation,
               t_crit: float, *, paired: bool = True) -> list[Guard]:
        """Every guard's figure and verdict, on a single effect or on a move of two as a whole; the
        held-out bar is the last. Admission and its words both read these (words follow the figures).
        ``paired=False`` leaves out the runs' paired test (to count the candidates it is corrected over)."""
        s = self.settings
        out: list[Guard] = []
        if self.per_run:
            if paired:
                out.append(self.runs_guard(cv, base_cv, runs_with))
        else:
            folds = len(base_cv.fold_rms_um)
            need = math.ceil(s.min_fold_share * folds)
            out.append(Guard("blocks improved", fold_wins >= need,
                             f"{fold_wins} of {folds} blocks improve (at least {need} must)"))
        counted = len(base_cv.fold_rms_um) if runs_with is None else int(np.sum(runs_with))
        judged_by_pairs = self.per_run and counted >= s.runs_test_min
        if not (judged_by_pairs and s.runs_replace_t_test):
            # Only where the runs' paired test judges this candidate (enough runs have its columns).
            t_words = ", ".join(f"{t:.2f}" for t in t_values)
            out.append(Guard("t-test", all(abs(t) >= t_crit for t in t_values),
                             f"t = {t_words} (critical {t_crit:.2f})"))
        physical = all(bounded(term) for term in terms)
        cannot = "; ".join(why for term in terms
                           if (why := term.spec.cannot_have(term.parameters, term.coefficient, s.structure)))
        out.append(Guard("physical", physical and not cannot,
                         "parameters outside what a machine can have" if not physical else
                         f"{CANNOT_HAVE}: {cannot}" if cannot else "parameters a machine can have"))
        if self.per_run:  # ... and it must not leave the worst run worse
            figures = self.run_figures(cv, base_cv, runs_with)
            limit = (1 + s.equivalence) * figures.worst_before_um
            # No run made worse in silence (issue 51): none beyond the harm tolerance either.
            counted = np.ones(len(cv.fold_rms_um), dtype=bool) if runs_with is None else np.asarray(runs_with)
            harmed = [self.library.problem.runs[i].name for i in self.harms_runs(
                self.reference_folds(base_cv), cv.fold_rms_um) if counted[i]]
            harm_words = (f"; {len(harmed)} run{'s' if len(harmed) > 1 else ''} worse by more than "
                          f"{s.run_harm_share:.0%} and {s.run_harm_floor_um:g} um: {', '.join(harmed[:4])}"
                          f"{', ...' if len(harmed) > 4 else ''}" if harmed else "")
            # Named, not refused: a term that helps heavy days much and leaves light days a little worse
            # (issue 42's duty mix) stays admissible; the words name the runs it harms.
            out.append(Guard("worst run", figures.worst_after_um <= limit,
                             f"the worst run ({figures.worst_run}) {figures.worst_before_um:.3f} -> "
                             f"{figures.worst_after_um:.3f} um (at most {limit:.3f}){harm_words}"))
        before_um, after_um, gain, figure = self.heldout_figures(cv, base_cv, runs_with)
        # A candidate only a few runs can judge (its columns missing in the others) clears the bar of a few.
        bar = self.bar if judged_by_pairs or not self.per_run else s.min_improvement
        if judged_by_pairs and s.runs_bar_per_parameter and len(terms) == 1:
            # The paired test is corrected over candidates, not over the values of a time constant
            # tried (as the t-test was): each parameter of the term buys its own share (a move of two
            # is judged over either of its terms alone instead).
            bar = shapes.parameter_bar(bar, shapes.parameters_of(terms[0]))
        out.append(Guard("held-out", gain >= bar,
                         f"{figure} {before_um:.3f} -> {after_um:.3f} um ({gain:.1%}; the bar is {percent(bar)})"
                         f"{per_parameter_words(bar, self.bar, terms)}", round(gain, 4)))
        return out

    def judge(self, cv: stats.CrossValidation, fold_wins: int, runs_with: np.ndarray | None,
              t_values: tuple[float, ...], terms: tuple[Term, ...], base_cv: stats.CrossValidation,
              t_crit: float, *, paired: bool = True) -> tuple[bool, bool]:
        """(passes every guard, passes every guard but the held-out bar and still lowers the held-out
        figure by ``likely_min_improvement``)."""
        found = self.guards(cv, fold_wins, runs_with, t_values, terms, base_cv, t_crit, paired=paired)
        rest = all(g.passes for g in found[:-1])
        held_out = found[-1]
        return held_out.passes and rest, rest and held_out.gain >= self.settings.likely_min_improvement

    def _guards(self, evaluation: Evaluation, base_cv: stats.CrossValidation, t_crit: float,
                paired: bool = True) -> tuple[bool, bool]:
        """(passes every guard, passes every guard but the held-out bar)."""
        term = evaluation.candidate.term.with_coefficient(evaluation.coefficient)
        return self.judge(evaluation.cv, evaluation.fold_wins, evaluation.candidate.runs_with,
                          (evaluation.t_value,), (term,), base_cv, t_crit, paired=paired)

    def guards_of(self, evaluation: Evaluation, base_cv: stats.CrossValidation, t_crit: float) -> list[Guard]:
        term = evaluation.candidate.term.with_coefficient(evaluation.coefficient)
        return self.guards(evaluation.cv, evaluation.fold_wins, evaluation.candidate.runs_with,
                           (evaluation.t_value,), (term,), base_cv, t_crit)

    def passes(self, evaluation: Evaluation, base_cv: stats.CrossValidation, t_crit: float) -> bool:
        return self._guards(evaluation, base_cv, t_crit)[0]

    def count_paired_tests(self, evaluations: list[Evaluation], base_cv: stats.CrossValidation,
                           t_crit: float) -> None:
        """The runs' paired test is corrected over the candidates that reach it: those that pass every
        other guard, the held-out bar included."""
        if self.per_run:
            self.paired_tests = max(1, sum(self._guards(e, base_cv, t_crit, paired=False)[0] for e in evaluations))

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
        simpler = [e for e in evaluations if e not in passing and extends(evaluation.candidate.term, e.candidate.term)]
        if not simpler:
            return None

        def figure(e: Evaluation) -> float:
            return float(np.median(e.cv.fold_rms_um)) if self.per_run else e.ranked_rms_um

        other = min(simpler, key=figure)
        gain = 1.0 - figure(evaluation) / figure(other) if figure(other) > 0 else 0.0
        what = "the median over runs of held-out RMS" if self.per_run else "held-out RMS without the sensors' noise"
        return Guard("time constant", gain >= self.bar,
                     f"its time constant against {other.candidate.label}: {what} {figure(other):.3f} -> "
                     f"{figure(evaluation):.3f} um ({gain:.1%}; the bar is {self.bar:.0%})", round(gain, 4))

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

    # ------------------------------------------------------------------ the search
    def search(self, gain_mode: bool) -> Path:
        """Add effects one round at a time to the recalibrated model (or to gain x the model as given)."""
        setup = self.baseline
        if gain_mode:
            gain, gain_se, gain_cv = setup.gain
            path = Path(True, setup.given[:, None], gain_cv, setup.given_noise[:, None])
            path.present.add("gain_error")
            path.discovered.append(Finding("gain_error", {"gain": round(gain, 5)}, GainEvidence(
                round(setup.baseline_rms, 4), round(gain_cv.rms_um, 4), round(setup.baseline_rms, 4),
                round(gain_se, 5), [], "one common factor on the whole model explains the mismatch")))
        else:
            path = Path(False, setup.base_design, setup.recal_cv, setup.base_noise)
        if self.library.problem.per_run_offset:
            path.present.add("offset")  # each run's own offset is in the baseline
        for _round in range(self.settings.max_effects):
            if len(path.added) >= self.settings.max_effects or not self.round(path):
                break
        path.at_limit = len(path.added) >= self.settings.max_effects
        self.name_shapes(path)
        if self.paired_runs:
            self.withdraw_redundant(path)
        if path.at_limit:
            self.survey(path)
        path.final = stats.fit(path.design, self.y) if path.design.shape[1] else None
        self.twin_shares(path)
        return path

    def name_shapes(self, path: Path) -> None:
        """A sensor named with its temperature and its own lag is named as the shape the two make: the
        lag's column becomes the sensor's transient at the lag's time constant (the same span, the
        same held-out figures), and the temperature is the static part (``shapes``). Whether the
        static part earns its parameter is then the withdrawal's to judge."""
        offset = 1 if path.gain_mode else 0
        pairs = shapes.temperature_with_lag(path.added)
        if not pairs:
            return
        coefficients = stats.least_squares(path.design, self.y)
        first = path.design.shape[1] - len(path.added)
        design, noise = path.design.copy(), path.noise.copy()
        for temperature_index, lag_index in pairs:
            lag = path.added[lag_index]
            if not self.settings.second_time_constant_ratio and any(
                    t.effect == "transient_gradient" and t.parameters.get("sensor") == lag.parameters["sensor"]
                    for t in path.added):
                continue  # a sensor at one time constant only: its transient is named already
            candidate = self.library.candidate(shapes.as_transient(lag))
            record = path.discovered[lag_index + offset]
            if candidate is None or not isinstance(record.evidence, Evidence):
                continue
            column = first + lag_index
            design[:, column], noise[:, column] = candidate.feature, candidate.noise
            path.added[lag_index] = candidate.term
            path.present.add(present_key(candidate.term))
            record.evidence.note = shapes.shape_words(str(lag.parameters["sensor"]), float(lag.parameters["tau_s"]),
                                                      float(coefficients[column]),
                                                      float(coefficients[first + temperature_index]))
            path.discovered[lag_index + offset] = finding(candidate.term.effect, candidate.term.parameters,
                                                          record.evidence)
        path.design, path.noise = design, noise
        path.base_cv = self.baseline.cross_validate(path.design, self.y, self.baseline.folds)

    def withdrawal_bar(self, term: Term) -> float:
        """What a named term must still be worth at the end: the held-out bar, weighed by its
        parameters as admission weighs them (``Settings.runs_bar_per_parameter``)."""
        if not self.settings.withdraw_per_parameter:
            return self.bar
        return shapes.parameter_bar(self.bar, shapes.parameters_of(term))

    def harms_runs(self, before: tuple[float, ...], after: tuple[float, ...]) -> list[int]:
        """The runs ``after`` leaves worse than ``before`` by more than ``run_harm_share`` and by more
        than ``run_harm_floor_um``."""
        s = self.settings
        return [index for index, (b, a) in enumerate(zip(before, after, strict=True))
                if a > b * (1 + s.run_harm_share) and a > b + s.run_harm_floor_um]

    def withdraw_redundant(self, path: Path) -> None:
        """With the runs' paired test and its lower bar, a term may pass in an early round and be
        explained by the terms named after it (a gradient of the rear and the ambient, then the rear's
        and the front's own temperatures; a second time constant that stood in for a temperature named
        later). Each term must still clear its bar (``withdrawal_bar``) over the others: without it,
        the median over runs of held-out RMS must rise by the bar, the worst run by the margin of
        equivalence, or some run by more than the harm tolerance. The one that matters least is
        withdrawn, and the rest are judged again; a term of a move whose partner goes stays, alone."""
        s = self.settings
        offset = 1 if path.gain_mode else 0
        while True:
            weakest: tuple[float, int, stats.CrossValidation, list[int], float] | None = None
            for index in range(len(path.added)):
                record = path.discovered[index + offset].evidence
                if not isinstance(record, Evidence):
                    continue
                without, keep = self.without_added(path, index)
                median_with, median_without = (float(np.median(cv.fold_rms_um)) for cv in (path.base_cv, without))
                loss = 1.0 - median_with / median_without if median_without > 0 else 0.0
                worst_with, worst_without = max(path.base_cv.fold_rms_um), max(without.fold_rms_um)
                bar = self.withdrawal_bar(path.added[index]) if record.move is None or s.withdraw_per_parameter \
                    else -math.inf
                if loss < bar and worst_without <= (1 + s.equivalence) * worst_with \
                        and not self.harms_runs(path.base_cv.fold_rms_um, without.fold_rms_um) \
                        and (weakest is None or loss < weakest[0]):
                    weakest = (loss, index, without, keep, bar)
            if weakest is None:
                return
            loss, index, without, keep, bar = weakest
            term = path.added.pop(index)
            gone = path.discovered.pop(index + offset).evidence
            path.design, path.noise = path.design[:, keep], path.noise[:, keep]
            path.withdrawn.append(Withdrawn(
                term.effect, explain.label_with_time_constants(term), dict(term.parameters),
                f"the terms named after it explain what it did: without it the median over runs of held-out RMS "
                f"is {float(np.median(without.fold_rms_um)):.3f} um against {float(np.median(path.base_cv.fold_rms_um)):.3f} um "
                f"with it ({loss:.1%}; the bar is {percent(bar)}){per_parameter_words(bar, self.bar, (term,))}, "
                f"the worst run {max(without.fold_rms_um):.3f} um against {max(path.base_cv.fold_rms_um):.3f} um"))
            path.base_cv = without
            if isinstance(gone, Evidence) and gone.move is not None:
                self.leave_move(path, gone.move.terms, explain.label_with_time_constants(term))

    def leave_move(self, path: Path, members: list[str], withdrawn: str) -> None:
        """A term of a move was withdrawn: its partner stays as a term of its own, and says so."""
        for found in path.discovered:
            record = found.evidence
            if isinstance(record, Evidence) and record.move is not None and record.move.terms == members:
                record.move = None
                record.preferred = f"named in a move with {withdrawn}, which the later terms made redundant (withdrawn)"

    def without_added(self, path: Path, index: int) -> tuple[stats.CrossValidation, list[int]]:
        """The path's design without the column of ``path.added[index]``, cross-validated, and the
        columns kept."""
        column = path.design.shape[1] - len(path.added) + index
        keep = [c for c in range(path.design.shape[1]) if c != column]
        return self.baseline.cross_validate(path.design[:, keep], self.y, self.baseline.folds), keep

    def twin_shares(self, path: Path) -> None:
        """A sensor named at two time constants in two rounds (the second found once another term was
        in): each one's share, as for a move of two, of what the two improve together: how much the
        held-out figure rises without it."""
        groups: dict[tuple[str, object], list[int]] = {}
        for index, term in enumerate(path.added):
            if time_constants(term) and term.parameters.get("sensor") is not None:
                groups.setdefault((term.effect, term.parameters["sensor"]), []).append(index)
        for indices in groups.values():
            records = [path.discovered[i + (1 if path.gain_mode else 0)].evidence for i in indices]
            if len(indices) != 2 or any(not isinstance(r, Evidence) or r.move is not None for r in records):
                continue
            lost = [max(self.heldout_gain(path.base_cv, self.without_added(path, index)[0]), 0.0)
                    for index in indices]
            total = sum(lost)
            for record, part in zip(records, lost, strict=True):
                assert isinstance(record, Evidence)
                record.twin_share = round(part / total if total > 0 else 0.5, 4)

    def evaluate_round(self, path: Path) -> tuple[list[Evaluation], float, int] | None:
        """The round's candidates evaluated beside the path's design: (evaluations, critical t, the
        hypotheses it is corrected over); the runs' paired test counted over them. None: no candidate."""
        s, setup = self.settings, self.baseline
        design = path.design
        candidates = self.library.candidates(design if design.shape[1] else setup.given[:, None], path.present,
                                             tuple(path.added))
        if not candidates:
            return None
        # Bonferroni over every hypothesis of the round, each time constant tried included.
        tests = sum(c.grid_points for c in candidates)
        t_crit = t_critical(s.alpha, tests, len(self.y) - design.shape[1] - 1 - setup.extra_parameters)
        evaluations = [e for e in (self.evaluate(design, path.noise, c, path.base_cv) for c in candidates)
                       if self.twin_of_one_sign(path, e)]
        self.count_paired_tests(evaluations, path.base_cv, t_crit)
        return evaluations, t_crit, tests

    def survey(self, path: Path) -> None:
        """The search stopped at the limit: the next round's candidates, evaluated and not admitted, so
        the words can say what came closest and the detectable sizes can be given."""
        surveyed = self.evaluate_round(path)
        if surveyed is not None:
            path.rejected, path.rejected_t_critical, _tests = surveyed
            path.rejected_paired_tests = self.paired_tests

    def round(self, path: Path) -> bool:
        s, setup = self.settings, self.baseline
        folds = setup.folds
        design = path.design
        evaluated = self.evaluate_round(path)
        if evaluated is None:
            return False
        evaluations, t_crit, tests = evaluated
        single_paired_tests = self.paired_tests  # pair_round counts its moves' own
        passing = [e for e in evaluations if self.passes(e, path.base_cv, t_crit)]
        fitting = self.note_cannot_have(path, [e for e in evaluations if e not in passing], t_crit)
        passing = [e for e in passing if self.earned(e, evaluations, passing)]
        if not passing and s.pair_moves and len(path.added) + 2 <= s.max_effects \
                and self.pair_round(path, evaluations, tests):
            return True
        if not passing:
            path.rejected, path.rejected_t_critical = evaluations, t_crit
            path.rejected_paired_tests = single_paired_tests
            return False
        best, margin, equivalent = self.equivalent(passing, fitting)
        chosen = min(equivalent, key=lambda e: (e.candidate.term.spec.complexity, e.ranked_rms_um))
        chosen = self.parsimonious(chosen, passing)
        if self.time_constant_moves(path, chosen, design, tests):
            return True
        term = chosen.candidate.term.with_coefficient(chosen.coefficient)
        # Several runs share one clock from their own starts: a window in time names no run.
        window = [] if self.library.problem.per_run_offset else explain.locate(
            self.t_s, chosen.coefficient * (chosen.candidate.feature - np.median(chosen.candidate.feature)))
        record = explain.evidence(chosen, best, equivalent, margin, path.base_cv.rms_um, t_crit, len(folds),
                                  window[0][:2] if window else None, term.spec.description)
        if self.per_run:
            record.runs = self.run_figures(chosen.cv, path.base_cv, chosen.candidate.runs_with)
        path.discovered.append(finding(term.effect, term.parameters, record))
        path.added.append(term)
        path.present.add(present_key(term))
        path.design = np.column_stack([design, chosen.candidate.feature])
        path.noise = np.column_stack([path.noise, chosen.candidate.noise])
        path.base_cv = chosen.cv
        return True

    def note_cannot_have(self, path: Path, refused: list[Evaluation], t_crit: float) -> list[Evaluation]:
        """Candidates that pass every guard but what a machine can have: never named, listed with
        their figures ("fits, but a machine cannot have it"). Returns those, and those held back only
        by the bar for their extra parameters: candidates that fit."""
        fitting = []
        for evaluation in refused:
            label = explain.label_with_time_constants(evaluation.candidate.term)
            guards = self.guards_of(evaluation, path.base_cv, t_crit)
            failing = [g for g in guards if not g.passes]
            cannot = len(failing) == 1 and failing[0].figure.startswith(CANNOT_HAVE)
            if cannot or (len(failing) == 1 and failing[0] is guards[-1] and guards[-1].gain >= self.bar):
                fitting.append(evaluation)
            if cannot and not any(item[0] == label for item in path.cannot_have):
                term = evaluation.candidate.term.with_coefficient(evaluation.coefficient)
                path.cannot_have.append((label, term, guards))
        return fitting

    # ------------------------------------------------------------------ one sensor, two time constants
    def twin_of_one_sign(self, path: Path, evaluation: Evaluation) -> bool:
        """A sensor's second time constant, offered in a later round, moves the structure the same way
        as its first in the joint fit (a skin and a core of one structure heated from one side; two
        pulling apart are one band of time constants, not two paths of heat: ``split_move``)."""
        term = evaluation.candidate.term
        sensor = term.parameters.get("sensor")
        twins = [index for index, added in enumerate(path.added)
                 if added.effect == term.effect and added.parameters.get("sensor") == sensor
                 and time_constants(added) and sensor is not None]
        if not twins:
            return True
        full = np.column_stack([path.design, evaluation.candidate.feature])
        coefficients = stats.least_squares(full, self.y)
        first = path.design.shape[1] - len(path.added) + twins[0]
        return bool(coefficients[first] * coefficients[-1] > 0)

    def time_constant_moves(self, path: Path, chosen: Evaluation, design: np.ndarray, tests: int) -> bool:
        """The round names an effect with a time constant of one sensor. Two questions before it is
        admitted as one effect (issue 42), each a move of two judged under every guard, which must
        clear the held-out bar over the effect the round chose and over either of its own alone:

        - a measured partner: the sensor's lag (or transient) with its time constant searched again
          beside another sensor's plain temperature (a lag found alone absorbs what a correlated
          sensor explains: a bed that follows the ambient and part of the spindle's heat);
        - two time constants of the sensor (a fast skin and a slow core), both of one sign.

        A measured sensor comes before a constructed one: the partner is named when it is within the
        margin of equivalence of the two time constants. Every value tried counts among the round's
        hypotheses. True when a move was admitted."""
        s = self.settings
        term = chosen.candidate.term
        sensor = term.parameters.get("sensor")
        if sensor is None or not time_constants(term) or len(path.added) + 2 > s.max_effects:
            return False
        tried_moves: list[tuple[str, Move, float]] = []
        # A partner search starts from the one time constant family the chosen term is or extends (the
        # registry's searched_column); two time constants only of such a family itself.
        partner_family = families.one_time_constant_family(term.effect)
        if partner_family is not None and s.measured_partners:
            partnered = self.partner_move(path, chosen, design, tests, partner_family, str(sensor))
            if partnered is not None:
                move, t_crit, other_partners = partnered
                tried_moves += [("partner", m, t_crit) for m in (move, *other_partners)]
        kind = term.spec.searched_column
        if kind is not None and s.second_time_constant_ratio:
            found = self.split_move(path, chosen, design, tests, kind, str(sensor))
            if found is not None:
                tried_moves.append(("split", *found))
        passing = [(what, move, t_crit) for what, move, t_crit in tried_moves
                   if self.move_passes(path, move, chosen, t_crit)]
        if not passing:
            return False
        best = min(passing, key=lambda item: item[1].ranked_rms_um)
        margin = s.equivalence * (1 + sum(time_constants(t) for t in best[1].terms))
        measured = [item for item in passing if item[0] == "partner"
                    and item[1].ranked_rms_um <= best[1].ranked_rms_um * (1 + margin)]
        what, move, t_crit = measured[0] if measured else best
        others = [item for item in passing if item[1] is not move]

        def named(what: str, move: Move) -> str:
            if what != "split":
                return move.label
            taus = " and ".join(f"{t.parameters['tau_s'] / 3600:.2g} h" for t in move.terms)
            return f"{move.alone[0].candidate.label} at two time constants, {taus}"

        alternatives = [MoveAlternative(f"{chosen.candidate.label} alone", round(chosen.cv.rms_um, 4))] \
            + [MoveAlternative(named(w, m), round(m.cv.rms_um, 4)) for w, m, _t in others]
        hours = [f"{t.parameters['tau_s'] / 3600:.2g} h" for t in move.terms if "tau_s" in t.parameters]
        if what == "split":
            why = (f"one sensor at two time constants (a fast skin and a slow core): {hours[0]} and {hours[1]} "
                   f"together clear the held-out bar over {chosen.candidate.label} alone (held-out "
                   f"{chosen.cv.rms_um:.3f} um against {move.cv.rms_um:.3f} um) and over either alone")

            def preferred(index: int) -> str:
                return (f"{chosen.candidate.label} at {hours[0]} and {hours[1]}: two time constants of one sensor "
                        f"({move.shares[index]:.0%} of it this one)")
        else:
            equivalent = [named(w, m) for w, m, _t in others if m.ranked_rms_um <= move.ranked_rms_um * (1 + margin)]
            plain = not time_constants(move.alone[0].candidate.term)
            why = (f"{'two measured sensors in place of the time constant' if plain else 'a measured sensor beside the time constant'}: "
                   f"{move.label} clears the held-out bar over "
                   f"{chosen.candidate.label} alone (held-out {chosen.cv.rms_um:.3f} um against "
                   f"{move.cv.rms_um:.3f} um) and over either alone; "
                   + ("the time constant, searched again beside the second sensor, earned nothing over the sensor "
                      "itself" if plain else
                      "the time constant alone had absorbed part of what the measured sensor explains"))
            if equivalent:
                constructed = any(w == "split" for w, m, _t in others
                                  if m.ranked_rms_um <= move.ranked_rms_um * (1 + margin))
                measured_too = any(w == "partner" for w, m, _t in others
                                   if m.ranked_rms_um <= move.ranked_rms_um * (1 + margin))
                reasons = ([f"the measured partner that fits the record best (in-sample), {move.alone[1].candidate.label}"]
                           if measured_too else []) + \
                    (["the measured sensor, which needs no constructed signal and fewer parameters"] if constructed else [])
                why += (f". Equivalent on these data (held-out without the sensors' noise within {margin:.0%}): "
                        f"{', '.join(equivalent)}; the data cannot tell them apart. Named: {'; and '.join(reasons)}")

            def preferred(index: int) -> str:
                kind = "two measured sensors" if plain else "a time constant and a measured sensor"
                return f"{move.label}: {kind} that share drivers, judged together ({move.shares[index]:.0%} of it this one)"
        self.admit_move(path, move, [], t_crit, why=why, alternatives=alternatives, preferred=preferred)
        return True

    def move_passes(self, path: Path, move: Move, chosen: Evaluation, t_crit: float) -> bool:
        return self.judge(move.cv, move.fold_wins, move.runs_with, move.t_values, move.terms, path.base_cv,
                          t_crit)[0] \
            and all(self.heldout_gain(move.cv, other.cv, move.runs_with) >= self.bar
                    for other in (chosen, *move.alone))

    def _alone(self, path: Path, design: np.ndarray, terms: list[Term], grid_points: int) -> list[Evaluation] | None:
        alone = []
        for term in terms:
            candidate = self.library.candidate(term, grid_points)
            if candidate is None:
                return None
            alone.append(self.evaluate(design, path.noise, candidate, path.base_cv))
        return alone

    def _move_t_critical(self, design: np.ndarray, tests: int) -> float:
        return t_critical(self.settings.alpha, tests,
                          len(self.y) - design.shape[1] - 2 - self.baseline.extra_parameters)

    def partner_move(self, path: Path, chosen: Evaluation, design: np.ndarray, tests: int, searched: Family,
                     sensor: str) -> tuple[Move, float, list[Move]] | None:
        """The sensor's ``effect`` beside the best other sensor's plain temperature, its time constant
        searched again with the partner in; and the same beside each other partner (sensors that share
        drivers may each stand in for the other: the words list those the data cannot tell apart)."""
        library = self.library
        partners: dict[str, Term] = {}
        for other in library.sensors():
            if other == sensor or f"temperature:{other}" in path.present or library.modelled("temperature", other):
                continue
            partners[other] = Term("temperature", {"sensor": other, "t_ref_C": library.t_ref(other),
                                                   "coeff_um_per_K": 0.0})
        columns = {}
        for name, partner in partners.items():
            candidate = library.candidate(partner)
            if candidate is not None:
                columns[name] = candidate.feature
        assert searched.searched_column is not None
        found = library.best_with_partner(searched.searched_column, sensor, design, columns)
        if found is None:
            return None
        tau_s, partner_name, tried = found
        base = {"sensor": sensor, "tau_s": tau_s, "coeff_um_per_K": 0.0}
        if "t_ref_C" in searched.optional:
            base = {"sensor": sensor, "t_ref_C": library.t_ref(sensor), **base}
        alone = self._alone(path, design, [Term(searched.effect, base), partners[partner_name]], tried)
        if alone is None:
            return None
        move = self.evaluate_pair(path, alone[0], alone[1])
        plain = Term("temperature", {"sensor": sensor, "t_ref_C": library.t_ref(sensor), "coeff_um_per_K": 0.0})
        if f"temperature:{sensor}" not in path.present and not library.modelled("temperature", sensor):
            # A time constant that earns nothing over the sensor itself (re-searched to the grid's
            # end beside the partner: a lag of 4 min of a sensor averaged over 5) is the sensor.
            simple = self._alone(path, design, [plain, partners[partner_name]], 1)
            if simple is not None:
                simpler = self.evaluate_pair(path, simple[0], simple[1])
                if move.ranked_rms_um > (1 - self.bar) * simpler.ranked_rms_um:
                    move = simpler
        others = []
        for name, partner in partners.items():
            if name == partner_name or name not in columns:
                continue
            other = self._alone(path, design, [move.alone[0].candidate.term, partner], tried)
            if other is not None:
                others.append(self.evaluate_pair(path, other[0], other[1]))
        return move, self._move_t_critical(design, tests + tried), others

    def split_move(self, path: Path, chosen: Evaluation, design: np.ndarray, tests: int, kind: str,
                   sensor: str) -> tuple[Move, float] | None:
        """The sensor at its best pair of time constants (``Library.best_time_constant_pair``), both
        coefficients of one sign."""
        found = self.library.best_time_constant_pair(kind, sensor, design, self.settings.second_time_constant_ratio)
        if found is None:
            return None
        _rms, fast_s, slow_s, tried = found
        term = chosen.candidate.term
        alone = self._alone(path, design, [Term(term.effect, {**term.parameters, "tau_s": tau_s,
                                                              term.spec.coefficient: 0.0})
                                           for tau_s in (fast_s, slow_s)], tried)
        if alone is None:
            return None
        move = self.evaluate_pair(path, alone[0], alone[1])
        if move.coefficients[0] * move.coefficients[1] <= 0:
            # A skin and a core of one structure heated from one side move it the same way; two lags of
            # one sensor pulling apart are a transient (a family of its own), two transients pulling
            # apart one band of time constants, not two paths of heat.
            return None
        return move, self._move_t_critical(design, tests + tried)

    # ------------------------------------------------------------------ moves of two effects
    def screen_pairs(self, design: np.ndarray, pool: list[Evaluation]) -> list[tuple[int, int]]:
        """The ``pair_beam`` pairs of ``pool`` that lower the in-sample residual most beside ``design``:
        the features and the gauge projected off the design once, then every pair's fit is a 2 x 2
        solve on one Gram matrix (no fit of n samples per pair)."""
        features = np.column_stack([e.candidate.feature for e in pool])
        target = self.y
        if design.shape[1]:
            stacked = np.column_stack([features, target])
            stacked = stacked - design @ stats.least_squares(design, stacked)
            features, target = stacked[:, :-1], stacked[:, -1]
        gram = features.T @ features
        moment = features.T @ target
        diagonal = np.diag(gram)
        first, second = np.triu_indices(len(pool), 1)
        cross = gram[first, second]
        determinant = diagonal[first] * diagonal[second] - cross ** 2
        # Near-collinear pairs (a lag and a slightly longer lag) are one effect fitted twice: skipped.
        usable = determinant > 1e-6 * diagonal[first] * diagonal[second]
        with np.errstate(divide="ignore", invalid="ignore"):
            reduction = (diagonal[second] * moment[first] ** 2 - 2 * cross * moment[first] * moment[second]
                         + diagonal[first] * moment[second] ** 2) / determinant
        reduction = np.where(usable & np.isfinite(reduction), reduction, -np.inf)
        # Pairs that span the same columns with the design (temperature(a) + temperature(b), or the
        # gradient a - b and either; a sensor of the design and a gradient with it) fit alike: the
        # simplest stands for them, and the beam holds moves that differ.
        complexity = np.array([e.candidate.term.spec.complexity for e in pool])
        scale = float(np.max(reduction)) if np.isfinite(np.max(reduction)) and np.max(reduction) > 0 else 1.0
        order = np.lexsort((complexity[first] + complexity[second], -np.round(reduction / scale, 7)))
        chosen: list[int] = []
        for k in order:
            if len(chosen) == self.settings.pair_beam or not reduction[k] > 0:
                break
            if not any(abs(reduction[k] - reduction[c]) <= 1e-6 * reduction[c] for c in chosen):
                chosen.append(int(k))
        return [(int(first[k]), int(second[k])) for k in chosen]

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
        lost = [max(self.heldout_gain(move.cv, other.cv, runs_with), 0.0) for other in (b, a)]
        total = sum(lost)
        move.shares = (lost[0] / total, lost[1] / total) if total > 0 else (0.5, 0.5)
        return move

    def pair_round(self, path: Path, evaluations: list[Evaluation], single_tests: int) -> bool:
        """No single effect passed: screen the pairs of the round's candidates, cross-validate the best
        few, and admit the simplest passing move as two effects. Every guard applies to the move as a
        whole (both coefficients past the t-test, Bonferroni-corrected over every pair of hypotheses),
        and each effect must earn its place in it: the move must clear the held-out bar over either
        effect alone."""
        s, setup = self.settings, self.baseline
        pool = sorted(evaluations, key=lambda e: e.ranked_rms_um)[: s.pair_pool]
        if len(pool) < 2:
            return False
        pairs = self.screen_pairs(path.design, pool)
        grid = np.array([e.candidate.grid_points for e in pool], dtype=float)
        tests = single_tests + int((grid.sum() ** 2 - float(np.sum(grid ** 2))) / 2)
        t_crit = t_critical(s.alpha, tests, len(self.y) - path.design.shape[1] - 2 - setup.extra_parameters)
        moves = [self.evaluate_pair(path, pool[first], pool[second]) for first, second in pairs]

        def guarded(move: Move, paired: bool) -> bool:
            return self.judge(move.cv, move.fold_wins, move.runs_with, move.t_values, move.terms, path.base_cv,
                              t_crit, paired=paired)[0] \
                and all(self.heldout_gain(move.cv, alone.cv, move.runs_with) >= self.bar
                        for alone in move.alone)
        if self.per_run:
            self.paired_tests = max(1, sum(guarded(move, paired=False) for move in moves))
        passing = [move for move in moves if guarded(move, paired=True)]
        if not passing:
            return False
        best = min(passing, key=lambda m: m.ranked_rms_um)
        margin = s.equivalence * (1 + sum(time_constants(term) for term in best.terms))
        equivalent = [m for m in passing if m.ranked_rms_um <= best.ranked_rms_um * (1 + margin)]
        chosen = min(equivalent, key=lambda m: (sum(t.spec.complexity for t in m.terms), m.ranked_rms_um))
        self.admit_move(path, chosen, [m for m in equivalent if m is not chosen], t_crit)
        return True

    def admit_move(self, path: Path, move: Move, equivalent: list[Move], t_crit: float, *,
                   why: str = "no single effect passed the guards; these two pass them together, and each is "
                              "needed (the pair clears the held-out bar over either alone)",
                   alternatives: list[MoveAlternative] | None = None,
                   preferred: Callable[[int], str] | None = None) -> None:
        folds = len(self.baseline.folds)
        figures = self.run_figures(move.cv, path.base_cv, move.runs_with) if self.per_run else None
        for index, (alone, term) in enumerate(zip(move.alone, move.terms, strict=True)):
            member = Evaluation(alone.candidate, move.cv, move.t_values[index], move.coefficients[index],
                                move.fold_wins, move.ranked_rms_um)
            record = explain.evidence(member, member, [member], 0.0, path.base_cv.rms_um, t_crit, folds, None,
                                      term.spec.description)
            record.move = MoveEvidence(
                [e.candidate.label for e in move.alone], round(move.cv.rms_um, 4),
                [round(e.cv.rms_um, 4) for e in move.alone], [round(share, 3) for share in move.shares],
                [MoveAlternative(m.label, round(m.cv.rms_um, 4)) for m in equivalent] + (alternatives or []),
                why, round(move.shares[index], 3))
            record.preferred = preferred(index) if preferred is not None else \
                f"{move.label}: a move of two effects ({move.shares[index]:.0%} of it this one)"
            record.runs = figures
            path.discovered.append(finding(term.effect, term.parameters, record))
            path.added.append(term)
            path.present.add(present_key(term))
        path.design = np.column_stack([path.design] + [e.candidate.feature for e in move.alone])
        path.noise = np.column_stack([path.noise] + [e.candidate.noise for e in move.alone])
        path.base_cv = move.cv

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
            self.paired_tests = path.rejected_paired_tests
            path.judged = [(e, self.guards_with_time_constant(e, path)) for e in path.rejected]
        return path.judged

    def guards_with_time_constant(self, evaluation: Evaluation, path: Path) -> list[Guard]:
        """Every guard of a candidate of the last round (nothing of which passed), the time constant's
        before the held-out bar."""
        guards = self.guards_of(evaluation, path.base_cv, path.rejected_t_critical)
        extra = [] if (found := self.time_constant_guard(evaluation, path.rejected, [])) is None else [found]
        if path.at_limit:
            extra.append(Guard("limit", False, f"the search stopped at {self.settings.max_effects} terms "
                                               f"(Settings.max_effects)"))
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
        alternative = Alternative("recalibration" + "".join(f" + {d.effect}" for d in recalibrate.discovered),
                                  round(cv_recal, 4))
        found = [d.effect for d in recalibrate.discovered]
        if not self.gain_physical(joint_gain, joint_se):
            why = (f"a common gain was considered and withdrawn: with the other effects in, it is {joint_gain:.3g} "
                   f"(physical range {s.gain_range[0]:g}..{s.gain_range[1]:g}, and it must depart from 1)")
            return recalibrate, explain.recalibration_words(found, setup.calibrated_here, why)
        single = setup.base_design.shape[1] <= 1
        if single or not recalibrate.discovered or cv_gain < (1 - s.equivalence) * cv_recal:
            reason = ("the model has one coefficient: its refit is the gain" if single else
                      "recalibrating the model's coefficients finds no physics the gain does not explain"
                      if not recalibrate.discovered else
                      f"gain x model explains held-out data better ({cv_gain:.3f} um) than recalibrating and "
                      f"adding physics ({cv_recal:.3f} um)")
            if not single:  # with one coefficient, recalibration is the same model as the gain
                with_gain.discovered[0].evidence.equivalent = [alternative]
            words = f"gain_error preferred: {reason}"
            with_gain.discovered[0].evidence.preferred = words
            return with_gain, words
        why = (f"a common gain of {joint_gain:.3g} was considered: held-out {cv_gain:.3f} um against "
               f"{cv_recal:.3f} um for recalibration + physics, not better by {s.equivalence:.0%}")
        for record in recalibrate.discovered:
            evidence = record.evidence
            assert isinstance(evidence, Evidence)  # the recalibrated path names no gain
            evidence.note = "a common gain on the model was considered and set aside"
        if recalibrate.discovered:
            recalibrate.discovered[0].evidence.equivalent.append(
                Alternative("gain_error", round(cv_gain, 4), gain=round(joint_gain, 5)))
        return recalibrate, explain.recalibration_words(found, setup.calibrated_here, why)
