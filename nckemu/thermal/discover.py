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
forward search and its guards) and ``explain`` (words, mismatch windows). This module wires them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nckemu.errors import NckConfigError

from . import explain, stats
from .library import Library
from .problem import Problem
from .readings import prepare
from .recording import Recording
from .selector import Baseline, Path, Selector
from .settings import Settings
from .splitters import Blocks, Splitter, held_out_masks
from .terms import Term, ThermalModel

__all__ = ["Discoverer", "Discovery", "Settings", "discover"]


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
        self.settings = settings or Settings()
        readings = prepare(recording, self.settings)
        self.data_quality: list[str] = list(readings.data_quality)
        self.sensor_noise_C = readings.sensor_noise_C
        self.problem = Problem([(recording.source, readings)], axis, model)
        self.splitter: Splitter = splitter or Blocks(self.settings.folds)

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
        recal_cv = stats.cross_validate(base_design, self.y, folds) if base_design.shape[1] else given_cv
        # A model whose coefficients are the least-squares optimum on this very record was calibrated
        # on it: its RMS "as given" is an in-sample figure, not a held-out one. Compare like with like:
        # the baseline refitted per fold, under the same blocked cross-validation as the candidates.
        calibrated_here = recalibrated is not None and self._calibrated_on_record()
        base_noise, given_noise = self._noise()
        extra = len(problem.runs) if problem.per_run_offset else 0
        return Baseline(base_design, given, folds, baseline_rms, recalibrated, recalibrated_rms, given_cv, recal_cv,
                        calibrated_here, base_noise, given_noise, extra)

    # ------------------------------------------------------------------ the run
    def run(self) -> Discovery:
        setup = self.baseline()
        selector = Selector(self.y, self.problem.t_s, Library(self.problem, self.settings), self.settings, setup)
        recalibrate = selector.search(gain_mode=False)
        chosen, preferred = recalibrate, explain.recalibration_words(
            [d["effect"] for d in recalibrate.discovered], setup.calibrated_here, None)
        if selector.gain_eligible():
            with_gain = selector.search(gain_mode=True)
            chosen, preferred = selector.prefer(recalibrate, with_gain)
        return self._finish(setup, chosen, preferred)

    def _finish(self, setup: Baseline, path: Path, preferred: str) -> Discovery:
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
        mismatch = explain.mismatch(problem.recording, problem.axis, problem.t_s,
                                    residual_recal if not discovered else before_residual)
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
            coefficients = coefficients[len(problem.runs[0].base_columns):]  # a sim_ column is a column, not a term
            records = discovered
        for term, coefficient, record in zip(added, coefficients, records, strict=False):
            updated = term.with_coefficient(float(coefficient))
            terms.append(updated)
            record["parameters"][updated.spec.coefficient] = round(float(coefficient), 6)
        return terms


def discover(recording: Recording, axis: str | None = None, model: ThermalModel | None = None,
             settings: Settings | None = None) -> Discovery:
    return Discoverer(recording, axis, model, settings).run()
