"""Discovery of missing physics: where does the model disagree with the recording, which named
effect was left out, what are its parameters, and does the held-out error go down?

Method (docs/thermal.md):
1. The baseline is the model as given (or the recording's ``sim_`` column). Refitting its own
   coefficients is *recalibration*, reported as ``recalibrated_rms_um`` and never as physics.
   One common factor on the whole model that explains the mismatch is a ``gain_error``.
2. Candidate effects from the vocabulary are fitted one at a time, jointly with the baseline's free
   coefficients. A candidate is accepted only if it lowers the blocked cross-validated RMS by at
   least ``min_improvement`` in most folds, its coefficient passes an autocorrelation-corrected
   t-test at a level Bonferroni-corrected over every hypothesis of the round (grid points of a time
   constant included), and its parameters are physical. Candidates whose held-out RMS is within
   ``equivalence`` of the best are equivalent explanations: the simplest wins, the others are
   reported with it; a time constant must earn its place over the effect it extends. Repeat until
   nothing passes. Equivalence is judged (admission is not) on held-out RMS without the share that
   the sensors' own white noise adds through the features (errors in variables).
3. Gross outliers (far beyond the robust noise scale) are set aside and reported as data quality.

The method is a pipeline of parts, each its own module: ``readings`` (glitch repair, sensor noise,
averaging), ``problem`` (the gauge samples over one run or several, features of a term),
``library`` (the candidates), ``splitters`` (blocks of one run, runs as groups), ``selector`` (the
forward search, by job: ``admission`` its guards, ``search`` and ``moves`` its rounds, ``run_figures``)
and ``explain`` (words, mismatch windows). This module wires them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from nckemu.errors import NckConfigError
from nckemu.thermal import stats
from nckemu.thermal.model.terms import Term, ThermalModel
from nckemu.thermal.recordings.recording import Recording

from . import explain, regimes, unusable
from .findings import Closest, Finding, GuardFigure, Likely, Withdrawn
from .library import Library
from .problem import Problem
from .readings import prepare, resampled
from .records import Baseline, Path
from .run_figures import made_worse, shared_traits
from .selection_words import stopped_by_data_words, stopped_by_limit_words
from .selector import Selector
from .settings import Settings
from .splitters import Blocks, LeaveOneRunOut, Splitter, held_out_masks

__all__ = ["Discoverer", "Discovery", "Settings", "discover", "discover_runs"]


@dataclass
class Discovery:
    axis: str
    baseline_rms_um: float
    recalibrated_rms_um: float
    heldout_rms_before_um: float
    heldout_rms_after_um: float
    mismatch: list[dict[str, Any]]
    missing_physics: list[Finding]
    improved_model: ThermalModel
    data_quality: list[str] = field(default_factory=list)
    samples: int = 0
    series: dict[str, np.ndarray] = field(default_factory=dict)
    preferred: str = ""
    calibrated_on_record: bool = False
    # What the headline "before" is: the baseline as given, or refitted per fold (like for like).
    before_is: str = ""
    # When nothing passed: why, in one line (independent blocks or runs, the smallest effect this
    # record could have shown per family, the residual's autocorrelation).
    why_nothing: str = ""
    smallest_detectable_um: dict[str, float] = field(default_factory=dict)
    # A term that passes every guard but the held-out bar: "likely, not proven", with its figures.
    likely: list[Likely] = field(default_factory=list)
    # The candidates of the last round that came closest, each with every guard's figure.
    closest: list[Closest] = field(default_factory=list)
    # Terms named in an early round, then withdrawn: the terms named after them explain what they did.
    withdrawn: list[Withdrawn] = field(default_factory=list)
    # After the last named term, when what is left is structure and no run stands out: where it is
    # largest (a run, or a window of the one recording) and what it follows there.
    left: list[dict[str, Any]] = field(default_factory=list)
    # Terms that fit and pass every other guard, but that a machine cannot have (issue 51): never named.
    cannot_have: list[Closest] = field(default_factory=list)
    # What stopped the search: "data" (nothing more earned its place) or "limit" (the next round, judged
    # with the limit lifted, would name ``beyond_limit``); ``stopped``: why in words, when the search
    # reached the limit (by the data or by the limit).
    stopped_by: str = "data"
    stopped: str = ""
    beyond_limit: dict[str, Any] = field(default_factory=dict)
    # Several runs: the figures of each (leave-one-run-out), which columns some runs lack.
    runs: list[dict[str, Any]] = field(default_factory=list)
    coverage: list[dict[str, Any]] = field(default_factory=list)
    # Several runs: medians over runs, how many improve, the worst run, the runs the model still fails.
    run_figures: dict[str, Any] = field(default_factory=dict)
    # The final residual's r(1), Ljung-Box Q and whether it is beyond white noise: a residual that is
    # structure is never "nothing missing".
    residual_structure: dict[str, Any] = field(default_factory=dict)
    # A program's sim_ column that is one constant (e.g. all zeros): it explains nothing, so candidates
    # were tried against it plus an offset, as against a constant-offset baseline. None otherwise.
    baseline_constant_um: float | None = None
    # What the recording cannot give (unusable.py): a still error column, a still sensor, a time
    # constant at the edge of what its length can tell; one line each.
    cannot_use: list[str] = field(default_factory=list)

    @property
    def residual_is_structure(self) -> bool:
        return bool(self.residual_structure.get("beyond_white_noise"))

    @property
    def stopped_at_limit(self) -> str:
        """The search stopped at Settings.max_effects, not because nothing more passed: ``stopped``'s
        words, with what the next round would name and its figure ("" when the data stopped it)."""
        return self.stopped if self.stopped_by == "limit" else ""

    def to_json(self) -> dict[str, Any]:
        document = {
            "axis": self.axis, "samples": self.samples,
            "baseline_rms_um": round(self.baseline_rms_um, 4),
            "recalibrated_rms_um": round(self.recalibrated_rms_um, 4),
            "heldout_rms_before_um": round(self.heldout_rms_before_um, 4),
            "heldout_rms_after_um": round(self.heldout_rms_after_um, 4),
            "heldout_before_is": self.before_is,
            "mismatch": self.mismatch, "missing_physics": [f.to_json() for f in self.missing_physics],
            "data_quality": self.data_quality, "preferred": self.preferred,
            "calibrated_on_record": self.calibrated_on_record,
            "why_nothing": self.why_nothing,
            "smallest_detectable_um": {k: round(v, 4) for k, v in self.smallest_detectable_um.items()},
            "likely_not_proven": [item.to_json() for item in self.likely],
            "closest_candidates": [item.to_json() for item in self.closest],
            "withdrawn": [item.to_json() for item in self.withdrawn],
            "cannot_have": [item.to_json() for item in self.cannot_have],
            "left": self.left,
            "stopped_at_limit": self.stopped_at_limit,
            "stopped_by": self.stopped_by, "stopped": self.stopped, "beyond_limit": self.beyond_limit,
            "residual_structure": self.residual_structure,
            "cannot_use": self.cannot_use,
        }
        if self.baseline_constant_um is not None:
            document["baseline_constant_um"] = round(self.baseline_constant_um, 6)
        if self.runs:
            document["runs"] = self.runs
            document["run_figures"] = self.run_figures
            document["coverage"] = self.coverage
        return document


def _with_structure(settings: Settings, model: ThermalModel | None) -> Settings:
    """The model file's [structure] (what its machine can have) in place of the default."""
    if model is None or model.structure is None:
        return settings
    return replace(settings, structure=model.structure)


def _isolated(flagged: np.ndarray, longest: int = 2) -> np.ndarray:
    """The flagged samples in runs of at most ``longest`` consecutive readings: an outlier leaves its
    neighbours; a stretch where the model is wrong is what discovery looks for, not bad data."""
    edges = np.diff(np.concatenate(([0], flagged.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    out = np.zeros_like(flagged)
    for start, end in zip(starts, ends, strict=True):
        if end - start <= longest:
            out[start:end] = True
    return out


def constant_program(recordings: list[Recording], axis: str) -> float | None:
    """The value of a ``sim_<axis>_um`` column that is one constant on every measured sample of every
    recording (a program whose output stays 0), else None. Such a baseline has no shape to refit: it
    is an offset, and candidates must be tried against it as against a constant."""
    values = []
    for recording in recordings:
        simulated = recording.simulated_um.get(axis)
        if simulated is None or axis not in recording.errors_um:
            return None
        measured = ~np.isnan(recording.errors_um[axis]) & ~np.isnan(simulated)
        if not measured.any():
            continue
        values.append(simulated[measured])
    if not values:
        return None
    together = np.concatenate(values)
    return float(together[0]) if float(np.ptp(together)) <= 1e-9 else None


class Discoverer:
    """Wires the parts for one recording (or, through ``runs``, several runs of one machine)."""

    def __init__(self, recording: Recording, axis: str | None = None, model: ThermalModel | None = None,
                 settings: Settings | None = None, *, splitter: Splitter | None = None) -> None:
        axis = axis or (model.axis if model is not None else None)
        if axis is None:
            axes = recording.axes()
            if len(axes) != 1:
                raise NckConfigError(f"several axes ({', '.join(axes)}): name one with --axis", path=recording.source)
            axis = axes[0]
        self.settings = _with_structure(settings or Settings(), model)
        self.constant_um = constant_program([recording], axis) if model is None else None
        if self.constant_um is not None:
            model = ThermalModel(axis, [Term("offset", {"value_um": self.constant_um})],
                                 f"<the sim_{axis}_um column, constant {self.constant_um:g} um>")
        readings = prepare(recording, self.settings)
        self.data_quality: list[str] = list(readings.data_quality)
        self.sensor_noise_C = readings.sensor_noise_C
        self.problem = Problem([(recording.source, readings)], axis, model)
        self.splitter: Splitter = splitter or Blocks(self.settings.folds)
        self.group_by: str | None = None

    @classmethod
    def for_runs(cls, runs: list[Recording], axis: str, model: ThermalModel | None,
                 settings: Settings | None = None, group_by: str | None = None) -> Discoverer:
        """Several runs of one machine: each its own offset, held out one at a time."""
        self = cls.__new__(cls)
        self.settings = _with_structure(settings or Settings(), model)
        self.constant_um = constant_program(runs, axis) if model is None else None
        if self.constant_um is not None:  # each run's own offset is the whole baseline
            model = ThermalModel(axis, [], f"<the sim_{axis}_um column, constant {self.constant_um:g} um>")
        self.data_quality = []
        self.sensor_noise_C = {}
        prepared = []
        for run in runs:
            name = getattr(run, "name", "") or run.source
            readings = prepare(run, self.settings)
            step_s = self.settings.runs_resample_s
            coarse = resampled(readings, step_s)
            if len(coarse.recording.t_s) < len(run.t_s):
                self.data_quality.append(f"{name}: sampled every {float(np.median(np.diff(run.t_s))):g} s; "
                                         f"resampled to {step_s:g} s steps (the gauge averaged per step) after "
                                         f"the readings were averaged")
            self.data_quality += [f"{name}: {note}" for note in readings.data_quality]
            self.sensor_noise_C.update({f"{name}:{k}": v for k, v in readings.sensor_noise_C.items()})
            prepared.append((name, coarse))
        self.problem = Problem(prepared, axis, model, per_run_offset=True)
        self.splitter = LeaveOneRunOut()
        if group_by:  # a bad grouping is refused before the search, not after it
            regimes.check_group_by(runs, group_by)
        self.group_by = group_by
        return self

    @property
    def y(self) -> np.ndarray:
        return self.problem.y

    # ------------------------------------------------------------------ the baseline
    def _base_design(self) -> np.ndarray:
        problem = self.problem
        if not problem.runs[0].base_columns:
            return np.empty((len(problem.y), 0))
        count = len(problem.runs[0].base_columns)
        return np.column_stack([problem.column(lambda run, i=i: run.base_columns[i]) for i in range(count)])

    def _screen_outliers(self, design: np.ndarray) -> None:
        residual = self.y - design @ stats.least_squares(design, self.y)
        sigma = stats.robust_sigma(residual)
        if not sigma > 0:
            return
        outliers = _isolated(np.abs(residual - np.median(residual)) > self.settings.outlier_sigmas * sigma)
        if outliers.any():
            self.data_quality.append(f"{int(outliers.sum())} outlier sample(s) beyond "
                                     f"{self.settings.outlier_sigmas:g} robust sigma set aside "
                                     f"(first at t = {float(self.problem.t_s[outliers][0]):.0f} s)")
            self.problem.set_aside(outliers)

    def _noise(self) -> tuple[np.ndarray, np.ndarray]:
        """The sensor noise carried by the baseline's columns and by the model as given (none for a
        ``sim_`` column)."""
        problem = self.problem
        if not problem.base_terms:  # a sim_ column, or no columns at all
            return (np.zeros((len(problem.y), len(problem.runs[0].base_columns))), np.zeros(len(problem.y)))
        base = np.column_stack([problem.feature(term, noisy=True) - problem.feature(term)
                                for term in problem.base_terms])
        model = problem.column(lambda run: problem.model.predict_um(run.readings.noisy)
                               - problem.model.predict_um(run.readings.recording))
        return base, model

    def _calibrated_on_record(self) -> bool:
        """Were the given coefficients fitted by least squares on this record? Judged on the readings
        as recorded (before glitch repair and averaging): RMS as given within ``calibrated_tolerance``
        of the least-squares optimum's."""
        problem = self.problem
        if problem.base_terms:
            columns = np.column_stack([problem.column(lambda run, term=term: term.feature(run.readings.raw, problem.axis))
                                       for term in problem.base_terms])
            given = problem.column(lambda run: problem.model.predict_um(run.readings.raw))
        else:  # a sim_ column: nothing was averaged
            columns = self._base_design()
            given = problem.column(lambda run: run.given_prediction)
        optimum = stats.rms(self.y - columns @ stats.least_squares(columns, self.y))
        return stats.rms(self.y - given) <= optimum * (1 + self.settings.calibrated_tolerance)

    def baseline(self) -> Baseline:
        problem = self.problem
        base_design = self._base_design()
        self._screen_outliers(base_design)
        base_design = self._base_design()
        given = problem.column(lambda run: run.given_prediction)
        folds = held_out_masks(self.splitter, len(self.y), problem.groups)
        baseline_rms = stats.rms(self.y - given)
        recalibrated = stats.fit(base_design, self.y) if base_design.shape[1] else None
        recalibrated_rms = recalibrated.rms_um if recalibrated else baseline_rms
        given_cv = stats.CrossValidation(baseline_rms, tuple(stats.rms(self.y[f] - given[f]) for f in folds))
        # One fit per fold, or (one fold per run, many runs) each fold's share taken off the normal equations.
        cross_validate = stats.cross_validate_gram if problem.per_run_offset else stats.cross_validate
        recal_cv = cross_validate(base_design, self.y, folds) if base_design.shape[1] else given_cv
        # A model whose coefficients are the least-squares optimum on this very record was calibrated
        # on it: its RMS "as given" is an in-sample figure, not a held-out one. Compare like with like:
        # the baseline refitted per fold, under the same blocked cross-validation as the candidates.
        calibrated_here = recalibrated is not None and self._calibrated_on_record()
        base_noise, given_noise = self._noise()
        extra = len(problem.runs) if problem.per_run_offset else 0
        return Baseline(base_design, given, folds, baseline_rms, recalibrated, recalibrated_rms, given_cv, recal_cv,
                        calibrated_here, base_noise, given_noise, extra, cross_validate)

    # ------------------------------------------------------------------ the run
    def run(self) -> Discovery:
        still = unusable.still_error(self.problem.recording, self.problem.axis, self.y)
        if still is not None:  # every candidate would "explain" a still column: say so and search nothing
            return self._nothing_to_explain(still)
        setup = self.baseline()
        selector = Selector(self.y, self.problem.t_s, Library(self.problem, self.settings), self.settings, setup)
        if self.problem.per_run_offset:
            selector.searcher.fit_apart = lambda path, evaluation, t_crit: regimes.fit_apart(
                selector, path, evaluation, t_crit, self.group_by)
        recalibrate = selector.search(gain_mode=False)
        regimes.split_runs(selector, recalibrate, self.group_by)
        chosen, preferred = recalibrate, explain.recalibration_words(
            [d.effect for d in recalibrate.discovered], setup.calibrated_here, None)
        if selector.gain_eligible():
            with_gain = selector.search(gain_mode=True)
            chosen, preferred = selector.prefer(recalibrate, with_gain)
        self.selector, self.setup, self.path = selector, setup, chosen
        result = self._finish(setup, chosen, preferred)
        result.withdrawn = list(chosen.withdrawn)
        named = {explain.label_with_time_constants(term) for term in chosen.added}
        result.cannot_have = [Closest(term.effect, label, {k: (round(v, 6) if isinstance(v, float) else v)
                                                           for k, v in term.parameters.items()},
                                      [GuardFigure(g.name, g.passes, g.figure) for g in guards])
                              for label, term, guards in sorted(chosen.cannot_have, key=lambda item: -item[2][-1].gain)
                              if label not in named][:3]
        result.baseline_constant_um = self.constant_um
        self._honest(result, selector, setup, chosen)
        if len(self.problem.runs) > 1:
            self._per_run(result, setup, chosen)
        self._cannot_use(result)
        return result

    def _cannot_use(self, result: Discovery) -> None:
        runs = [run.readings.raw for run in self.problem.runs]
        result.cannot_use = unusable.still_sensors(runs)
        shortest_s = min(run.duration_s for run in runs)
        named = [(explain.label(Term(m.effect, m.parameters)), m.parameters)
                 for m in result.missing_physics]
        result.cannot_use += unusable.short_time_constants(named, shortest_s)

    def _nothing_to_explain(self, line: str) -> Discovery:
        problem = self.problem
        result = Discovery(axis=problem.axis, baseline_rms_um=0.0, recalibrated_rms_um=0.0,
                           heldout_rms_before_um=0.0, heldout_rms_after_um=0.0, mismatch=[], missing_physics=[],
                           improved_model=problem.model, data_quality=self.data_quality, samples=len(self.y),
                           why_nothing=line, baseline_constant_um=self.constant_um,
                           before_is="nothing to explain: the error column is one value")
        result.cannot_use = [line, *unusable.still_sensors(run.readings.raw for run in problem.runs)]
        return result

    def _honest(self, result: Discovery, selector: Selector, setup: Baseline, path: Path) -> None:
        """The like-for-like "before"; why nothing passed; a term likely but not proven."""
        if path.gain_mode:
            result.before_is = "the model as given (a common gain on it is the finding)"
            before_um = setup.baseline_rms
        else:
            reference = setup.reference_cv
            before_um = reference.rms_um
            result.before_is = ("each run's own offset" if self.problem.per_run_offset and not setup.base_design.shape[1]
                                else "the baseline as given" if reference is setup.given_cv else
                                "the baseline refitted on the other runs, each run's offset on its own"
                                if self.problem.per_run_offset else "the baseline refitted per held-out block")
        result.heldout_rms_before_um = before_um
        if not result.missing_physics:
            result.heldout_rms_after_um = before_um
        final_residual = path.final.residual if path.final is not None else self.y - setup.given
        if self.problem.per_run_offset:  # what each run's own offset leaves
            final_residual = self.problem.within(final_residual)
        result.residual_structure = explain.residual_structure(final_residual)
        if result.missing_physics and result.residual_is_structure and not self.problem.per_run_offset:
            result.left = explain.mismatch(self.problem.recording, self.problem.axis, self.problem.t_s,
                                           final_residual)[:1]
        near = selector.near_misses(path)
        found = {(m.effect, str(m.parameters.get("sensor", m.parameters.get("sensors", ""))))
                 for m in result.missing_physics}
        for evaluation in near[:1]:
            term = evaluation.candidate.term
            if (term.effect, str(term.parameters.get("sensor", term.parameters.get("sensors", "")))) in found:
                continue
            before_um, after_um, gain, figure = selector.heldout_figures(evaluation.cv, path.base_cv,
                                                                         evaluation.candidate.runs_with)
            guards = next(g for e, g in selector.judged(path) if e is evaluation)
            passed = [g.figure for g in guards[:-1]]
            result.likely.append(explain.likely_record(
                evaluation, before_um, after_um, gain, figure, path.rejected_t_critical, len(setup.folds),
                selector.bar, "runs" if self.problem.per_run_offset else "folds", passed=passed))
        self._stop_words(result, path)
        for evaluation, guards in selector.closest(path):
            term = evaluation.candidate.term.with_coefficient(evaluation.coefficient)
            result.closest.append(Closest(
                term.effect, explain.label_with_time_constants(term),
                {k: (round(v, 6) if isinstance(v, float) else v) for k, v in term.parameters.items()},
                [GuardFigure(g.name, g.passes, g.figure) for g in guards]))
        # The smallest effect each family could have shown: when nothing passed, and whenever what is
        # left is structure (what the last round could not name, and how large it would have had to be).
        if not path.rejected or (result.missing_physics and not result.residual_is_structure):
            return
        for evaluation in path.rejected:
            evaluation.own_rms = selector.own_rms(path.design, evaluation.candidate.feature)
        result.smallest_detectable_um = explain.detectable_um(path.rejected, path.base_cv.rms_um,
                                                              path.rejected_t_critical, selector.bar)
        if result.missing_physics:
            return
        residual = path.final.residual if path.final is not None else self.y - setup.given
        _beyond, words = explain.autocorrelation_words(residual)
        runs = len(self.problem.runs)
        unit = (runs, "runs") if runs > 1 else (len(setup.folds), "blocks of time")
        result.why_nothing = explain.nothing_passed(unit[0], unit[1], result.smallest_detectable_um, words)

    def _stop_words(self, result: Discovery, path: Path) -> None:
        """What stopped the search, judged at the limit (``Search.judge_next_round``): the data, said
        when the limit was reached; or the limit, with what the next round would name."""
        result.stopped_by = path.stopped_by
        if path.beyond_limit is not None:
            labels, before_um, after_um, figure = path.beyond_limit
            result.stopped = stopped_by_limit_words(
                path.limit_terms, self.settings.max_effects, labels, before_um, after_um, figure)
            result.beyond_limit = {"terms": labels, "before_um": round(before_um, 4), "after_um": round(after_um, 4),
                                   "figure": figure}
        elif path.limit_terms >= self.settings.max_effects:
            result.stopped = stopped_by_data_words(path.limit_terms)

    def _per_run(self, result: Discovery, setup: Baseline, path: Path) -> None:
        """Leave-one-run-out figures per run (before = the like-for-like baseline, after = the improved
        model), the medians as headline, how many runs improve, the worst run, and which runs the
        model still fails: when in the run and what the residual there follows."""
        problem = self.problem
        before_cv = setup.given_cv if path.gain_mode else setup.reference_cv
        found = bool(result.missing_physics)
        after_cv = path.base_cv if found else before_cv
        residual = _heldout_residual(path.design if found else setup.base_design, self.y, setup.folds)
        base_residual = _heldout_residual(setup.base_design, self.y, setup.folds)
        rows = []
        for index, run in enumerate(problem.runs):
            recording = run.readings.recording
            rows.append({"name": run.name, "rows": int(run.mask.sum()), "duration_h": round(recording.duration_s / 3600, 3),
                         "heldout_rms_before_um": round(before_cv.fold_rms_um[index], 4),
                         "heldout_rms_after_um": round(after_cv.fold_rms_um[index], 4)})
        result.runs = rows
        figures = explain.run_figures([r["name"] for r in rows], [r["heldout_rms_before_um"] for r in rows],
                                      [r["heldout_rms_after_um"] for r in rows], found)
        result.run_figures = figures
        result.heldout_rms_before_um = figures["median_before_um"]
        result.heldout_rms_after_um = figures["median_after_um"]
        result.before_is += "; median over runs, each held out"
        result.mismatch = []
        for index, (run, row) in enumerate(zip(problem.runs, rows, strict=True)):
            row["fails"] = row["name"] in figures["fails"]
            if not row["fails"]:
                continue
            window = self._run_window(index, residual)
            row["fails_from_h"], row["fails_to_h"] = window["from_h"], window["to_h"]
            row["follows"] = window["follows"]
            row["follows_signal"], row["follows_r"] = window["follows_signal"], window["follows_r"]
            result.mismatch.append({"run": run.name, "t_start_s": window["t_start_s"], "t_end_s": window["t_end_s"],
                                    "why": window["why"]})
        # No run made worse in silence (issue 51): the runs the final model leaves worse than before
        # discovery beyond the harm tolerance, unless a group fitted apart holds them, and what they share.
        apart = {name: m.evidence.regime.runs_words for m in result.missing_physics
                 if getattr(m.evidence, "regime", None) is not None and m.evidence.regime.apart
                 for name in m.evidence.regime.runs}
        figures["made_worse"] = made_worse(rows, self.settings, apart)
        figures["made_worse_share"] = shared_traits(rows, figures["median_after_um"])
        if found and result.residual_is_structure and not result.mismatch:
            # No run stands out, yet what is left is structure: where the worst run's residual is.
            worst = int(np.argmax([r["heldout_rms_after_um"] for r in rows]))
            result.left = [{"run": problem.runs[worst].name, **self._run_window(worst, residual)}]
        library = self.selector.library
        result.coverage = [{"column": column, "missing_in": lacking, "handled": library.handling(column)}
                           for column, lacking in library.unavailable.items()]
        # The report's series: the runs laid end to end, each from its own start.
        hours, start = [], 0.0
        for index, run in enumerate(problem.runs):
            t_run = problem.t_s[problem.groups == index]
            hours.append(t_run - t_run[0] + start)
            start += run.readings.recording.duration_s + 1800.0
        result.series["t_s"] = np.concatenate(hours)
        # Hours after each run's own start (its first row): where the per-run plots and windows are.
        result.series["run_hours"] = np.concatenate([
            (problem.t_s[problem.groups == index] - float(run.readings.recording.t_s[0])) / 3600.0
            for index, run in enumerate(problem.runs)])
        result.series["run_index"] = problem.groups.copy()
        result.series["heldout_residual_um"] = residual
        # Each run held out: the baseline and the improved model as they predict it from the other runs.
        result.series["heldout_baseline_um"] = self.y - base_residual
        result.series["heldout_improved_um"] = self.y - residual

    def _run_window(self, index: int, residual: np.ndarray) -> dict[str, Any]:
        """Where in run ``index`` its held-out residual is largest: the window (s from the shared clock,
        hours after the run's start), what was going on there and what the residual there follows."""
        problem = self.problem
        run = problem.runs[index]
        mine = problem.groups == index
        t_run, r_run = problem.t_s[mine], residual[mine]
        windows = explain.structured_windows(t_run, r_run, limit=1)
        start_s, end_s = windows[0] if windows else (float(t_run[0]), float(t_run[-1]))
        inside = (t_run >= start_s) & (t_run <= end_s)
        t0 = float(run.readings.recording.t_s[0])
        why = explain.why(run.readings.recording, problem.axis, t_run, inside, r_run)
        best = explain.follower(run.readings.recording, t_run[explain.widened(inside)], r_run[explain.widened(inside)])
        follows = explain.follows_words(best)
        return {"t_start_s": start_s, "t_end_s": end_s, "from_h": round((start_s - t0) / 3600, 2),
                "to_h": round((end_s - t0) / 3600, 2), "follows": follows,
                "follows_signal": best[0] if best is not None else None,
                "follows_r": round(best[1], 3) if best is not None else None,
                "why": f"{why}; {follows}" if follows else why}

    def _finish(self, setup: Baseline, path: Path, preferred: str) -> Discovery:
        problem, given, final = self.problem, setup.given, path.final
        discovered = path.discovered
        heldout_after_um = path.base_cv.rms_um if discovered else setup.baseline_rms  # nothing found: it stands
        # Coefficients of the final joint fit go into the improved model and the report.
        improved_terms = self._improved_terms(final, path.gain_mode, path.added, discovered)
        # The structure it was judged by, when one was declared (a model's [structure], --structure)
        declared = self.settings.structure if self.settings.structure.declared else None
        improved = ThermalModel(problem.axis, improved_terms, "<improved>", declared)
        improved_full = final.residual if final is not None else self.y - given
        before_residual = self.y - given
        residual_recal = setup.recalibrated.residual \
            if setup.recalibrated is not None and not path.gain_mode else before_residual
        mismatch = explain.mismatch(problem.recording, problem.axis, problem.t_s,
                                    residual_recal if not discovered else before_residual) \
            if len(problem.runs) == 1 else []  # several runs: per run, from their held-out residuals
        return Discovery(
            axis=problem.axis, baseline_rms_um=setup.baseline_rms, recalibrated_rms_um=setup.recalibrated_rms,
            heldout_rms_before_um=stats.rms(before_residual), heldout_rms_after_um=heldout_after_um,
            mismatch=mismatch, missing_physics=discovered, improved_model=improved, data_quality=self.data_quality,
            samples=len(self.y), preferred=preferred, calibrated_on_record=setup.calibrated_here,
            series={"t_s": problem.t_s, "measured_um": self.y, "baseline_um": given,
                    "improved_um": self.y - improved_full, "residual_before_um": before_residual,
                    "residual_after_um": improved_full},
        )

    def _improved_terms(self, final: stats.Fit | None, gain_mode: bool, added: list[Term],
                        discovered: list[Finding]) -> list[Term]:
        """The model as given with refitted coefficients, plus the discovered terms.

        For a ``sim_`` baseline there are no terms to carry: the gain then applies to that column."""
        problem = self.problem
        if final is None:
            return list(problem.model.terms)
        coefficients = list(final.coefficients)
        if gain_mode:
            gain = float(coefficients.pop(0))
            terms = [Term("gain_error", {"gain": round(gain * problem.model.gain, 6)})] + list(problem.base_terms)
            discovered[0].parameters["gain"] = round(gain, 5)
            records = discovered[1:]
        else:
            terms = [term.with_coefficient(c) for term, c in zip(problem.base_terms, coefficients, strict=False)]
            coefficients = coefficients[len(problem.runs[0].base_columns):]  # a sim_ column is a column, not a term
            records = discovered
        for term, coefficient, record in zip(added, coefficients, records, strict=False):
            updated = term.with_coefficient(float(coefficient))
            regime = getattr(record.evidence, "regime", None)
            if regime is None or not regime.apart:  # a model file holds one relation: the larger group's
                terms.append(updated)
            record.parameters[updated.spec.coefficient] = round(float(coefficient), 6)
        return terms


def discover(recording: Recording, axis: str | None = None, model: ThermalModel | None = None,
             settings: Settings | None = None) -> Discovery:
    return Discoverer(recording, axis, model, settings).run()


def _heldout_residual(design: np.ndarray, y: np.ndarray, folds: list[np.ndarray]) -> np.ndarray:
    """Each fold's residual predicted by the design fitted without it."""
    out = np.empty_like(y)
    for test in folds:
        if design.shape[1] == 0:
            out[test] = y[test]
        else:
            out[test] = y[test] - design[test] @ stats.least_squares(design[~test], y[~test])
    return out


def discover_runs(runs: list[Recording], axis: str | None = None, model: ThermalModel | None = None,
                  settings: Settings | None = None, group_by: str | None = None) -> Discovery:
    """Discovery over several runs of one machine. Each run has its own constant offset, always in
    the baseline and fitted on that run; everything else (coefficients, time constants, the physics
    named) is fitted on the other runs: the held-out figures are leave-one-run-out, per run and
    their medians. Without a model (and without a ``sim_`` column in every run) the baseline is
    each run's offset alone. ``group_by``: a regular expression on the run names (its first group)
    whose two groups a term may be fitted apart on (``regimes``); without it, groups are found from
    the residual's relation."""
    if not runs:
        raise NckConfigError("no runs to discover on")
    axis = axis or (model.axis if model is not None else None)
    if axis is None:
        axes = sorted({a for run in runs for a in run.axes()})
        if len(axes) != 1:
            raise NckConfigError(f"several axes across the runs ({', '.join(axes)}): name one with --axis",
                                 path=runs[0].source)
        axis = axes[0]
    for run in runs:
        if axis not in run.errors_um:
            raise NckConfigError(f"no err_{axis}_um column (the runs' axis is {axis})", path=run.source,
                                 field=f"err_{axis}_um")
    names = [getattr(run, "name", "") or run.source for run in runs]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise NckConfigError(f"two runs named {twice[0]!r}: runs need unique names", path=runs[0].source)
    if len(runs) == 1:
        if model is None and axis not in runs[0].simulated_um:  # no baseline: a constant offset, as for one file
            model = ThermalModel(axis, [Term("offset", {"value_um": 0.0})], "<constant offset>")
        return discover(runs[0], axis, model, settings)
    if model is None and not all(axis in run.simulated_um for run in runs):
        model = ThermalModel(axis, [], "<each run's own offset>")
    return Discoverer.for_runs(runs, axis, model, settings, group_by).run()
