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
   the sensors' own white noise adds through the features (errors in variables): a gradient of two
   raw readings carries that noise, a lag filters it away, and a quiet lag of a correlated sensor must
   not win on that alone. Removing the noise may make up for it within the margin of equivalence, not
   beyond: a candidate that predicts worse as measured and carries more noise than the margin (a large
   coefficient on raw readings, standing in for a lag) is set aside.
3. Gross outliers (far beyond the robust noise scale) are set aside and reported as data quality.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from nckemu.errors import NckConfigError

from . import quality, stats
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
    # A gain error claims that a gauge or a scale reads gain x the truth: only physical values.
    gain_range: tuple[float, float] = (0.5, 2.0)
    # The model as given fits the record within this share of the least-squares optimum's RMS: it
    # was calibrated on the record, and its RMS as given is in-sample.
    calibrated_tolerance: float = 0.002
    glitch_sigmas: float = 8.0          # sensor bursts beyond this many robust sigma are glitches
    glitch_min_K: float = 0.3           # ... and beyond this many kelvin
    # Temperature readings are averaged over this centred window before features are built: a
    # structure does not follow a sensor's white noise, and a difference of two sensors (a gradient)
    # carries the noise of both against a small signal (errors in variables).
    sensor_smoothing_s: float = 300.0
    # The fixed draw of sensor noise that measures how much of it each feature passes on (the
    # errors-in-variables share of a candidate's held-out RMS): fixed, so a run is repeatable.
    noise_draw_seed: int = 0
    lag_grid_s: tuple[float, ...] = tuple(float(v) for v in np.geomspace(300.0, 6 * 3600.0, 18))
    hysteresis_grid_s: tuple[float, ...] = tuple(float(v) for v in np.geomspace(600.0, 4 * 3600.0, 8))


@dataclass
class Candidate:
    term: Term
    feature: np.ndarray
    # What the sensors' white noise contributes to the feature (one draw of it), gauge samples only.
    noise: np.ndarray
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
    # Held-out RMS without the sensors' noise carried by the fitted model's features: what candidates
    # are ranked on (held-out RMS itself still decides whether one is admitted at all).
    ranked_rms_um: float


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
    preferred: str = ""
    calibrated_on_record: bool = False

    def to_json(self) -> dict[str, Any]:
        return {
            "axis": self.axis, "samples": self.samples,
            "baseline_rms_um": round(self.baseline_rms_um, 4),
            "recalibrated_rms_um": round(self.recalibrated_rms_um, 4),
            "heldout_rms_before_um": round(self.heldout_rms_before_um, 4),
            "heldout_rms_after_um": round(self.heldout_rms_after_um, 4),
            "mismatch": self.mismatch, "missing_physics": self.missing_physics,
            "data_quality": self.data_quality, "preferred": self.preferred,
            "calibrated_on_record": self.calibrated_on_record,
        }


@dataclass
class _Setup:
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
    gain: tuple[float, float, stats.CrossValidation] = (math.nan, math.nan, stats.CrossValidation(math.nan, ()))


@dataclass
class _Path:
    """One line of explanation: the recalibrated model plus effects, or gain x model plus effects."""
    gain_mode: bool
    design: np.ndarray
    base_cv: stats.CrossValidation
    noise: np.ndarray               # sensor noise carried by each column of design
    discovered: list[dict[str, Any]] = field(default_factory=list)
    added: list[Term] = field(default_factory=list)
    present: set[str] = field(default_factory=set)
    final: stats.Fit | None = None


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
    if term.effect == "thermal_lag":
        return 60.0 <= float(p["tau_s"]) <= 48 * 3600.0
    if term.effect == "heating_cooling_hysteresis":
        return all(60.0 <= float(p[key]) <= 48 * 3600.0 for key in ("tau_heat_s", "tau_cool_s"))
    if term.effect == "gain_error":
        return 0.2 <= c <= 5.0
    return math.isfinite(c)


# Effects of one sensor that contain another as a special case (a time constant going to zero, or
# heating and cooling at the same rate).
_EXTENDS = {("thermal_lag", "temperature"), ("heating_cooling_hysteresis", "temperature"),
            ("heating_cooling_hysteresis", "thermal_lag")}


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


def _time_constants(term: Term) -> int:
    return sum(key in term.parameters for key in ("tau_s", "tau_heat_s", "tau_cool_s"))


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
        self.data_quality: list[str] = []
        self.raw_recording = recording
        self.sensor_noise_C: dict[str, float] = {}
        recording = self._repair_glitches(recording)
        self.problem = _Problem(recording, axis, model)
        self.recording = recording
        self.noisy_recording = self._with_noise_draw(recording)

    def _smooth_sensor(self, t_s: np.ndarray, values: np.ndarray) -> np.ndarray:
        if len(t_s) < 3 or self.settings.sensor_smoothing_s <= 0:
            return values
        width = int(round(self.settings.sensor_smoothing_s / max(float(np.median(np.diff(t_s))), 1e-9)))
        if width < 3:
            return values
        return uniform_filter1d(values, size=width | 1, mode="nearest")

    def _repair_glitches(self, recording: Recording) -> Recording:
        """Short bursts of a temperature reading that no structure follows are bridged before any
        feature sees them (fed through a gradient or a lag they become spikes of the improved model
        that the gauge never showed), and reported under ``data_quality``."""
        repaired = dict(recording.temperatures_C)
        for name, values in recording.temperatures_C.items():
            glitches = quality.find_glitches(recording.t_s, values, sigmas=self.settings.glitch_sigmas,
                                             min_jump_K=self.settings.glitch_min_K)
            if glitches is None:
                continue
            repaired[name] = quality.bridge(recording.t_s, values, glitches.samples)
            self.data_quality.append(
                f"{name}: {glitches.bursts} glitch burst(s), {int(glitches.samples.sum())} sample(s), up to "
                f"{glitches.peak_K:.2f} K off the sensor's running median (first at t = {glitches.first_t_s:.0f} s "
                f"= {glitches.first_t_s / 3600:.2f} h): bridged by interpolation before fitting")
        self.sensor_noise_C = {name: self._white_noise_C(values) for name, values in repaired.items()}
        repaired = {name: self._smooth_sensor(recording.t_s, values) for name, values in repaired.items()}
        return Recording(recording.source, recording.t_s, repaired, recording.spindle_rpm, recording.positions_mm,
                         recording.errors_um, recording.simulated_um)

    @staticmethod
    def _white_noise_C(values: np.ndarray) -> float:
        """A sensor's white noise: second differences cancel a slowly curving temperature and leave
        6 sigma^2 of white noise; the robust scale ignores the few samples where heating starts."""
        if len(values) < 8:
            return 0.0
        sigma = stats.robust_sigma(np.diff(values, 2)) / math.sqrt(6.0)
        return sigma if math.isfinite(sigma) else 0.0

    def _with_noise_draw(self, recording: Recording) -> Recording:
        """The (averaged) readings plus one more draw of each sensor's white noise, averaged alike: a
        feature computed on it minus the same feature on the readings is what the feature passes on of
        the sensors' noise, whatever the feature does (a difference, a lag, a square)."""
        rng = np.random.default_rng(self.settings.noise_draw_seed)
        noisy = {}
        for name, values in recording.temperatures_C.items():
            draw = rng.normal(0.0, self.sensor_noise_C.get(name, 0.0), len(values))
            noisy[name] = values + self._smooth_sensor(recording.t_s, draw)  # the averaging is linear
        return Recording(recording.source, recording.t_s, noisy, recording.spindle_rpm, recording.positions_mm,
                         recording.errors_um, recording.simulated_um)

    def _feature_noise(self, term: Term, clean: np.ndarray | None = None) -> np.ndarray:
        """The sensor noise ``term``'s feature carries, on the gauge samples (``clean``: its feature there)."""
        problem = self.problem
        if clean is None:
            clean = problem.column(term.feature(self.recording, problem.axis))
        return problem.column(term.feature(self.noisy_recording, problem.axis)) - clean

    def _model_noise(self) -> np.ndarray:
        """The sensor noise carried by the model as given (none for a ``sim_`` column)."""
        problem = self.problem
        if not problem.base_terms:
            return np.zeros(len(problem.y))
        return problem.column(problem.model.predict_um(self.noisy_recording) - problem.model.predict_um(self.recording))

    def _base_noise(self) -> np.ndarray:
        if not self.problem.base_terms:  # a sim_ column, or no columns at all
            return np.zeros((len(self.problem.y), len(self.problem.base_columns)))
        return np.column_stack([self._feature_noise(term) for term in self.problem.base_terms])

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
            out.append(Candidate(term, feature, self._feature_noise(term, feature), grid_points=grid_points))

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
            # The search runs on the >= 30 s grid (the readings are averaged over minutes already);
            # the chosen term's feature is computed on every sample.
            signal = self._decimated_signal(sensor)
            best: tuple[float, float] | None = None
            tried = 0
            for tau in self.settings.lag_grid_s:
                if tau > duration_s / 3:
                    continue
                tried += 1
                feature = self._lag_feature(signal, tau) - self._t_ref(sensor)
                score = self._in_sample(design, feature)
                if best is None or score < best[0]:
                    best = (score, tau)
            if best is not None:
                for tau in best[1] * np.geomspace(0.8, 1.25, 9):
                    tried += 1
                    feature = self._lag_feature(signal, float(tau)) - self._t_ref(sensor)
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
                # Refine around the grid point (not around the last improvement: that compounded,
                # and walked a cooling time constant to 21 h on a 36 h null record).
                grid_heat, grid_cool = best_h[1], best_h[2]
                for factor_heat, factor_cool in itertools.product(np.geomspace(0.7, 1.4, 5), repeat=2):
                    tau_heat, tau_cool = grid_heat * float(factor_heat), grid_cool * float(factor_cool)
                    if max(tau_heat, tau_cool) > duration_s / 3:
                        continue
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

    def _lag_feature(self, decimated: tuple[np.ndarray, np.ndarray], tau_s: float) -> np.ndarray:
        t_coarse, signal = decimated
        return np.interp(self.problem.t_s, t_coarse, first_order_lag(t_coarse, signal, tau_s))

    def _asymmetric_feature(self, decimated: tuple[np.ndarray, np.ndarray], tau_heat: float,
                            tau_cool: float) -> np.ndarray:
        t_coarse, signal = decimated
        lagged = asymmetric_lag(t_coarse, signal, tau_heat, tau_cool)
        return np.interp(self.problem.t_s, t_coarse, lagged)

    # ------------------------------------------------------------------ evaluation
    def _evaluate(self, design: np.ndarray, noise: np.ndarray, candidate: Candidate, folds: list[np.ndarray],
                  base_cv: stats.CrossValidation) -> Evaluation:
        full = np.column_stack([design, candidate.feature])
        cv = stats.cross_validate(full, self.y, folds)
        result = stats.fit(full, self.y)
        wins = sum(after < before for after, before in zip(cv.fold_rms_um, base_cv.fold_rms_um, strict=True))
        # Errors in variables: noise n in the features adds mean((n @ b)^2) to the squared error of
        # the fitted model's prediction, independent of the gauge's noise and of the physics.
        carried = float(np.mean(np.square(np.column_stack([noise, candidate.noise]) @ result.coefficients)))
        ranked = math.sqrt(max(cv.rms_um ** 2 - carried, 0.0))
        return Evaluation(candidate, cv, result.t_value(full.shape[1] - 1), float(result.coefficients[-1]), wins,
                          ranked)

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

    def _margin(self, *evaluations: Evaluation) -> float:
        """Held-out RMS within this share is "as good": a time constant is picked on the whole record,
        so the held-out RMS of an effect that has one is optimistic; one more share per time constant."""
        return self.settings.equivalence * (1 + max(_time_constants(e.candidate.term) for e in evaluations))

    def _equivalent(self, passing: list[Evaluation]) -> tuple[Evaluation, float, list[Evaluation]]:
        """The best candidate on held-out RMS without the sensors' noise, its margin, and the candidates
        within that margin of it.

        Removing the noise may make up for it within the margin of equivalence, not beyond. Near-collinear
        effects (a gradient of two sensors and a lag of a third all follow the spindle's load) fit the
        shape alike, and then the sensors' noise is all the record tells them apart by. A candidate
        that predicts the gauge worse than another as measured, and whose features carry more of the
        noise than the pair's margin (a large coefficient on raw readings: held-out RMS with / without
        the noise), ranks where it does on the correction, not on the record: it is set aside. The
        best as measured always stays."""
        def carried(e: Evaluation) -> float:
            return e.cv.rms_um / e.ranked_rms_um if e.ranked_rms_um > 0 else math.inf

        pool = [e for e in passing
                if not any(other.cv.rms_um < e.cv.rms_um
                           and carried(e) > (1 + self._margin(e, other)) * carried(other) for other in passing)]
        best = min(pool, key=lambda e: e.ranked_rms_um)
        margin = self._margin(best)
        return best, margin, [e for e in pool if e.ranked_rms_um <= best.ranked_rms_um * (1 + margin)]

    def _parsimonious(self, chosen: Evaluation, passing: list[Evaluation]) -> Evaluation:
        """An effect that extends a simpler one of the same sensor by a time constant (a lag extends a
        plain temperature term, an asymmetric lag a lag) must earn that parameter as an effect earns
        its place: by ``min_improvement`` of held-out RMS over the simpler one, or the simpler wins."""
        while True:
            simpler = [e for e in passing if _extends(chosen.candidate.term, e.candidate.term)
                       and chosen.ranked_rms_um > (1 - self.settings.min_improvement) * e.ranked_rms_um]
            if not simpler:
                return chosen
            chosen = min(simpler, key=lambda e: e.ranked_rms_um)

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
        outliers = _isolated(np.abs(residual - np.median(residual)) > self.settings.outlier_sigmas * sigma)
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
        setup = self._setup()
        recalibrate = self._search(setup, gain_mode=False)
        chosen, preferred = recalibrate, self._recalibration_words(setup, recalibrate, None)
        if self._gain_eligible(setup):
            with_gain = self._search(setup, gain_mode=True)
            chosen, preferred = self._prefer(setup, recalibrate, with_gain)
        return self._finish(setup, chosen, preferred)

    def _setup(self) -> _Setup:
        problem = self.problem
        base_design = self._base_design()
        self._screen_outliers(base_design)
        base_design = self._base_design()
        given = problem.column(problem.given_prediction)
        folds = stats.blocked_folds(len(self.y), self.settings.folds)
        baseline_rms = stats.rms(self.y - given)
        recalibrated = stats.fit(base_design, self.y) if base_design.shape[1] else None
        recalibrated_rms = recalibrated.rms_um if recalibrated else baseline_rms
        given_cv = stats.CrossValidation(baseline_rms, tuple(stats.rms(self.y[f] - given[f]) for f in folds))
        recal_cv = stats.cross_validate(base_design, self.y, folds) if base_design.shape[1] else given_cv
        # A model whose coefficients are the least-squares optimum on this very record was calibrated
        # on it: its RMS "as given" is an in-sample figure, not a held-out one. Compare like with like:
        # the baseline refitted per fold, under the same blocked cross-validation as the candidates.
        calibrated_here = recalibrated is not None and self._calibrated_on_record()
        self._given_heldout_um = math.inf if calibrated_here else baseline_rms
        return _Setup(base_design, given, folds, baseline_rms, recalibrated, recalibrated_rms, given_cv, recal_cv,
                      calibrated_here, self._base_noise(), self._model_noise())

    def _calibrated_on_record(self) -> bool:
        """Were the given coefficients fitted by least squares on this record? Judged on the readings
        as recorded (before glitch repair and averaging): RMS as given within ``calibrated_tolerance``
        of the least-squares optimum's."""
        problem, raw = self.problem, self.raw_recording
        if problem.base_terms:
            columns = np.column_stack([term.feature(raw, problem.axis)[problem.mask] for term in problem.base_terms])
            given = problem.model.predict_um(raw)[problem.mask]
        else:  # a sim_ column: nothing was averaged
            columns = np.column_stack([problem.column(c) for c in problem.base_columns])
            given = problem.column(problem.given_prediction)
        optimum = stats.rms(self.y - columns @ stats.least_squares(columns, self.y))
        return stats.rms(self.y - given) <= optimum * (1 + self.settings.calibrated_tolerance)

    def _base_design(self) -> np.ndarray:
        problem = self.problem
        if not problem.base_columns:
            return np.empty((len(problem.y), 0))
        return np.column_stack([problem.column(c) for c in problem.base_columns])

    def _gain_eligible(self, setup: _Setup) -> bool:
        """One common factor on the model as given: physical (``gain_range``), departing from 1 by
        more than ``min_gain_departure`` and 3 standard errors, explaining (>= 90 % of) what
        recalibration explains, and improving held-out RMS in most blocks."""
        s, y, given = self.settings, self.y, setup.given
        gain_design = given[:, None]
        gain_fit = stats.fit(gain_design, y)
        gain, gain_se = float(gain_fit.coefficients[0]), float(gain_fit.standard_errors[0])
        gain_cv = stats.cross_validate(gain_design, y, setup.folds)
        explains = (setup.baseline_rms - gain_fit.rms_um) >= 0.9 * (setup.baseline_rms - setup.recalibrated_rms) \
            or setup.base_design.shape[1] <= 1
        wins = sum(g < b for g, b in zip(gain_cv.fold_rms_um, setup.given_cv.fold_rms_um, strict=True))
        setup.gain = (gain, gain_se, gain_cv)
        return (self._gain_physical(gain, gain_se) and explains
                and gain_cv.rms_um <= (1 - s.min_improvement) * setup.baseline_rms
                and wins >= math.ceil(s.min_fold_share * len(setup.folds)))

    def _gain_physical(self, gain: float, gain_se: float) -> bool:
        s = self.settings
        return s.gain_range[0] <= gain <= s.gain_range[1] and abs(gain - 1) >= max(s.min_gain_departure, 3 * gain_se)

    def _search(self, setup: _Setup, gain_mode: bool) -> _Path:
        """Add effects one round at a time to the recalibrated model (or to gain x the model as given)."""
        s = self.settings
        if gain_mode:
            gain, gain_se, gain_cv = setup.gain
            path = _Path(True, setup.given[:, None], gain_cv, setup.given_noise[:, None])
            path.present.add("gain_error")
            path.discovered.append({"effect": "gain_error", "parameters": {"gain": round(gain, 5)},
                                    "evidence": {"heldout_rms_before_um": round(setup.baseline_rms, 4),
                                                 "heldout_rms_after_um": round(gain_cv.rms_um, 4),
                                                 "baseline_rms_um": round(setup.baseline_rms, 4),
                                                 "gain_se": round(gain_se, 5), "equivalent": [],
                                                 "why": "one common factor on the whole model explains the mismatch"}})
        else:
            path = _Path(False, setup.base_design, setup.recal_cv, setup.base_noise)
        for _round in range(s.max_effects):
            if not self._round(setup, path):
                break
        path.final = stats.fit(path.design, self.y) if path.design.shape[1] else None
        return path

    def _round(self, setup: _Setup, path: _Path) -> bool:
        s, folds = self.settings, setup.folds
        design = path.design
        candidates = self.candidates(design if design.shape[1] else setup.given[:, None], path.present)
        if not candidates:
            return False
        # Bonferroni over every hypothesis of the round, each time constant tried included.
        tests = sum(c.grid_points for c in candidates)
        t_critical = self._t_critical(s.alpha, tests, len(self.y) - design.shape[1] - 1)
        evaluations = [self._evaluate(design, path.noise, c, folds, path.base_cv) for c in candidates]
        passing = [e for e in evaluations if self._passes(e, path.base_cv, t_critical)]
        if not passing:
            return False
        best, margin, equivalent = self._equivalent(passing)
        chosen = min(equivalent, key=lambda e: (e.candidate.term.spec.complexity, e.ranked_rms_um))
        chosen = self._parsimonious(chosen, passing)
        term = chosen.candidate.term.with_coefficient(chosen.coefficient)
        window = _locate(self.problem.t_s, chosen.coefficient * (chosen.candidate.feature
                                                                 - np.median(chosen.candidate.feature)))
        evidence: dict[str, Any] = {
            "heldout_rms_before_um": round(path.base_cv.rms_um, 4), "heldout_rms_after_um": round(chosen.cv.rms_um, 4),
            "heldout_rms_without_sensor_noise_um": round(chosen.ranked_rms_um, 4),
            "t_value_ar1_corrected": _finite(chosen.t_value), "t_critical": round(t_critical, 3),
            "folds_improved": f"{chosen.fold_wins}/{len(folds)}",
            "window": {"t_start_s": window[0][0], "t_end_s": window[0][1]} if window else None,
            "equivalent": [{"effect": e.candidate.label, "heldout_rms_um": round(e.cv.rms_um, 4),
                            "heldout_rms_without_sensor_noise_um": round(e.ranked_rms_um, 4)}
                           for e in equivalent if e is not chosen],
            "why": EFFECTS[term.effect].description,
        }
        if chosen is not best:
            evidence["resolved_to_simpler"] = best.candidate.label
        evidence["preferred"] = self._preference_words(chosen, best, equivalent, margin)
        path.discovered.append({"effect": term.effect, "parameters": {
            k: (round(v, 6) if isinstance(v, float) else v) for k, v in term.parameters.items()}, "evidence": evidence})
        path.added.append(term)
        path.present.add(term.effect if term.effect in ("offset", "time_drift", "centrifugal_growth")
                         else f"{term.effect}:{term.parameters.get('sensor') or '-'.join(term.parameters.get('sensors', []))}")
        path.design = np.column_stack([design, chosen.candidate.feature])
        path.noise = np.column_stack([path.noise, chosen.candidate.noise])
        path.base_cv = chosen.cv
        return True

    @staticmethod
    def _preference_words(chosen: Evaluation, best: Evaluation, equivalent: list[Evaluation], margin: float) -> str:
        label = chosen.candidate.label
        if chosen is not best and chosen not in equivalent:
            return (f"{label} preferred to {best.candidate.label}: the time constant of the latter improves "
                    f"held-out RMS by less than the bar an effect must clear")
        others = [e.candidate.label for e in equivalent if e is not chosen]
        if not others:
            return f"{label}: passed every guard, and no other explanation came within {margin:.0%} of its held-out RMS"
        if chosen is best:
            return f"{label}: best held-out RMS and simplest; {', '.join(others)} explain the data almost as well"
        return (f"{label} preferred as the simplest of equivalent explanations (held-out RMS within {margin:.0%} "
                f"of the best, {best.ranked_rms_um:.3f} um without the sensors' noise): "
                f"{', '.join(others)}")

    def _prefer(self, setup: _Setup, recalibrate: _Path, with_gain: _Path) -> tuple[_Path, str]:
        """A gain error is a claim about a gauge or a scale. It is named only if it stays physical
        once the other effects are in, and explains the mismatch better than recalibrating the model
        and naming the physics does (or as well, when recalibration finds no physics, or when the
        model has a single coefficient, whose refit *is* a gain)."""
        s = self.settings
        final = with_gain.final
        joint_gain, joint_se = (float(final.coefficients[0]), float(final.standard_errors[0])) \
            if final is not None else (math.nan, math.nan)
        cv_gain, cv_recal = with_gain.base_cv.rms_um, recalibrate.base_cv.rms_um
        alternative = {"effect": "recalibration" + "".join(f" + {d['effect']}" for d in recalibrate.discovered),
                       "heldout_rms_um": round(cv_recal, 4)}
        if not self._gain_physical(joint_gain, joint_se):
            why = (f"a common gain was considered and withdrawn: with the other effects in, it is {joint_gain:.3g} "
                   f"(physical range {s.gain_range[0]:g}..{s.gain_range[1]:g}, and it must depart from 1)")
            return recalibrate, self._recalibration_words(setup, recalibrate, why)
        single = setup.base_design.shape[1] <= 1
        if single or not recalibrate.discovered or cv_gain < (1 - s.equivalence) * cv_recal:
            reason = ("the model has one coefficient: its refit is the gain" if single else
                      "recalibrating the model's coefficients finds no physics the gain does not explain"
                      if not recalibrate.discovered else
                      f"gain x model explains held-out data better ({cv_gain:.3f} um) than recalibrating and "
                      f"adding physics ({cv_recal:.3f} um)")
            if not single:  # with one coefficient, recalibration is the same model as the gain
                with_gain.discovered[0]["evidence"]["equivalent"] = [alternative]
            words = f"gain_error preferred: {reason}"
            with_gain.discovered[0]["evidence"]["preferred"] = words
            return with_gain, words
        why = (f"a common gain of {joint_gain:.3g} was considered: held-out {cv_gain:.3f} um against "
               f"{cv_recal:.3f} um for recalibration + physics, not better by {s.equivalence:.0%}")
        for record in recalibrate.discovered:
            record["evidence"]["note"] = "a common gain on the model was considered and set aside"
        if recalibrate.discovered:
            recalibrate.discovered[0]["evidence"]["equivalent"].append(
                {"effect": "gain_error", "gain": round(joint_gain, 5), "heldout_rms_um": round(cv_gain, 4)})
        return recalibrate, self._recalibration_words(setup, recalibrate, why)

    def _recalibration_words(self, setup: _Setup, path: _Path, gain_note: str | None) -> str:
        if path.discovered:
            words = (f"the model recalibrated (its own coefficients refitted) plus "
                     f"{', '.join(d['effect'] for d in path.discovered)}: each passed the held-out, "
                     f"fold and t-test guards against the recalibrated model")
        else:
            words = "nothing passed the guards: the model stands (recalibration is not physics)"
        if setup.calibrated_here:
            words += ("; the model as given was calibrated on this record, so candidates were compared with "
                      "it refitted per fold under the same blocked cross-validation")
        return words + (f"; {gain_note}" if gain_note else "")

    def _finish(self, setup: _Setup, path: _Path, preferred: str) -> Discovery:
        problem, given, final = self.problem, setup.given, path.final
        discovered = path.discovered
        heldout_after_um = path.base_cv.rms_um if discovered else setup.baseline_rms  # nothing found: it stands
        # Coefficients of the final joint fit go into the improved model and the report.
        improved_terms = self._improved_terms(final, path.gain_mode, path.added, discovered)
        improved = ThermalModel(problem.axis, improved_terms, "<improved>")
        improved_full = final.residual if final is not None else self.y - given
        before_residual = self.y - given
        residual_recal = setup.recalibrated.residual \
            if setup.recalibrated is not None and not path.gain_mode else before_residual
        return Discovery(
            axis=problem.axis, baseline_rms_um=setup.baseline_rms, recalibrated_rms_um=setup.recalibrated_rms,
            heldout_rms_before_um=stats.rms(before_residual), heldout_rms_after_um=heldout_after_um,
            mismatch=self._mismatch(residual_recal if not discovered else before_residual),
            missing_physics=discovered, improved_model=improved, data_quality=self.data_quality,
            samples=len(self.y), preferred=preferred, calibrated_on_record=setup.calibrated_here,
            series={"t_s": self.problem.t_s, "measured_um": self.y, "baseline_um": given,
                    "improved_um": self.y - improved_full, "residual_before_um": before_residual,
                    "residual_after_um": improved_full},
        )

    def _improved_terms(self, final: stats.Fit | None, gain_mode: bool, added: list[Term],
                        discovered: list[dict[str, Any]]) -> list[Term]:
        """The model as given with refitted coefficients, plus the discovered terms.

        For a ``sim_`` baseline there are no terms to carry: the gain then applies to that column."""
        problem = self.problem
        if final is None:
            return list(problem.model.terms)
        coefficients = list(final.coefficients)
        if gain_mode:
            gain = float(coefficients.pop(0))
            terms = [Term("gain_error", {"gain": round(gain * problem.model.gain, 6)})] + list(problem.base_terms)
            discovered[0]["parameters"]["gain"] = round(gain, 5)
            records = discovered[1:]
        else:
            terms = [term.with_coefficient(c) for term, c in zip(problem.base_terms, coefficients, strict=False)]
            coefficients = coefficients[len(problem.base_columns):]  # a sim_ column is a column, not a term
            records = discovered
        for term, coefficient, record in zip(added, coefficients, records, strict=False):
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
