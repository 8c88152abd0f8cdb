"""Where a heat fit may look and where it is judged: the fit's settings, and the held-out judge (one
recording: fitted on its first part, judged in blocks of the rest; several runs: each run held out once,
as discovery holds out, discovery/splitters.py and discovery/admission.runs_improve)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.discovery.admission import runs_improve
from nckemu.thermal.discovery.splitters import Blocks, LeaveOneRunOut

from .table import HeatRun


@dataclass(frozen=True)
class Settings:
    train_share: float = 0.6          # one recording: fitted on this first share, judged on the rest
    min_improvement: float = 0.10     # the held-out RMS must fall by this share (as discovery's bar)
    blocks: int = 4                   # one recording: its held-out part in this many blocks of time
    min_block_share: float = 0.75     # ... and this share of them must improve
    runs_alpha: float = 0.05          # several runs: the paired test's level (over the round's families)
    runs_test_min: int = 6            # fewer runs than this: most must improve instead
    max_terms: int = 6
    # Time constants tried, s (between a minute and two days; at most a third of what is fitted on).
    tau_grid_s: tuple[float, ...] = tuple(float(v) for v in np.geomspace(60.0, 48 * 3600.0, 26))
    power_grid: tuple[float, ...] = tuple(round(v, 2) for v in np.arange(0.2, 2.81, 0.2))
    tau_ratio: float = 3.0            # two time constants of one input at least this far apart
    withdraw_share: float = 0.01      # a term whose removal costs less held-out RMS than this is withdrawn
    min_effect_noise: float = 3.0     # a new term must move the sensor by this many times its white noise
    # Each admitted term's time constant and power polished off the grid (False: the grid alone, the
    # bench's anchor).
    polish: bool = True
    noise_factor: float = 1.3         # a held-out RMS within this factor of the white noise: nothing left
    reference: tuple[str, ...] = ()   # sensors that read the room (their terms are "ambient")


@dataclass
class Judgement:
    rms: float                 # held-out RMS (one recording) or the median over runs of each run's
    unit_ms: np.ndarray        # held-out mean square per block of time or per run
    residual: np.ndarray       # held-out residual on the held-out rows (one recording) or every row


class Judge:
    """Fits coefficients where the fit may look and measures them where it may not."""

    def __init__(self, runs: list[HeatRun], settings: Settings) -> None:
        self.settings = settings
        lengths = [len(run.t_s) for run in runs]
        self.groups = np.repeat(np.arange(len(runs)), lengths)
        self.count = int(sum(lengths))
        self.per_run = len(runs) > 1
        if self.per_run:
            self.folds = [test for _train, test in LeaveOneRunOut().split(self.count, self.groups)]
            self.train = np.ones(self.count, dtype=bool)
        else:
            cut = int(round(self.count * settings.train_share))
            self.train = np.arange(self.count) < cut
            test = np.flatnonzero(~self.train)
            self.folds = [test[block] for _train, block in Blocks(settings.blocks).split(len(test))]
        self.starts = np.concatenate(([0], np.cumsum(lengths)))[:-1]
        self.lengths = np.asarray(lengths, dtype=float)

    def within(self, values: np.ndarray) -> np.ndarray:
        """Each run's own mean taken off (its own offset), column by column."""
        sums = np.add.reduceat(values, self.starts, axis=0)
        means = sums / (self.lengths[:, None] if values.ndim == 2 else self.lengths)
        return values - np.repeat(means, self.lengths.astype(np.int64), axis=0)

    def fitting_rows(self, y: np.ndarray, design: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """y and the design as the in-sample fit sees them: the training rows with a constant, or every
        row with each run's offset taken off."""
        if self.per_run:
            return self.within(y), self.within(design)
        rows = self.train
        return y[rows], np.column_stack((np.ones(int(rows.sum())), design[rows]))

    def judge(self, y: np.ndarray, design: np.ndarray) -> Judgement:
        if self.per_run:
            yw, xw = self.within(y), self.within(design)
            residual = np.empty(self.count)
            gram, cross = products(xw, xw), products(xw, yw)
            for test in self.folds:
                xt, yt = xw[test], yw[test]
                coef = np.linalg.lstsq(gram - products(xt, xt), cross - products(xt, yt), rcond=None)[0] \
                    if xw.shape[1] else np.zeros(0)
                residual[test] = yt - np.einsum("ij,j->i", xt, coef)
            unit_ms = np.array([float(np.mean(residual[test] ** 2)) for test in self.folds])
            return Judgement(float(np.median(np.sqrt(unit_ms))), unit_ms, residual)
        x = np.column_stack((np.ones(self.count), design))
        coef = stats.least_squares(x[self.train], y[self.train])
        residual = y - x @ coef
        held = residual[~self.train]
        unit_ms = np.array([float(np.mean(residual[test] ** 2)) for test in self.folds])
        return Judgement(stats.rms(held), unit_ms, residual)

    def passes(self, before: Judgement, after: Judgement, tests: int) -> tuple[bool, str]:
        s = self.settings
        drop = 1.0 - after.rms / before.rms if before.rms > 0 else 0.0
        if self.per_run:
            level = s.runs_alpha / max(tests, 1)
            units = runs_improve(before.unit_ms, after.unit_ms, level, s.min_block_share, s.runs_test_min)
            improved = int(np.sum(after.unit_ms < before.unit_ms))
            unit_words = f"{improved} of {len(after.unit_ms)} runs improve"
        else:
            improved = int(np.sum(after.unit_ms < before.unit_ms))
            units = improved >= math.ceil(s.min_block_share * len(after.unit_ms))
            unit_words = f"{improved} of {len(after.unit_ms)} held-out blocks improve"
        ok = units and drop >= s.min_improvement
        why = (f"held-out {before.rms:.3f} -> {after.rms:.3f} K ({drop:.0%}; the bar is {s.min_improvement:.0%}), "
               f"{unit_words}")
        return ok, why


def products(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a.T @ b for the tall, narrow designs of a heat fit, without BLAS: its threads cost more than they
    save on a few columns when the cores are shared (measured: 7x the fit's time on this machine)."""
    return np.einsum("ij,i...->j...", a, b)
