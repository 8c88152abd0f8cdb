"""The candidate library: every named effect of the vocabulary that could explain what the baseline
leaves, as a term with its feature on the gauge samples (and the sensor noise that feature carries).

Like PySINDy's feature libraries, it only builds columns; what is fitted and judged is the
selector's. A lag's or a hysteresis's time constant is picked here on a grid, in-sample against the
current design: each value tried is a hypothesis the selector counts in its Bonferroni correction.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.model import families
from nckemu.thermal.model.lags import asymmetric_lags, first_order_lags
from nckemu.thermal.model.terms import Term

from .problem import Problem, Run
from .settings import Settings


@dataclass
class Candidate:
    term: Term
    feature: np.ndarray
    # What the sensors' white noise contributes to the feature (one draw of it), gauge samples only.
    noise: np.ndarray
    in_sample_rms_um: float = math.nan
    # Values of a time constant tried to find this one: each was a hypothesis tested on the data.
    grid_points: int = 1
    # Several runs: which runs have the columns it needs (None: all); only those count as its folds.
    runs_with: np.ndarray | None = None

    @property
    def label(self) -> str:
        return label(self.term)


def label(term: Term) -> str:
    """``effect(sensor)``, ``effect(a - b)`` or ``effect``."""
    p = term.parameters
    detail = p.get("sensor") or (f"{p['sensors'][0]} - {p['sensors'][1]}" if "sensors" in p else "")
    return f"{term.effect}({detail})" if detail else term.effect


def present_key(term: Term) -> str:
    """What a found term rules out of later rounds: the effect, or the effect of that sensor (pair)."""
    return term.spec.present_key(term.parameters)


def bounded(term: Term) -> bool:
    """Parameters a machine can have."""
    return term.spec.bounded(term.parameters, term.coefficient)


def time_constants(term: Term) -> int:
    return sum(key in term.parameters for key in term.spec.time_constants)


def extends(complex_term: Term, simple_term: Term) -> bool:
    """``complex_term`` is ``simple_term`` of the same sensor plus a time constant."""
    return simple_term.effect in complex_term.spec.extends \
        and complex_term.parameters.get("sensor") == simple_term.parameters.get("sensor") is not None


CACHE_BYTES = 400_000_000


class Library:
    """The candidates of one round, given the current design and the effects already in it."""

    def __init__(self, problem: Problem, settings: Settings) -> None:
        self.problem = problem
        self.settings = settings
        self._columns: dict[tuple[object, ...], np.ndarray] = {}
        self._bytes = 0  # of the columns kept, counted as they come and go
        self._version = problem.version
        self._signals: dict[tuple[int, str], tuple[np.ndarray, np.ndarray]] = {}
        self.unavailable: dict[str, list[str]] = self._unavailable()
        self._design = np.empty((len(problem.y), 0))
        # The round's time-constant searches: (kind, sensor) -> (in-sample RMS, tau_s).
        self._searched: dict[tuple[str, str], tuple[float, float]] = {}
        self._added: tuple[Term, ...] = ()

    # ------------------------------------------------------------------ what every run has
    def _enough(self, have: int) -> bool:
        """A column is used when at least half the runs (and two) have it: a candidate is judged on
        the runs that have its columns."""
        runs = len(self.problem.runs)
        return have == runs or have >= max(2, math.ceil(runs / 2))

    def sensors(self) -> list[str]:
        """Sensors enough runs have (in order of first appearance)."""
        runs = self.problem.runs
        names: list[str] = []
        for run in runs:
            names += [k[len("temp_"):-len("_C")] for k in run.readings.recording.temperatures_C
                      if k[len("temp_"):-len("_C")] not in names]
        return [n for n in names
                if self._enough(sum(f"temp_{n}_C" in r.readings.recording.temperatures_C for r in runs))]

    def has_spindle(self) -> bool:
        return self._enough(sum(r.readings.recording.spindle_rpm is not None for r in self.problem.runs))

    def has_positions(self) -> bool:
        return self._enough(sum(self.problem.axis in r.readings.recording.positions_mm for r in self.problem.runs))

    def _unavailable(self) -> dict[str, list[str]]:
        """Columns some runs have and others lack: column -> the runs lacking it."""
        runs, axis = self.problem.runs, self.problem.axis
        if len(runs) < 2:
            return {}
        columns: dict[str, list[str]] = {}
        everything = set()
        for run in runs:
            recording = run.readings.recording
            everything |= set(recording.temperatures_C)
            if recording.spindle_rpm is not None:
                everything.add("spindle_rpm")
            if axis in recording.positions_mm:
                everything.add(f"pos_{axis}_mm")
        for column in sorted(everything):
            lacking = []
            for run in runs:
                recording = run.readings.recording
                has = (recording.spindle_rpm is not None if column == "spindle_rpm"
                       else axis in recording.positions_mm if column == f"pos_{axis}_mm"
                       else column in recording.temperatures_C)
                if not has:
                    lacking.append(run.name)
            if lacking:
                columns[column] = lacking
        return columns

    def handling(self, column: str) -> str:
        """How candidates that need ``column`` were handled, in words."""
        lacking = len(self.unavailable.get(column, []))
        if self._enough(len(self.problem.runs) - lacking):
            return ("candidates that need it were judged on the runs that have it: elsewhere they contribute "
                    "nothing, and only those runs count among the folds they must improve")
        return "candidates that need it were not tried (fewer than half the runs have it)"

    def duration_s(self) -> float:
        """The typical run's length: a time constant beyond a third of it is a trend, not a lag."""
        return float(np.median([r.readings.recording.duration_s for r in self.problem.runs]))

    def t_ref(self, sensor: str) -> float:
        for term in self.problem.base_terms:
            if term.parameters.get("sensor") == sensor and "t_ref_C" in term.parameters:
                return float(term.parameters["t_ref_C"])
        return 20.0

    # ------------------------------------------------------------------ features
    def _cached(self, key: tuple[object, ...], make: Callable[[], np.ndarray]) -> np.ndarray:
        """A column computed once per set of samples; the oldest go first beyond ``CACHE_BYTES`` (a
        single recording of millions of samples would otherwise hold gigabytes of grid columns)."""
        if self._version != self.problem.version:
            self._columns.clear()
            self._bytes = 0
            self._version = self.problem.version
        column = self._columns.get(key)
        if column is None:
            column = make()
            self._columns[key] = column
            self._bytes += column.nbytes
            while self._bytes > CACHE_BYTES and len(self._columns) > 1:
                oldest = next(iter(self._columns))
                self._bytes -= self._columns.pop(oldest).nbytes
        return column

    def _decimated(self, run: Run, sensor: str) -> tuple[np.ndarray, np.ndarray]:
        """The lags run on a coarser grid (>= 30 s: the readings are averaged over minutes already)."""
        key = (id(run), sensor)
        if key not in self._signals:
            t = run.readings.recording.t_s
            signal = run.readings.recording.sensor(sensor)
            step = max(1, int(30.0 / max(float(np.median(np.diff(t))), 1e-9)))
            self._signals[key] = (t[::step], signal[::step])
        return self._signals[key]

    def _sensor_series(self, sensor: str) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """The runs that have ``sensor`` (by id, in the runs' order): each one's coarse (t_s, signal)."""
        return {id(run): self._decimated(run, sensor) for run in self.problem.runs
                if f"temp_{sensor}_C" in run.readings.recording.temperatures_C}

    def _filtered_column(self, key: tuple[object, ...], sensor: str,
                         lagged: Callable[[list[tuple[np.ndarray, np.ndarray]]], list[np.ndarray]]) -> np.ndarray:
        """A filter of ``sensor`` (on its coarse grid) at the gauge samples, less t_ref; zero in a run
        without the sensor (no contribution there). ``lagged`` filters the runs' (t_s, signal) at once."""
        def make() -> np.ndarray:
            t_ref = self.t_ref(sensor)
            series = self._sensor_series(sensor)
            filtered = dict(zip(series, zip(series.values(), lagged(list(series.values())), strict=True), strict=True))

            def per_run(run: Run) -> np.ndarray:
                t_gauge = run.readings.recording.t_s[run.mask]
                if id(run) not in filtered:
                    return np.zeros(len(t_gauge))
                (t_coarse, _signal), values = filtered[id(run)]
                return np.interp(t_gauge, t_coarse, values) - t_ref
            return self.problem.gauge_column(per_run)
        return self._cached(key, make)

    def lag_column(self, sensor: str, tau_s: float) -> np.ndarray:
        return self._filtered_column(("lag", sensor, tau_s), sensor, lambda series: first_order_lags(series, tau_s))

    def transient_column(self, sensor: str, tau_s: float) -> np.ndarray:
        """The sensor less its own lag (on the coarse grid, like ``lag_column``, whose cache it shares)."""
        plain = self._filtered_column(("plain", sensor), sensor, lambda series: [signal for _t, signal in series])
        return plain - self.lag_column(sensor, tau_s)

    def best_time_constant(self, column: Callable[[float], np.ndarray], key: tuple[str, str],
                           away_from: tuple[float, ...] = ()) -> tuple[float, float, int] | None:
        """(in-sample RMS, tau_s, values tried) against the round's design: the grid of
        ``Settings.lag_grid_s`` up to a third of a run, then refined around the best grid point. The
        result is kept for the round under ``key`` (kind, sensor): ``best_searched`` ranks them.
        ``away_from``: the sensor's time constants already named; the search keeps
        ``second_time_constant_ratio`` away from each (a second time constant, not the same one)."""
        design, duration_s = self._design, self.duration_s()
        ratio = self.settings.second_time_constant_ratio

        def allowed(tau: float) -> bool:
            return tau <= duration_s / 3 and all(max(tau, other) >= ratio * min(tau, other) for other in away_from)

        best: tuple[float, float] | None = None
        tried = 0
        for tau in self.settings.lag_grid_s:
            if not allowed(tau):
                continue
            tried += 1
            score = self._in_sample(design, column(tau))
            if best is None or score < best[0]:
                best = (score, tau)
        if best is None:
            return None
        for tau in best[1] * np.geomspace(0.8, 1.25, 9):
            if not allowed(float(tau)):
                continue
            tried += 1
            score = self._in_sample(design, column(float(tau)))
            if score < best[0]:
                best = (score, float(tau))
        if not away_from:  # a second time constant does not rank the sensor's lag (the hysteresis's pick)
            self._searched[key] = (best[0], best[1])
        return best[0], best[1], tried

    def best_time_constant_pair(self, kind: str, sensor: str, design: np.ndarray, min_ratio: float
                                ) -> tuple[float, float, float, int] | None:
        """(in-sample RMS, fast tau_s, slow tau_s, pairs tried): one sensor's ``kind`` ("lag" or
        "transient") at two time constants at least ``min_ratio`` apart (a fast skin and a slow core),
        against ``design``: every pair of the grid of ``best_time_constant``, then refined around the
        best. The columns and the gauge are projected off the design once; a pair is a 2 x 2 solve."""
        column = self.lag_column if kind == "lag" else self.transient_column
        duration_s = self.duration_s()
        grid = [tau for tau in self.settings.lag_grid_s if tau <= duration_s / 3]
        if len(grid) < 2:
            return None
        y = self.problem.y

        def reductions(fast: list[float], slow: list[float]) -> list[tuple[float, float, float]]:
            columns = np.column_stack([column(sensor, tau) for tau in fast + slow] + [y])
            if design.shape[1]:
                columns = columns - design @ stats.least_squares(design, columns)
            features, target = columns[:, :-1], columns[:, -1]
            gram, moment = features.T @ features, features.T @ target
            found = []
            for i, tau_fast in enumerate(fast):
                for j, tau_slow in enumerate(slow, start=len(fast)):
                    if tau_slow < min_ratio * tau_fast:
                        continue
                    determinant = gram[i, i] * gram[j, j] - gram[i, j] ** 2
                    if not determinant > 1e-6 * gram[i, i] * gram[j, j]:
                        continue  # one effect fitted twice
                    drop = (gram[j, j] * moment[i] ** 2 - 2 * gram[i, j] * moment[i] * moment[j]
                            + gram[i, i] * moment[j] ** 2) / determinant
                    found.append((float(drop), tau_fast, tau_slow))
            return found

        tried = reductions(grid, grid)
        if not tried:
            return None
        count = len(tried)
        _drop, fast, slow = max(tried)
        near = reductions([fast * float(f) for f in np.geomspace(0.8, 1.25, 5)],
                          [slow * float(f) for f in np.geomspace(0.8, 1.25, 5) if slow * f <= duration_s / 3])
        count += len(near)
        best_drop, fast, slow = max(tried + near)
        residual = y - design @ stats.least_squares(design, y) if design.shape[1] else y
        rms = math.sqrt(max(float(residual @ residual) - best_drop, 0.0) / max(len(y), 1))
        return rms, fast, slow, count

    def best_with_partner(self, kind: str, sensor: str, design: np.ndarray, partners: dict[str, np.ndarray]
                          ) -> tuple[float, str, int] | None:
        """(tau_s, partner, pairs tried): one sensor's ``kind`` ("lag" or "transient") beside one of
        ``partners`` (measured columns, by name), the time constant searched again with the partner in
        (a time constant found alone absorbs what a correlated partner explains): every grid value
        with every partner, 2 x 2 solves off the design, then the best refined."""
        column = self.lag_column if kind == "lag" else self.transient_column
        duration_s = self.duration_s()
        grid = [tau for tau in self.settings.lag_grid_s if tau <= duration_s / 3]
        if not grid or not partners:
            return None
        y, names = self.problem.y, list(partners)

        def best(taus: list[float]) -> tuple[float, float, str]:
            columns = np.column_stack([column(sensor, tau) for tau in taus] + [partners[n] for n in names] + [y])
            if design.shape[1]:
                columns = columns - design @ stats.least_squares(design, columns)
            features, target = columns[:, :-1], columns[:, -1]
            gram, moment = features.T @ features, features.T @ target
            found = (-math.inf, taus[0], names[0])
            for i, tau in enumerate(taus):
                for j, name in enumerate(names, start=len(taus)):
                    determinant = gram[i, i] * gram[j, j] - gram[i, j] ** 2
                    if not determinant > 1e-6 * gram[i, i] * gram[j, j]:
                        continue
                    drop = (gram[j, j] * moment[i] ** 2 - 2 * gram[i, j] * moment[i] * moment[j]
                            + gram[i, i] * moment[j] ** 2) / determinant
                    if drop > found[0]:
                        found = (float(drop), tau, name)
            return found

        drop, tau, partner = best(grid)
        if not math.isfinite(drop):
            return None
        refined = [tau * float(f) for f in np.geomspace(0.8, 1.25, 9) if tau * f <= duration_s / 3]
        drop_near, tau_near, partner_near = best(refined)
        if drop_near > drop:
            tau, partner = tau_near, partner_near
        return tau, partner, (len(grid) + len(refined)) * len(names)

    def best_searched(self, kind: str, count: int) -> list[str]:
        """The ``count`` sensors whose time-constant search of ``kind`` fitted best this round."""
        found = sorted((score, sensor, tau) for (k, sensor), (score, tau) in self._searched.items() if k == kind)
        return [sensor for _score, sensor, _tau in found[:count]]

    def best_asymmetric_lag(self, sensor: str) -> tuple[float, float, float, int] | None:
        """(in-sample RMS, tau_heat_s, tau_cool_s, values tried): the pairs of
        ``Settings.hysteresis_grid_s`` up to a third of a run, then refined around the best grid point."""
        design, duration_s = self._design, self.duration_s()
        best_h: tuple[float, float, float] | None = None
        tried = 0
        grid = [(h, c) for h, c in itertools.product(self.settings.hysteresis_grid_s, repeat=2)
                if h != c and max(h, c) <= duration_s / 3]
        for (tau_heat, tau_cool), column in zip(grid, self.asymmetric_columns(sensor, grid), strict=True):
            tried += 1
            score = self._in_sample(design, column)
            if best_h is None or score < best_h[0]:
                best_h = (score, tau_heat, tau_cool)
        if best_h is None:
            return None
        # Refine around the grid point (not around the last improvement: that compounded, and walked a
        # cooling time constant to 21 h on a 36 h null record).
        grid_heat, grid_cool = best_h[1], best_h[2]
        near = [(grid_heat * float(fh), grid_cool * float(fc))
                for fh, fc in itertools.product(np.geomspace(0.7, 1.4, 5), repeat=2)]
        near = [(h, c) for h, c in near if max(h, c) <= duration_s / 3]
        for (tau_heat, tau_cool), column in zip(near, self.asymmetric_columns(sensor, near), strict=True):
            tried += 1
            score = self._in_sample(design, column)
            if score < best_h[0]:
                best_h = (score, tau_heat, tau_cool)
        return best_h[0], best_h[1], best_h[2], tried

    def asymmetric_column(self, sensor: str, tau_heat_s: float, tau_cool_s: float) -> np.ndarray:
        return self._filtered_column(("hysteresis", sensor, tau_heat_s, tau_cool_s), sensor,
                                     lambda series: [lags[:, 0] for lags in
                                                     asymmetric_lags(series, [(tau_heat_s, tau_cool_s)])])

    def asymmetric_columns(self, sensor: str, pairs: list[tuple[float, float]]) -> list[np.ndarray]:
        """``asymmetric_column`` for many time-constant pairs, the missing ones in one pass over time."""
        missing = [p for p in pairs if ("hysteresis", sensor, *p) not in self._columns
                   or self._version != self.problem.version]
        if len(missing) > 1:
            t_ref = self.t_ref(sensor)
            series = self._sensor_series(sensor)
            lags = dict(zip(series, asymmetric_lags(list(series.values()), missing), strict=True))
            per_run = []
            for run in self.problem.runs:
                t_gauge = run.readings.recording.t_s[run.mask]
                if id(run) not in lags:
                    per_run.append([np.zeros(len(t_gauge))] * len(missing))
                    continue
                t_coarse, _signal = series[id(run)]
                lagged = lags[id(run)]
                per_run.append([np.interp(t_gauge, t_coarse, lagged[:, k]) - t_ref for k in range(len(missing))])
            for k, pair in enumerate(missing):
                column = self.problem.within(np.concatenate([columns[k] for columns in per_run]))
                self._cached(("hysteresis", sensor, *pair), lambda column=column: column)
        return [self.asymmetric_column(sensor, *pair) for pair in pairs]

    def candidate(self, term: Term, grid_points: int = 1) -> Candidate | None:
        """The term with its feature and carried noise; None when its feature is constant."""
        key = ("term", repr(term))
        feature = self._cached(key, lambda: self.problem.feature(term))
        if np.ptp(feature) == 0 and term.effect != "offset":
            return None
        noise = self._cached(("noise",) + key, lambda: self.problem.feature(term, noisy=True) - feature)
        runs_with = self.problem.runs_with(term) if len(self.problem.runs) > 1 else None
        if runs_with is not None and runs_with.all():
            runs_with = None
        return Candidate(term, feature, noise, grid_points=grid_points, runs_with=runs_with)

    def _in_sample(self, design: np.ndarray, feature: np.ndarray) -> float:
        y = self.problem.y
        full = np.column_stack([design, feature])
        return stats.rms(y - full @ stats.least_squares(full, y))

    # ------------------------------------------------------------------ the round's candidates
    def needs_offset(self) -> bool:
        """A common offset is a candidate unless the baseline has one (or each run has its own)."""
        problem = self.problem
        return not problem.per_run_offset and not any(t.effect == "offset" for t in problem.base_terms)

    def named_time_constants(self, effect: str, sensor: str) -> tuple[float, ...] | None:
        """The time constants of ``effect`` on ``sensor`` named in earlier rounds; None when discovery
        allows no second one (``second_time_constant_ratio`` 0)."""
        if not self.settings.second_time_constant_ratio:
            return None
        return tuple(float(t.parameters["tau_s"]) for t in self._added
                     if t.effect == effect and t.parameters.get("sensor") == sensor and "tau_s" in t.parameters)

    def modelled(self, effect: str, sensor: str) -> bool:
        return any(t.effect == effect and t.parameters.get("sensor") == sensor for t in self.problem.base_terms)

    def candidates(self, design: np.ndarray, present: set[str], added: tuple[Term, ...] = ()) -> list[Candidate]:
        """Every family's candidates of the round (``families``: each family proposes its own);
        ``added``: the terms earlier rounds named (a sensor's second time constant is searched away
        from its first)."""
        self._design = design
        self._added = added
        self._searched = {}
        sensors = {name: index for index, name in enumerate(self.sensors())}
        ranked: list[tuple[tuple[int, int, int], Candidate]] = []
        # Generated in registry order (a family may build on an earlier one's search: the hysteresis
        # on the lags), listed by each family's stage, then sensor.
        for rank, entry in enumerate(families.families()):
            if entry.candidates is None or entry.feature is None:
                continue
            for effect, parameters, grid_points in entry.candidates(self, present):
                candidate = self.candidate(Term(effect, parameters), grid_points)
                if candidate is not None:
                    sensor = sensors.get(parameters.get("sensor"), 0) if entry.stage == 1 else 0
                    ranked.append(((entry.stage, sensor, rank), candidate))
        return [candidate for _key, candidate in sorted(ranked, key=lambda item: item[0])]
