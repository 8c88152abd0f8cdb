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
   nothing passes.
3. Gross outliers (far beyond the robust noise scale) are set aside and reported as data quality.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nckemu.errors import NckConfigError

from . import stats
from .recording import Recording
from .terms import EFFECTS, Term, ThermalModel, asymmetric_lag, first_order_lag


@dataclass(frozen=True)
class Settings:
    folds: int = 5
    min_improvement: float = 0.10       # relative drop of held-out RMS
    min_fold_share: float = 0.8         # share of folds that must improve
    alpha: float = 0.01                 # family-wise, Bonferroni over the candidates of a round
    equivalence: float = 0.03           # held-out RMS within 3 % of the best: equivalent
    max_effects: int = 4
    outlier_sigmas: float = 8.0
    min_gain_departure: float = 0.03
    lag_grid_s: tuple[float, ...] = tuple(float(v) for v in np.geomspace(300.0, 6 * 3600.0, 18))
    hysteresis_grid_s: tuple[float, ...] = tuple(float(v) for v in np.geomspace(600.0, 4 * 3600.0, 8))


@dataclass
class Candidate:
    term: Term
    feature: np.ndarray
    in_sample_rms_um: float = math.nan
    # Values of a time constant tried to find this one: each was a hypothesis tested on the data.
    grid_points: int = 1

    @property
    def label(self) -> str:
        p = self.term.parameters
        detail = p.get("sensor") or (f"{p['sensors'][0]} - {p['sensors'][1]}" if "sensors" in p else "")
        return f"{self.term.effect}({detail})" if detail else self.term.effect


@dataclass
class Evaluation:
    candidate: Candidate
    cv: stats.CrossValidation
    t_value: float
    coefficient: float
    fold_wins: int


@dataclass
class Discovery:
    axis: str
    baseline_rms_um: float
    recalibrated_rms_um: float
    heldout_rms_before_um: float
    heldout_rms_after_um: float
    mismatch: list[dict[str, Any]]
    missing_physics: list[dict[str, Any]]
    improved_model: ThermalModel
    data_quality: list[str] = field(default_factory=list)
    samples: int = 0
    series: dict[str, np.ndarray] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            "axis": self.axis, "samples": self.samples,
            "baseline_rms_um": round(self.baseline_rms_um, 4),
            "recalibrated_rms_um": round(self.recalibrated_rms_um, 4),
            "heldout_rms_before_um": round(self.heldout_rms_before_um, 4),
            "heldout_rms_after_um": round(self.heldout_rms_after_um, 4),
            "mismatch": self.mismatch, "missing_physics": self.missing_physics,
            "data_quality": self.data_quality,
        }


def _finite(value: float) -> float | None:
    return None if not math.isfinite(value) else round(float(value), 6)


class _Problem:
    """The measured samples of one axis and the baseline's columns."""

    def __init__(self, recording: Recording, axis: str, model: ThermalModel | None) -> None:
        if axis not in recording.errors_um:
            raise NckConfigError(f"the recording has no err_{axis}_um column", path=recording.source,
                                 field=f"err_{axis}_um")
        self.recording = recording
        self.axis = axis
        measured = ~np.isnan(recording.errors_um[axis])
        if model is None:
            if axis not in recording.simulated_um:
                raise NckConfigError(f"no baseline: give --model or a sim_{axis}_um column",
                                     path=recording.source, field=f"sim_{axis}_um")
            simulation = recording.simulated_um[axis]
            measured &= ~np.isnan(simulation)
            self.base_terms: list[Term] = []
            self.base_columns = [np.nan_to_num(simulation)]
            self.given_prediction = np.nan_to_num(simulation)
            self.model = ThermalModel(axis, [], "<sim column>")
        else:
            self.model = model
            self.base_terms = model.additive_terms()
            self.base_columns = [term.feature(recording, axis) for term in self.base_terms]
            self.given_prediction = model.predict_um(recording)
        self.mask = measured
        if measured.sum() < 8:
            raise NckConfigError(f"only {int(measured.sum())} measured err_{axis}_um samples", path=recording.source)
        self.y = recording.errors_um[axis][measured]
        self.t_s = recording.t_s[measured]

    def column(self, full: np.ndarray) -> np.ndarray:
        return full[self.mask]


def _bounded(term: Term) -> bool:
    """Parameters a machine can have."""
    p = term.parameters
    c = term.coefficient
    if term.effect in ("thermal_lag",):
        return 60.0 <= float(p["tau_s"]) <= 48 * 3600.0
    if term.effect == "gain_error":
        return 0.2 <= c <= 5.0
    return math.isfinite(c)


# Effects of one sensor that contain another as a special case (a time constant going to zero, or
# heating and cooling at the same rate).
_EXTENDS = {("thermal_lag", "temperature"), ("heating_cooling_hysteresis", "temperature"),
            ("heating_cooling_hysteresis", "thermal_lag")}


def _extends(complex_term: Term, simple_term: Term) -> bool:
    return (complex_term.effect, simple_term.effect) in _EXTENDS \
        and complex_term.parameters.get("sensor") == simple_term.parameters.get("sensor") is not None


def _locate(t_s: np.ndarray, values: np.ndarray, fraction: float = 0.5) -> list[tuple[float, float, float]]:
    """Contiguous windows where |values| exceeds ``fraction`` of its peak: (start, end, weight)."""
    if len(values) == 0:
        return []
    peak = float(np.max(np.abs(values)))
    if peak == 0:
        return []
    above = np.abs(values) >= fraction * peak
    windows = []
    start = None
    for index, flag in enumerate(np.append(above, False)):
        if flag and start is None:
            start = index
        elif not flag and start is not None:
            end = index - 1
            windows.append((float(t_s[start]), float(t_s[end]), float(np.sum(np.abs(values[start:end + 1])))))
            start = None
    merged: list[tuple[float, float, float]] = []
    gap = 0.02 * (t_s[-1] - t_s[0]) if len(t_s) > 1 else 0
    for window in windows:
        if merged and window[0] - merged[-1][1] <= gap:
            previous = merged.pop()
            window = (previous[0], window[1], previous[2] + window[2])
        merged.append(window)
    return sorted(merged, key=lambda w: -w[2])


def _smooth(values: np.ndarray, width: int) -> np.ndarray:
    if width <= 1 or len(values) < width:
        return values.copy()
    kernel = np.ones(width) / width
    padded = np.pad(values, (width // 2, width - 1 - width // 2), mode="edge")
    return np.convolve(padded, kernel, mode="valid")


class Discoverer:
    def __init__(self, recording: Recording, axis: str | None = None, model: ThermalModel | None = None,
                 settings: Settings | None = None) -> None:
        axis = axis or (model.axis if model is not None else None)
        if axis is None:
            axes = recording.axes()
            if len(axes) != 1:
                raise NckConfigError(f"several axes ({', '.join(axes)}): name one with --axis", path=recording.source)
            axis = axes[0]
        self.settings = settings or Settings()
        self.problem = _Problem(recording, axis, model)
        self.recording = recording
        self.data_quality: list[str] = []

    # ------------------------------------------------------------------ candidates
    def _sensors(self) -> list[str]:
        return [key[len("temp_"):-len("_C")] for key in self.recording.temperatures_C]

    def _t_ref(self, sensor: str) -> float:
        for term in self.problem.base_terms:
            if term.parameters.get("sensor") == sensor and "t_ref_C" in term.parameters:
                return float(term.parameters["t_ref_C"])
        return 20.0

    def _in_sample(self, design: np.ndarray, feature: np.ndarray) -> float:
        full = np.column_stack([design, feature])
        return stats.rms(self.y - full @ stats.least_squares(full, self.y))

    def candidates(self, design: np.ndarray, present: set[str]) -> list[Candidate]:
        problem, recording = self.problem, self.recording
        duration_s = recording.duration_s
        out: list[Candidate] = []

        def add(term: Term, grid_points: int = 1) -> None:
            if term.effect == "gain_error":
                return
            feature = problem.column(term.feature(recording, problem.axis))
            if np.ptp(feature) == 0 and term.effect != "offset":
                return
            out.append(Candidate(term, feature, grid_points=grid_points))

        modelled = {(t.effect, t.parameters.get("sensor")) for t in problem.base_terms}
        if "offset" not in present and not any(t.effect == "offset" for t in problem.base_terms):
            add(Term("offset", {"value_um": 0.0}))
        if "time_drift" not in present:
            add(Term("time_drift", {"um_per_h": 0.0}))
        if recording.spindle_rpm is not None and "centrifugal_growth" not in present:
            add(Term("centrifugal_growth", {"coeff_um_per_krpm2": 0.0}))
        sensors = self._sensors()
        for sensor in sensors:
            t_ref = self._t_ref(sensor)
            if ("temperature", sensor) not in modelled and f"temperature:{sensor}" not in present:
                add(Term("temperature", {"sensor": sensor, "t_ref_C": t_ref, "coeff_um_per_K": 0.0}))
            if f"quadratic_temperature:{sensor}" not in present:
                add(Term("quadratic_temperature", {"sensor": sensor, "t_ref_C": t_ref, "coeff_um_per_K2": 0.0}))
            if problem.axis in recording.positions_mm and f"position_dependent_expansion:{sensor}" not in present \
                    and ("position_dependent_expansion", sensor) not in modelled:
                add(Term("position_dependent_expansion", {"sensor": sensor, "t_ref_C": t_ref, "p0_mm": 0.0,
                                                          "slope_um_per_m_per_K": 0.0}))
        for a, b in itertools.combinations(sensors, 2):
            if f"thermal_gradient:{a}-{b}" not in present:
                add(Term("thermal_gradient", {"sensors": [a, b], "coeff_um_per_K": 0.0}))
        # Lags: the best time constant per sensor (grid in-sample), then the asymmetric variant
        # for the two sensors whose lag fits best.
        lag_scores = []
        for sensor in sensors:
            if f"thermal_lag:{sensor}" in present:
                continue
            signal = recording.sensor(sensor)
            best: tuple[float, float] | None = None
            tried = 0
            for tau in self.settings.lag_grid_s:
                if tau > duration_s / 3:
                    continue
                tried += 1
                feature = problem.column(first_order_lag(recording.t_s, signal, tau)) - self._t_ref(sensor)
                score = self._in_sample(design, feature)
                if best is None or score < best[0]:
                    best = (score, tau)
            if best is not None:
                for tau in best[1] * np.geomspace(0.8, 1.25, 9):
                    tried += 1
                    feature = problem.column(first_order_lag(recording.t_s, signal, float(tau))) - self._t_ref(sensor)
                    score = self._in_sample(design, feature)
                    if score < best[0]:
                        best = (score, float(tau))
                lag_scores.append((best[0], sensor, best[1]))
                add(Term("thermal_lag", {"sensor": sensor, "t_ref_C": self._t_ref(sensor), "tau_s": best[1],
                                         "coeff_um_per_K": 0.0}), tried)
        for _score, sensor, _tau in sorted(lag_scores)[:2]:
            if f"heating_cooling_hysteresis:{sensor}" in present:
                continue
            signal = self._decimated_signal(sensor)
            best_h: tuple[float, float, float] | None = None
            tried = 0
            for tau_heat, tau_cool in itertools.product(self.settings.hysteresis_grid_s, repeat=2):
                if tau_heat == tau_cool or max(tau_heat, tau_cool) > duration_s / 3:
                    continue
                tried += 1
                feature = self._asymmetric_feature(signal, tau_heat, tau_cool) - self._t_ref(sensor)
                score = self._in_sample(design, feature)
                if best_h is None or score < best_h[0]:
                    best_h = (score, tau_heat, tau_cool)
            if best_h is not None:
                for factor_heat, factor_cool in itertools.product(np.geomspace(0.7, 1.4, 5), repeat=2):
                    tau_heat, tau_cool = best_h[1] * float(factor_heat), best_h[2] * float(factor_cool)
                    tried += 1
                    feature = self._asymmetric_feature(signal, tau_heat, tau_cool) - self._t_ref(sensor)
                    score = self._in_sample(design, feature)
                    if score < best_h[0]:
                        best_h = (score, tau_heat, tau_cool)
                add(Term("heating_cooling_hysteresis", {"sensor": sensor, "t_ref_C": self._t_ref(sensor),
                                                        "tau_heat_s": best_h[1], "tau_cool_s": best_h[2],
                                                        "coeff_um_per_K": 0.0}), tried)
        return out

    def _decimated_signal(self, sensor: str) -> tuple[np.ndarray, np.ndarray]:
        """The asymmetric lag runs in Python: compute it on a coarser grid (>= 30 s) and interpolate."""
        t = self.recording.t_s
        signal = self.recording.sensor(sensor)
        step = max(1, int(30.0 / max(float(np.median(np.diff(t))), 1e-9)))
        return t[::step], signal[::step]

    def _asymmetric_feature(self, decimated: tuple[np.ndarray, np.ndarray], tau_heat: float,
                            tau_cool: float) -> np.ndarray:
        t_coarse, signal = decimated
        lagged = asymmetric_lag(t_coarse, signal, tau_heat, tau_cool)
        return np.interp(self.problem.t_s, t_coarse, lagged)

    # ------------------------------------------------------------------ evaluation
    def _evaluate(self, design: np.ndarray, candidate: Candidate, folds: list[np.ndarray],
                  base_cv: stats.CrossValidation) -> Evaluation:
        full = np.column_stack([design, candidate.feature])
        cv = stats.cross_validate(full, self.y, folds)
        result = stats.fit(full, self.y)
        wins = sum(after < before for after, before in zip(cv.fold_rms_um, base_cv.fold_rms_um, strict=True))
        return Evaluation(candidate, cv, result.t_value(full.shape[1] - 1), float(result.coefficients[-1]), wins)

    def _passes(self, evaluation: Evaluation, base_cv: stats.CrossValidation, t_critical: float) -> bool:
        s = self.settings
        # Beat both the current model (refitted) and the model exactly as given: refitting a right
        # model on autocorrelated data can make it worse, and a candidate must not win by undoing that.
        reference_um = min(base_cv.rms_um, self._given_heldout_um)
        improved = evaluation.cv.rms_um <= (1 - s.min_improvement) * reference_um
        consistent = evaluation.fold_wins >= math.ceil(s.min_fold_share * len(base_cv.fold_rms_um))
        significant = abs(evaluation.t_value) >= t_critical
        term = evaluation.candidate.term.with_coefficient(evaluation.coefficient)
        return improved and consistent and significant and _bounded(term)

    def _parsimonious(self, chosen: Evaluation, passing: list[Evaluation]) -> Evaluation:
        """An effect that extends a simpler one of the same sensor by a time constant (a lag extends a
        plain temperature term, an asymmetric lag a lag) must earn that parameter as an effect earns
        its place: by ``min_improvement`` of held-out RMS over the simpler one, or the simpler wins."""
        while True:
            simpler = [e for e in passing if _extends(chosen.candidate.term, e.candidate.term)
                       and chosen.cv.rms_um > (1 - self.settings.min_improvement) * e.cv.rms_um]
            if not simpler:
                return chosen
            chosen = min(simpler, key=lambda e: e.cv.rms_um)

    @staticmethod
    def _t_critical(alpha: float, tests: int, dof: int) -> float:
        """Two-sided Student-t at ``alpha`` / ``tests`` (Bonferroni): short records need the t tail."""
        from scipy.stats import t as student_t

        return float(student_t.isf(alpha / (2 * max(tests, 1)), max(dof, 1)))

    def _screen_outliers(self, design: np.ndarray) -> None:
        residual = self.y - design @ stats.least_squares(design, self.y)
        sigma = stats.robust_sigma(residual)
        if not sigma > 0:
            return
        outliers = np.abs(residual - np.median(residual)) > self.settings.outlier_sigmas * sigma
        if outliers.any():
            keep = ~outliers
            self.data_quality.append(f"{int(outliers.sum())} outlier sample(s) beyond "
                                     f"{self.settings.outlier_sigmas:g} robust sigma set aside "
                                     f"(first at t = {float(self.problem.t_s[outliers][0]):.0f} s)")
            self.problem.y = self.problem.y[keep]
            self.problem.t_s = self.problem.t_s[keep]
            indices = np.flatnonzero(self.problem.mask)
            self.problem.mask[indices[outliers]] = False

    @property
    def y(self) -> np.ndarray:
        return self.problem.y

    # ------------------------------------------------------------------ the run
    def run(self) -> Discovery:
        problem, s = self.problem, self.settings
        base_design = np.column_stack([problem.column(c) for c in problem.base_columns]) \
            if problem.base_columns else np.empty((len(problem.y), 0))
        self._screen_outliers(base_design)
        base_design = np.column_stack([problem.column(c) for c in problem.base_columns]) \
            if problem.base_columns else np.empty((len(problem.y), 0))
        given = problem.column(problem.given_prediction)
        folds = stats.blocked_folds(len(self.y), s.folds)
        baseline_rms = stats.rms(self.y - given)
        self._given_heldout_um = baseline_rms
        recalibrated = stats.fit(base_design, self.y) if base_design.shape[1] else None
        recalibrated_rms = recalibrated.rms_um if recalibrated else baseline_rms
        discovered: list[dict[str, Any]] = []
        added_terms: list[Term] = []
        present: set[str] = set()

        # A common factor on the whole model as given.
        gain_design = given[:, None]
        gain_fit = stats.fit(gain_design, self.y)
        gain = float(gain_fit.coefficients[0])
        gain_cv = stats.cross_validate(gain_design, self.y, folds)
        recal_cv = stats.cross_validate(base_design, self.y, folds) if base_design.shape[1] else gain_cv
        explains_recalibration = (baseline_rms - gain_fit.rms_um) >= 0.9 * (baseline_rms - recalibrated_rms) \
            or base_design.shape[1] <= 1
        gain_se = float(gain_fit.standard_errors[0])
        gain_wins = sum(g < b for g, b in zip(gain_cv.fold_rms_um,
                                              [stats.rms(self.y[f] - given[f]) for f in folds], strict=True))
        if (abs(gain - 1) >= max(s.min_gain_departure, 3 * gain_se) and explains_recalibration
                and gain_cv.rms_um <= (1 - s.min_improvement) * baseline_rms
                and gain_wins >= math.ceil(s.min_fold_share * len(folds)) and 0.2 <= gain <= 5):
            design = gain_design
            base_cv = gain_cv
            present.add("gain_error")
            discovered.append({"effect": "gain_error", "parameters": {"gain": round(gain, 5)},
                               "evidence": {"heldout_rms_um": round(gain_cv.rms_um, 4),
                                            "baseline_rms_um": round(baseline_rms, 4),
                                            "gain_se": round(gain_se, 5),
                                            "why": "one common factor on the whole model explains the mismatch"}})
            gain_mode = True
        else:
            design = base_design
            base_cv = recal_cv if base_design.shape[1] else stats.CrossValidation(
                baseline_rms, tuple(stats.rms(self.y[f] - given[f]) for f in folds))
            gain_mode = False
            if base_design.shape[1] == 0:
                design = np.empty((len(self.y), 0))

        for _round in range(s.max_effects):
            candidates = self.candidates(design if design.shape[1] else given[:, None], present)
            if not candidates:
                break
            work_design = design if design.shape[1] else np.empty((len(self.y), 0))
            # Bonferroni over every hypothesis of the round, each time constant tried included.
            tests = sum(c.grid_points for c in candidates)
            t_critical = self._t_critical(s.alpha, tests, len(self.y) - work_design.shape[1] - 1)
            evaluations = [self._evaluate(work_design, c, folds, base_cv) for c in candidates]
            passing = [e for e in evaluations if self._passes(e, base_cv, t_critical)]
            if not passing:
                break
            best = min(passing, key=lambda e: e.cv.rms_um)
            equivalent = [e for e in passing if e.cv.rms_um <= best.cv.rms_um * (1 + s.equivalence)]
            chosen = min(equivalent, key=lambda e: (e.candidate.term.spec.complexity, e.cv.rms_um))
            chosen = self._parsimonious(chosen, passing)
            term = chosen.candidate.term.with_coefficient(chosen.coefficient)
            window = _locate(self.problem.t_s, chosen.coefficient * (chosen.candidate.feature
                                                                     - np.median(chosen.candidate.feature)))
            record = {
                "effect": term.effect,
                "parameters": {k: (round(v, 6) if isinstance(v, float) else v) for k, v in term.parameters.items()},
                "evidence": {
                    "heldout_rms_before_um": round(base_cv.rms_um, 4), "heldout_rms_after_um": round(chosen.cv.rms_um, 4),
                    "t_value_ar1_corrected": _finite(chosen.t_value), "t_critical": round(t_critical, 3),
                    "folds_improved": f"{chosen.fold_wins}/{len(folds)}",
                    "window": {"t_start_s": window[0][0], "t_end_s": window[0][1]} if window else None,
                    "equivalent": [e.candidate.label for e in equivalent if e is not chosen],
                    "why": EFFECTS[term.effect].description,
                },
            }
            if chosen is not best:
                record["evidence"]["resolved_to_simpler"] = best.candidate.label
            discovered.append(record)
            added_terms.append(term)
            present.add(term.effect if term.effect in ("offset", "time_drift", "centrifugal_growth")
                        else f"{term.effect}:{term.parameters.get('sensor') or '-'.join(term.parameters.get('sensors', []))}")
            design = np.column_stack([work_design, chosen.candidate.feature])
            base_cv = chosen.cv

        final = stats.fit(design, self.y) if design.shape[1] else None
        gain_reported = gain_mode
        if gain_mode and final is not None and len(discovered) > 1:
            joint_gain, joint_se = float(final.coefficients[0]), float(final.standard_errors[0])
            if abs(joint_gain - 1) < max(s.min_gain_departure, 3 * joint_se):
                # The effects found after it explain the mismatch: the common factor was their shadow.
                discovered.pop(0)
                gain_reported = False
                for record in discovered:
                    record["evidence"]["note"] = "a common gain on the model was considered and withdrawn"
        heldout_after_um = base_cv.rms_um if discovered else baseline_rms  # nothing found: the model stands
        # Coefficients of the final joint fit go into the improved model and the report.
        improved_terms = self._improved_terms(final, gain_mode, gain_reported, added_terms, discovered)
        improved = ThermalModel(problem.axis, improved_terms, "<improved>")
        improved_full = final.residual if final is not None else self.y - given
        before_residual = self.y - given
        residual_recal = recalibrated.residual if recalibrated is not None and not gain_mode else before_residual
        return Discovery(
            axis=problem.axis, baseline_rms_um=baseline_rms, recalibrated_rms_um=recalibrated_rms,
            heldout_rms_before_um=stats.rms(before_residual), heldout_rms_after_um=heldout_after_um,
            mismatch=self._mismatch(residual_recal if not discovered else before_residual),
            missing_physics=discovered, improved_model=improved, data_quality=self.data_quality,
            samples=len(self.y),
            series={"t_s": self.problem.t_s, "measured_um": self.y, "baseline_um": given,
                    "improved_um": self.y - improved_full, "residual_before_um": before_residual,
                    "residual_after_um": improved_full},
        )

    def _improved_terms(self, final: stats.Fit | None, gain_mode: bool, gain_reported: bool, added: list[Term],
                        discovered: list[dict[str, Any]]) -> list[Term]:
        """The model as given with refitted coefficients, plus the discovered terms.

        For a ``sim_`` baseline there are no terms to carry: the gain then applies to that column."""
        problem = self.problem
        if final is None:
            return list(problem.model.terms)
        coefficients = list(final.coefficients)
        if gain_mode:
            gain = float(coefficients.pop(0))
            if gain_reported:
                terms = [Term("gain_error", {"gain": round(gain, 6)})] + list(problem.base_terms)
                discovered[0]["parameters"]["gain"] = round(gain, 5)
            else:  # withdrawn: fold the small factor into the coefficients (recalibration)
                terms = [t.with_coefficient(t.coefficient * problem.model.gain * gain) for t in problem.base_terms]
        else:
            terms = [term.with_coefficient(c) for term, c in zip(problem.base_terms, coefficients, strict=False)]
            coefficients = coefficients[len(problem.base_columns):]  # a sim_ column is a column, not a term
        for term, coefficient, record in zip(added, coefficients, discovered[1 if gain_reported else 0:],
                                             strict=False):
            updated = term.with_coefficient(float(coefficient))
            terms.append(updated)
            record["parameters"][updated.spec.coefficient] = round(float(coefficient), 6)
        return terms

    def _mismatch(self, residual: np.ndarray) -> list[dict[str, Any]]:
        t = self.problem.t_s
        if len(t) < 8:
            return []
        width = max(3, len(t) // 40)
        smooth = _smooth(residual, width)
        noise = float(np.std(np.diff(residual)) / math.sqrt(2)) if len(residual) > 2 else 0.0
        if not np.max(np.abs(smooth)) > 3 * noise / math.sqrt(width) + 1e-12:
            return []
        out = []
        for start, end, _weight in _locate(t, smooth - np.median(smooth))[:5]:
            inside = (t >= start) & (t <= end)
            out.append({"t_start_s": start, "t_end_s": end, "why": self._why(inside, residual)})
        return out

    def _why(self, inside: np.ndarray, residual: np.ndarray) -> str:
        recording, mask = self.recording, self.problem.mask
        parts = [f"mean residual {float(np.mean(residual[inside])):+.2f} um "
                 f"(elsewhere {float(np.mean(residual[~inside])) if (~inside).any() else 0:+.2f} um)"]
        t_all = recording.t_s
        window = (t_all >= self.problem.t_s[inside][0]) & (t_all <= self.problem.t_s[inside][-1])
        if recording.temperatures_C:
            name, values = max(recording.temperatures_C.items(), key=lambda kv: float(np.ptp(kv[1])))
            if window.sum() > 1:
                slope = float(values[window][-1] - values[window][0])
                trend = "rises" if slope > 0.2 else "falls" if slope < -0.2 else "is steady"
                parts.append(f"{name} {trend} ({slope:+.1f} K)")
        if recording.spindle_rpm is not None and window.any():
            parts.append(f"spindle at {float(np.mean(recording.spindle_rpm[window])):.0f} rpm on average")
        axis = self.problem.axis
        if axis in recording.positions_mm and window.any():
            inside_pos = float(np.mean(recording.positions_mm[axis][window]))
            outside_pos = float(np.mean(recording.positions_mm[axis][~window])) if (~window).any() else inside_pos
            if abs(inside_pos - outside_pos) > 50:
                parts.append(f"axis {axis} at {inside_pos:.0f} mm on average (elsewhere {outside_pos:.0f} mm)")
        del mask
        return "; ".join(parts)


def discover(recording: Recording, axis: str | None = None, model: ThermalModel | None = None,
             settings: Settings | None = None) -> Discovery:
    return Discoverer(recording, axis, model, settings).run()
