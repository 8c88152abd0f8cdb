"""What discovery explains: the measured samples of one axis over one run or several, the
baseline's columns, and any term's feature on those samples.

With several runs, each run has its own constant offset (a machine is re-referenced at the start of
a run). It is fitted on that run alone, always: every column and the gauge are centred per run
before anything is fitted (a regression on centred data gives the same coefficients as one with an
offset per run, Frisch-Waugh-Lovell), so the offset is part of the baseline and of every candidate
alike, and a held-out run's offset is its own.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from nckemu.errors import NckConfigError
from nckemu.thermal.model.terms import Term, ThermalModel
from nckemu.thermal.recordings.recording import Recording

from .readings import Readings


@dataclass
class Run:
    name: str
    readings: Readings
    mask: np.ndarray                    # the run's samples the gauge measured (and not set aside)
    given_prediction: np.ndarray        # the model as given, on every sample of the run
    base_columns: list[np.ndarray]      # what the baseline's free coefficients multiply, every sample


class Problem:
    """The measured samples of one axis and the baseline's columns, over one run or several."""

    def __init__(self, runs: list[tuple[str, Readings]], axis: str, model: ThermalModel | None,
                 per_run_offset: bool = False) -> None:
        self.axis = axis
        self.per_run_offset = per_run_offset
        if model is None:
            self.model = ThermalModel(axis, [], "<sim column>")
            self.base_terms: list[Term] = []
        else:
            self.model = model
            # A constant is the runs' own offsets already: it would be a column of zeros.
            self.base_terms = [t for t in model.additive_terms() if not (per_run_offset and t.effect == "offset")]
        self.runs = [self._run(name, readings, model) for name, readings in runs]
        self._gather()
        if len(self.y) < 8:
            raise NckConfigError(f"only {len(self.y)} measured err_{axis}_um samples", path=self.runs[0].readings.raw.source)

    def _run(self, name: str, readings: Readings, model: ThermalModel | None) -> Run:
        recording, axis = readings.recording, self.axis
        if axis not in recording.errors_um:
            raise NckConfigError(f"the recording has no err_{axis}_um column", path=recording.source,
                                 field=f"err_{axis}_um")
        measured = ~np.isnan(recording.errors_um[axis])
        if model is None:
            if axis not in recording.simulated_um:
                raise NckConfigError(f"no baseline: give --model or a sim_{axis}_um column",
                                     path=recording.source, field=f"sim_{axis}_um")
            simulation = recording.simulated_um[axis]
            measured &= ~np.isnan(simulation)
            return Run(name, readings, measured, np.nan_to_num(simulation), [np.nan_to_num(simulation)])
        return Run(name, readings, measured, model.predict_um(recording),
                   [term.feature(recording, axis) for term in self.base_terms])

    def _gather(self) -> None:
        self.raw_y = np.concatenate([run.readings.recording.errors_um[self.axis][run.mask] for run in self.runs])
        self.t_s = np.concatenate([run.readings.recording.t_s[run.mask] for run in self.runs])
        self.groups = np.concatenate([np.full(int(run.mask.sum()), index) for index, run in enumerate(self.runs)])
        self.y = self.within(self.raw_y)
        self.version = getattr(self, "version", -1) + 1  # features cached on the samples are stale now

    @property
    def recording(self) -> Recording:
        """The first run's averaged readings (the only one, for a single run)."""
        return self.runs[0].readings.recording

    @property
    def mask(self) -> np.ndarray:
        return self.runs[0].mask

    def within(self, values: np.ndarray) -> np.ndarray:
        """Gauge-sample values with each run's own mean taken off (several runs), or as they are."""
        if not self.per_run_offset:
            return values
        counts = np.bincount(self.groups)
        means = np.bincount(self.groups, weights=values) / np.maximum(counts, 1)
        return values - means[self.groups]

    def run_means(self, values: np.ndarray) -> np.ndarray:
        counts = np.bincount(self.groups, minlength=len(self.runs))
        return np.bincount(self.groups, weights=values, minlength=len(self.runs)) / np.maximum(counts, 1)

    def gather(self, per_run: Callable[[Run], np.ndarray]) -> np.ndarray:
        """A per-sample value of every run, on the gauge samples, concatenated (not centred)."""
        if len(self.runs) == 1:
            run = self.runs[0]
            return per_run(run)[run.mask]
        return np.concatenate([per_run(run)[run.mask] for run in self.runs])

    def column(self, per_run: Callable[[Run], np.ndarray]) -> np.ndarray:
        return self.within(self.gather(per_run))

    def gauge_column(self, per_run: Callable[[Run], np.ndarray]) -> np.ndarray:
        """Like ``column``, for a value computed on the run's gauge samples already."""
        if len(self.runs) == 1:
            return self.within(per_run(self.runs[0]))
        return self.within(np.concatenate([per_run(run) for run in self.runs]))

    def feature(self, term: Term, noisy: bool = False) -> np.ndarray:
        """The term's feature on the gauge samples; zero in a run that lacks a column it needs (several
        runs: the term then contributes nothing there, and that run does not inform its coefficient)."""
        axis = self.axis

        def per_run(run: Run) -> np.ndarray:
            recording = run.readings.noisy if noisy else run.readings.recording
            if len(self.runs) > 1 and not self.has_columns(run, term):
                return np.zeros(len(recording.t_s))
            return term.feature(recording, axis)
        return self.column(per_run)

    def has_columns(self, run: Run, term: Term) -> bool:
        """Does the run have every column ``term`` needs?"""
        recording = run.readings.recording
        p = term.parameters
        sensors = list(p.get("sensors", [])) + ([p["sensor"]] if "sensor" in p else [])
        if any(f"temp_{s}_C" not in recording.temperatures_C for s in sensors):
            return False
        if term.spec.uses_spindle and recording.spindle_rpm is None:
            return False
        return not (term.spec.uses_position and self.axis not in recording.positions_mm)

    def runs_with(self, term: Term) -> np.ndarray:
        """Per run: has it every column ``term`` needs?"""
        return np.array([self.has_columns(run, term) for run in self.runs])

    def set_aside(self, outliers: np.ndarray) -> None:
        """Drop gauge samples (a boolean over the current samples) from every run."""
        start = 0
        for run in self.runs:
            count = int(run.mask.sum())
            indices = np.flatnonzero(run.mask)
            run.mask[indices[outliers[start:start + count]]] = False
            start += count
        self._gather()
