"""The families a sensor's heat response is built from, and the search for each family's parameters.

- spindle: the spindle's speed as (rpm/1000)^p through a lag tau (p on a grid from 0.6 to 2.8,
  refined to 0.05: bearing friction grows faster than the speed);
- spindle, a second time constant: the same input through a second lag at least ``tau_ratio`` away
  (a fast skin and a slow core);
- axes: the path speed (m/min) through a lag;
- a switched input (coolant 0/1) through a lag;
- a sensor through a lag (0 allowed): the room through a reference sensor ("ambient"), or heat passed
  on from a neighbour ("neighbour").

Parameters are picked in-sample on what the fit may see (a grid, then a finer look around the best),
against the terms already named: a lagged column of each grid point, scored by how much it lowers the
residual beyond the design's span. Admission is the held-out judge's (fit.py), never this score.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol

import numpy as np
from scipy.signal import lfilter

from nckemu.heat_response import PATH, SENSOR, SPINDLE, HeatTerm, spindle_drive
from nckemu.thermal.model.lags import first_order_lag

from .table import HeatRun, hours, switch_inputs

if TYPE_CHECKING:
    from .judge import Judge, Settings


class Search(Protocol):
    """What the families ask of one sensor's search (fit.SensorSearch is it; named here so that the
    families do not import the search that imports them)."""

    sensor: str
    runs: list[HeatRun]
    columns: Columns
    judge: Judge
    settings: Settings
    neighbours: bool
    y: np.ndarray

    def design(self, specs: list[Spec], *, cache: bool = True) -> np.ndarray: ...

    def in_sample_sse(self, specs: list[Spec], *, cache: bool = True) -> float: ...

AMBIENT_WORDS = ("ambient", "room", "hall", "air", "reference", "environment", "outside")
REFINE_TAU = tuple(float(v) for v in np.geomspace(0.8, 1.25, 9))
REFINE_POWER = (-0.15, -0.1, -0.05, 0.0, 0.05, 0.1, 0.15)
# The speed law has at most two parts (e.g. running at all, and a power of the speed), this far apart.
MAX_SPINDLE_LAWS = 2
# The shortest lag a polish may reach (the grid's first point): shorter is "no lag" on these grids.
MIN_TAU_S = 60.0
MIN_POWER_GAP = 0.5


def law(power: float) -> str:
    return "running" if power == 0 else f"speed^{power:.2f}"


@dataclass(frozen=True)
class Spec:
    """One term's shape before its gain: which input, its power (spindle) and its time constant."""

    kind: str           # spindle, path, switch, sensor
    source: str = ""    # switch: the input's name; sensor: the sensor's
    power: float = 1.0
    tau_s: float = 0.0

    def describe(self) -> str:
        at = f" at {hours(self.tau_s)}" if self.tau_s > 0 else " (no lag)"
        if self.kind == "spindle":
            return f"spindle {'running' if self.power == 0 else f'(rpm/1000)^{self.power:.2f}'}{at}"
        if self.kind == "path":
            return f"axes (path speed){at}"
        return f"{self.source}{at}"

    def term(self, k: float, columns: Columns) -> HeatTerm:
        if self.kind == "spindle":
            return HeatTerm(SPINDLE, k, self.tau_s, self.power)
        if self.kind == "path":
            return HeatTerm(PATH, k, self.tau_s)
        if self.kind == "sensor":
            return HeatTerm(SENSOR, k, self.tau_s, sensor=self.source, from_C=columns.from_C(self.source))
        return HeatTerm(self.source, k, self.tau_s)


class Columns:
    """Every lagged drive the search asks for, over all runs laid end to end, computed once (the
    spindle's columns serve every sensor)."""

    def __init__(self, runs: list[HeatRun], settings: Settings, judge: Judge) -> None:
        self.runs, self.settings, self.judge = runs, settings, judge
        self._cache: dict[Spec, np.ndarray] = {}
        # The room's sensors (recorded, inputs of the twin) and the other sensors' fitted rises on offer
        # as neighbours (per run); a neighbour's drive is its response, as the twin simulates it.
        self.reference: tuple[str, ...] = ()
        self.simulated: dict[str, list[np.ndarray]] = {}
        self._fitting: dict[tuple[Spec, ...], np.ndarray] = {}
        # One grid step shared by every run (the fit's grid): each lag runs over all runs at once.
        steps = [np.diff(run.t_s) for run in runs]
        first = float(steps[0][0]) if len(steps[0]) else 0.0
        uniform = first > 0 and all(len(d) and float(np.ptp(d)) <= 1e-9 * first and abs(float(d[0]) - first) <= 1e-9 * first
                                    for d in steps)
        self._step_s: float | None = first if uniform else None
        spans = [run.duration_s for run in runs]
        span_s = float(np.median(spans)) * (settings.train_share if len(runs) == 1 else 1.0)
        self.longest_tau_s = span_s / 3.0

    def from_C(self, sensor: str) -> float:
        return float(self.runs[0].sensors_C[sensor][0])

    def drive(self, run: HeatRun, spec: Spec) -> np.ndarray:
        if spec.kind == "spindle":
            return spindle_drive(run.inputs[SPINDLE], spec.power)
        if spec.kind == "path":
            return run.inputs[PATH]
        if spec.kind == "sensor":
            if spec.source in self.simulated:
                return self.simulated[spec.source][self.runs.index(run)]
            values = run.sensors_C[spec.source]
            return values - values[0]
        return run.inputs[spec.source]

    def offer(self, rises: dict[str, np.ndarray]) -> None:
        """Other sensors' fitted rises (every row) as the drives of neighbour terms; each is offered once."""
        bounds = np.cumsum([len(run.t_s) for run in self.runs])[:-1]
        for name, rise in rises.items():
            self.simulated.setdefault(name, np.split(rise, bounds))

    def column(self, spec: Spec, *, cache: bool = True) -> np.ndarray:
        found = self._cache.get(spec)
        if found is None:
            drives = [self.drive(run, spec) for run in self.runs]
            if spec.tau_s <= 0:
                found = np.concatenate(drives)
            elif self._step_s is not None:
                found = self._lag_rows(drives, spec.tau_s)
            else:
                found = np.concatenate([first_order_lag(run.t_s, drive, spec.tau_s)
                                        for run, drive in zip(self.runs, drives, strict=True)])
            if cache:
                self._cache[spec] = found
        return found

    def _lag_rows(self, drives: list[np.ndarray], tau_s: float) -> np.ndarray:
        """``first_order_lag`` of every run at once: the runs as rows of one filter (one grid step)."""
        lengths = [len(drive) for drive in drives]
        rows = np.empty((len(drives), max(lengths)))
        for row, drive in zip(rows, drives, strict=True):
            row[:len(drive)] = drive - drive[0]
            row[len(drive):] = row[len(drive) - 1]
        alpha = 1.0 - math.exp(-self._step_s / tau_s)
        lagged = lfilter([alpha], [1.0, alpha - 1.0], rows, axis=1)
        return np.concatenate([lagged[k, :n] + drive[0] for k, (n, drive) in enumerate(zip(lengths, drives, strict=True))])

    def fitting_one(self, spec: Spec, *, cache: bool = True) -> np.ndarray:
        """One column as the in-sample fit sees it."""
        found = self._fitting.get((spec,))
        if found is None:
            column = self.column(spec, cache=cache)
            found = self.judge.within(column) if self.judge.per_run else column[self.judge.train]
            if cache:
                self._fitting[(spec,)] = found
        return found

    def fitting(self, specs: tuple[Spec, ...]) -> np.ndarray:
        """The columns of ``specs`` as the in-sample fit sees them (judge.fitting_rows' rows)."""
        found = self._fitting.get(specs)
        if found is None:
            matrix = np.column_stack([self.column(spec) for spec in specs])
            found = self.judge.within(matrix) if self.judge.per_run else matrix[self.judge.train]
            self._fitting[specs] = found
        return found

    def taus(self, *, lagless: bool = False) -> list[float]:
        grid = [tau for tau in self.settings.tau_grid_s if tau <= self.longest_tau_s]
        return ([0.0] if lagless else []) + grid


class Scorer:
    """How much a column lowers the in-sample residual beyond the current design's span."""

    def __init__(self, search: Search, specs: list[Spec]) -> None:
        y, x = search.judge.fitting_rows(search.y, search.design(specs))
        self.q = np.linalg.qr(x)[0] if x.shape[1] else np.zeros((len(y), 0))
        self.residual = y - self.q @ (self.q.T @ y)

    def best(self, specs: tuple[Spec, ...], columns: Columns) -> tuple[float, Spec | None]:
        if not specs:
            return 0.0, None
        c = columns.fitting(specs)
        c = c - self.q @ (self.q.T @ c)
        energy = np.sum(c * c, axis=0)
        gain = np.where(energy > 1e-12 * max(float(energy.max()), 1e-300), (self.residual @ c) ** 2 / np.maximum(energy, 1e-300), 0.0)
        index = int(np.argmax(gain))
        return float(gain[index]), specs[index]


def _refine(search: Search, specs: list[Spec], index: int, options: list[Spec]) -> list[Spec]:
    """``specs`` with the term at ``index`` replaced by the option of least in-sample residual."""
    best, best_sse = specs, search.in_sample_sse(specs)
    for option in options:
        trial = specs[:index] + [option] + specs[index + 1:]
        sse = search.in_sample_sse(trial)
        if sse < best_sse:
            best, best_sse = trial, sse
    return best


def _tau_options(spec: Spec, longest_s: float, away_from: float = 0.0, ratio: float = 1.0) -> list[Spec]:
    options = []
    for factor in REFINE_TAU:
        tau = spec.tau_s * factor
        if tau <= longest_s and (away_from <= 0 or max(tau, away_from) >= ratio * min(tau, away_from)):
            options.append(replace(spec, tau_s=tau))
    return options


def _power_options(power: float) -> list[float]:
    if power == 0:
        return [0.0]   # running or not: no power near it is another law
    return [round(power + step, 3) for step in REFINE_POWER if 0.05 <= power + step <= 3.5]


def _with_power(specs: list[Spec], index: int, power: float) -> list[Spec]:
    """``specs`` with the spindle terms of the power of ``specs[index]`` at ``power``."""
    old = specs[index].power
    return [replace(s, power=power) if s.kind == "spindle" and s.power == old else s for s in specs]


def _spindle(search: Search, specs: list[Spec], columns: Columns) -> list[Spec] | None:
    """The speed law's best (next) part: a power of the speed, or running at all (power 0)."""
    scorer = Scorer(search, specs)
    taken = [s.power for s in specs if s.kind == "spindle"]
    best_gain, best_spec = 0.0, None
    for power in (0.0, *columns.settings.power_grid):
        if any(abs(power - other) < MIN_POWER_GAP for other in taken):
            continue
        gain, spec = scorer.best(tuple(Spec("spindle", "", power, tau) for tau in columns.taus()), columns)
        if spec is not None and gain > best_gain:
            best_gain, best_spec = gain, spec
    if best_spec is None:
        return None
    out = specs + [best_spec]
    index = len(out) - 1
    for _round in range(2):
        options = [p for p in _power_options(out[index].power) if all(abs(p - o) >= MIN_POWER_GAP for o in taken)]
        if options:
            best_power = min(options, key=lambda p: search.in_sample_sse(_with_power(out, index, p)))
            out = _with_power(out, index, best_power)
        out = _refine(search, out, index, _tau_options(out[index], columns.longest_tau_s))
    return out


def _second_time_constant(search: Search, specs: list[Spec], index: int,
                          columns: Columns) -> list[Spec] | None:
    """The spindle term at ``index`` as two lags of its input (same power) at least ``tau_ratio`` apart:
    every pair of the grid at once against the other terms, then the polish (fit.py) refines them."""
    first = specs[index]
    ratio = columns.settings.tau_ratio
    rest = specs[:index] + specs[index + 1:]
    scorer = Scorer(search, rest)
    grid = tuple(Spec("spindle", "", first.power, tau) for tau in columns.taus())
    c = columns.fitting(grid)
    c = c - scorer.q @ (scorer.q.T @ c)
    gram, v = c.T @ c, c.T @ scorer.residual
    best, pair = 0.0, None
    for i, fast in enumerate(grid):
        for j in range(i + 1, len(grid)):
            if grid[j].tau_s < ratio * fast.tau_s:
                continue
            g = gram[np.ix_((i, j), (i, j))]
            if abs(np.linalg.det(g)) <= 1e-12 * float(np.trace(g)) ** 2:
                continue
            w = v[[i, j]]
            gain = float(w @ np.linalg.solve(g, w))
            if gain > best:
                best, pair = gain, (fast, grid[j])
    if pair is None:
        return None
    return rest[:index] + [pair[0]] + rest[index:] + [pair[1]]


def _lagged(search: Search, specs: list[Spec], columns: Columns, shapes: list[Spec],
            lagless: bool = False) -> list[Spec] | None:
    """The best of ``shapes`` (one input each) at its best time constant."""
    scorer = Scorer(search, specs)
    grid = tuple(replace(shape, tau_s=tau) for shape in shapes for tau in columns.taus(lagless=lagless))
    _gain, best = scorer.best(grid, columns)
    if best is None:
        return None
    out = specs + [best]
    if best.tau_s > 0:
        out = _refine(search, out, len(out) - 1, _tau_options(best, columns.longest_tau_s))
    return out


def polish(search: Search, specs: list[Spec]) -> list[Spec]:
    """Every term's time constant (and a spindle law's power) once more, given all the others, by a
    continuous in-sample search from where the grid left it (the grid's steps are a few per cent)."""
    from scipy.optimize import minimize

    out = list(specs)
    longest = search.columns.longest_tau_s
    ratio = search.settings.tau_ratio
    for index, spec in enumerate(specs):
        if spec.tau_s <= 0:
            continue
        twins = [s.tau_s for i, s in enumerate(out) if i != index and s.kind == spec.kind
                 and s.source == spec.source and s.power == spec.power]
        free_power = spec.kind == "spindle" and spec.power > 0 and not twins

        def shaped(x: np.ndarray, spec: Spec = spec, free_power: bool = free_power) -> Spec:
            power = round(float(np.clip(x[1], 0.05, 3.5)), 4) if free_power else spec.power
            return replace(spec, tau_s=float(np.exp(x[0])), power=power)

        laws = [s.power for i, s in enumerate(out) if i != index and s.kind == "spindle" and s.power != spec.power]

        def cost(x: np.ndarray, index: int = index, twins: list[float] = twins, shaped=shaped,
                 laws: list[float] = laws) -> float:
            trial = shaped(x)
            if not MIN_TAU_S <= trial.tau_s <= longest or any(max(trial.tau_s, t) < ratio * min(trial.tau_s, t) for t in twins):
                return math.inf
            if trial.kind == "spindle" and any(abs(trial.power - law) < MIN_POWER_GAP for law in laws):
                return math.inf
            return search.in_sample_sse(out[:index] + [trial] + out[index + 1:], cache=False)

        start = np.array([math.log(spec.tau_s), spec.power] if free_power else [math.log(spec.tau_s)])
        with np.errstate(invalid="ignore"):   # a simplex with an infinite corner (a constraint) subtracts inf
            found = minimize(cost, start, method="Nelder-Mead",
                             options={"maxfev": 40, "xatol": 0.004, "fatol": 1e-9})
        if math.isfinite(found.fun) and found.fun < cost(start):
            out[index] = shaped(found.x)
    for power in sorted({s.power for s in out if s.kind == "spindle" and s.power > 0}):
        group = [i for i, s in enumerate(out) if s.kind == "spindle" and s.power == power]
        if len(group) < 2:
            continue
        from scipy.optimize import minimize_scalar

        def shared(p: float, first: int = group[0], now: list[Spec] = out) -> float:
            return search.in_sample_sse(_with_power(now, first, round(float(p), 4)), cache=False)

        others = [s.power for s in out if s.kind == "spindle" and s.power != power]
        low = max([0.05, power - 0.3] + [o + MIN_POWER_GAP for o in others if o < power])
        high = min([power + 0.3] + [o - MIN_POWER_GAP for o in others if o > power])
        if high <= low:
            continue
        found = minimize_scalar(shared, bounds=(low, high), method="bounded", options={"maxiter": 25, "xatol": 0.002})
        if found.fun < shared(power):
            out = _with_power(out, group[0], round(float(found.x), 4))
    return out


def family_candidates(search: Search, specs: list[Spec], only: str = "") -> list[tuple[str, list[Spec]]]:
    """Each family's best next design (label, specs) for this round (``only="spindle"``: a single lag of
    the spindle alone)."""
    if only == "spindle":
        found = _spindle(search, specs, search.columns) if all(SPINDLE in run.inputs for run in search.runs) else None
        return [("spindle", found)] if found else []
    return list(_candidates(search, specs))


def _candidates(search: Search, specs: list[Spec]) -> Iterator[tuple[str, list[Spec]]]:
    columns: Columns = search.columns
    runs = search.runs
    kinds = [s.kind for s in specs]
    if all(SPINDLE in run.inputs for run in runs):
        powers = [s.power for s in specs if s.kind == "spindle"]
        if len(set(powers)) < MAX_SPINDLE_LAWS:
            found = _spindle(search, specs, columns)
            if found:
                yield "spindle", found
                if not powers:   # skin and core at once: one lag first would take the wrong place
                    pair = _second_time_constant(search, found, len(found) - 1, columns)
                    if pair:
                        yield "spindle, two time constants", pair
        for power in sorted(set(powers)):
            if powers.count(power) == 1:
                index = next(i for i, s in enumerate(specs) if s.kind == "spindle" and s.power == power)
                found = _second_time_constant(search, specs, index, columns)
                if found:
                    yield f"spindle, a second time constant ({law(power)})", found
    if all(PATH in run.inputs for run in runs) and "path" not in kinds:
        found = _lagged(search, specs, columns, [Spec("path")])
        if found:
            yield "axes", found
    for name in switch_inputs(runs):
        if all(name in run.inputs for run in runs) and not any(s.kind == "switch" and s.source == name for s in specs):
            found = _lagged(search, specs, columns, [Spec("switch", name)])
            if found:
                yield name, found
    used = {s.source for s in specs if s.kind == "sensor"}
    reference = [name for name in columns.reference if name != search.sensor and name not in used]
    if reference:
        found = _lagged(search, specs, columns, [Spec("sensor", name) for name in reference], lagless=True)
        if found:
            yield f"ambient ({found[-1].source})", found
    neighbours = [name for name in columns.simulated if name != search.sensor and name not in used]
    if search.neighbours and neighbours:
        found = _lagged(search, specs, columns, [Spec("sensor", name) for name in neighbours])
        if found:
            yield f"neighbour ({found[-1].source})", found


def is_reference(sensor: str, declared: tuple[str, ...]) -> bool:
    if declared:
        return sensor in declared
    return any(word in sensor.lower() for word in AMBIENT_WORDS)


def label_terms(terms: list[HeatTerm], reference: tuple[str, ...]) -> list[HeatTerm]:
    """Each term's name: spindle (skin and core when it has two time constants), axes, the switch's
    input, ambient (a reference sensor) or neighbour."""
    out = []
    for term in terms:
        if term.input == SPINDLE:
            same = sorted(t.tau_s for t in terms if t.input == SPINDLE and t.power == term.power)
            name = "spindle running" if term.power == 0 else "spindle"
            if len(same) > 1:
                name += " skin" if term.tau_s == same[0] else " core"
        elif term.input == PATH:
            name = "axes"
        elif term.input == SENSOR:
            name = "ambient" if term.sensor in reference else "neighbour"
        else:
            name = term.input
        out.append(replace(term, name=name))
    return out
