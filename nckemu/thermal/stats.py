"""The few statistics discovery needs, on numpy: least squares, blocked cross-validation over time,
autocorrelation-corrected standard errors and a robust noise scale.

Residuals of thermal models are strongly autocorrelated, so nothing here treats samples as
independent: folds are contiguous blocks of time, and standard errors are inflated by the residual's
long-run variance under an AR(1)-plus-white-noise model.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np


def rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values)))) if len(values) else math.nan


def robust_sigma(values: np.ndarray) -> float:
    """1.4826 × median absolute deviation: a noise scale that outliers do not inflate."""
    if len(values) == 0:
        return math.nan
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def least_squares(design: np.ndarray, target: np.ndarray) -> np.ndarray:
    coefficients, *_ = np.linalg.lstsq(design, target, rcond=None)
    return coefficients


def blocked_folds(count: int, folds: int = 5) -> list[np.ndarray]:
    """Boolean test masks of ``folds`` contiguous blocks of the (time-ordered) samples."""
    folds = max(2, min(folds, count))
    edges = np.linspace(0, count, folds + 1).round().astype(int)
    masks = []
    for start, end in zip(edges[:-1], edges[1:], strict=True):
        mask = np.zeros(count, dtype=bool)
        mask[start:end] = True
        masks.append(mask)
    return masks


@dataclass(frozen=True)
class CrossValidation:
    rms_um: float
    fold_rms_um: tuple[float, ...]


def cross_validate(design: np.ndarray, target: np.ndarray, folds: list[np.ndarray]) -> CrossValidation:
    """Fit on all blocks but one, predict that one; RMS over all held-out predictions."""
    squared = np.empty_like(target)
    per_fold = []
    for test in folds:
        train = ~test
        if design.shape[1] == 0:
            prediction = np.zeros(int(test.sum()))
        else:
            prediction = design[test] @ least_squares(design[train], target[train])
        errors = target[test] - prediction
        squared[test] = errors ** 2
        per_fold.append(rms(errors))
    return CrossValidation(float(np.sqrt(np.mean(squared))), tuple(per_fold))


def held_out_rows(mask: np.ndarray) -> slice | np.ndarray:
    """A fold's held-out samples as a slice when they are one contiguous block (a run, a block of
    time): indexing by it is a view, not a copy, and gives the same numbers as the mask."""
    rows = np.flatnonzero(mask)
    if len(rows) and rows[-1] - rows[0] + 1 == len(rows):
        return slice(int(rows[0]), int(rows[-1]) + 1)
    return rows


def cross_validate_gram(design: np.ndarray, target: np.ndarray, folds: list[np.ndarray]) -> CrossValidation:
    """``cross_validate`` through each fold's normal equations: the training fit of a fold is the sum
    over all samples minus the fold's own share, so many folds (one per run) cost one pass over the
    samples instead of one least-squares fit each. For well-conditioned designs of a few columns."""
    squared = np.empty_like(target)
    per_fold = []
    if design.shape[1] == 0:
        return cross_validate(design, target, folds)
    # C order, as the masks' copies were: a fold's rows are then a C-ordered view, and BLAS gets the
    # layout (so the last digits) it got from the copies.
    design, target = np.ascontiguousarray(design), np.ascontiguousarray(target)
    held_out = [held_out_rows(test) for test in folds]
    parts = [design[rows] for rows in held_out]
    # Against a copy: numpy sends an array times its own transpose to BLAS's syrk, whose last digits
    # differ from the gemm of two arrays that the figures have always come from.
    grams = [part.T @ part.copy() for part in parts]
    moments = [part.T @ target[rows] for part, rows in zip(parts, held_out, strict=True)]
    gram, moment = sum(grams), sum(moments)
    for rows, part, fold_gram, fold_moment in zip(held_out, parts, grams, moments, strict=True):
        coefficients, *_ = np.linalg.lstsq(gram - fold_gram, moment - fold_moment, rcond=None)
        errors = target[rows] - part @ coefficients
        squared[rows] = errors ** 2
        per_fold.append(rms(errors))
    return CrossValidation(float(np.sqrt(np.mean(squared))), tuple(per_fold))


def paired_improvement_p(before: np.ndarray, after: np.ndarray) -> float:
    """One-sided p-value that ``after`` is below ``before``, pair by pair: the Wilcoxon signed-rank
    test on the differences (exact for the few dozen pairs of a machine's runs; pairs that do not
    change are dropped). 1.0 when nothing changed."""
    difference = np.asarray(before, dtype=float) - np.asarray(after, dtype=float)
    difference = difference[np.isfinite(difference) & (difference != 0)]
    if len(difference) == 0:
        return 1.0
    return _signed_rank_p(difference.tobytes())


@functools.lru_cache(maxsize=4096)
def _signed_rank_p(difference: bytes) -> float:
    """``paired_improvement_p`` of these differences, kept: a search asks about the same runs' figures
    several times (a candidate's guards, its move, its withdrawal; three of four calls on a month of
    runs: 97 distinct of 436), and scipy's test costs milliseconds, mostly checking its arguments."""
    from scipy.stats import wilcoxon

    values = np.frombuffer(difference).copy()
    method = "exact" if len(values) <= 50 else "approx"
    return float(wilcoxon(values, alternative="greater", method=method).pvalue)


def autocorrelation(residual: np.ndarray, lag: int) -> float:
    if len(residual) <= lag + 1:
        return 0.0
    centred = residual - residual.mean()
    denominator = float(np.dot(centred, centred))
    if denominator == 0.0:
        return 0.0
    return float(np.dot(centred[lag:], centred[:-lag]) / denominator)


def _ar1_plus_white(residual: np.ndarray) -> tuple[float, float]:
    """r(1) and the decay per sample φ of the residual's slow part: AR(1) plus white noise (a gauge's
    own noise on a slowly wandering error) has r(k) = r(1)·φ^(k−1), so φ = r(2)/r(1); for a pure
    AR(1), r(1)."""
    r1, r2 = autocorrelation(residual, 1), autocorrelation(residual, 2)
    phi = r2 / r1 if 0.0 < r2 < r1 else r1
    return r1, float(np.clip(phi, -0.99, 0.99))


def _variance_factor(r1: float, phi: float) -> float:
    return 1.0 + 2.0 * r1 / (1.0 - phi) if r1 > 0.0 else 1.0


def long_run_variance_factor(residual: np.ndarray) -> float:
    """Var(mean of n samples) · n / Var(sample) for AR(1) plus white noise: 1 + 2·r(1)/(1 − φ).
    A lag-1 AR(1) fit alone, (1 + r1)/(1 − r1), underestimates it badly when white noise dilutes r(1)."""
    return _variance_factor(*_ar1_plus_white(residual))


@dataclass(frozen=True)
class Fit:
    coefficients: np.ndarray
    standard_errors: np.ndarray
    residual: np.ndarray
    rms_um: float
    ar1: float

    def t_value(self, index: int) -> float:
        se = self.standard_errors[index]
        return float(self.coefficients[index] / se) if se > 0 else math.inf


def fit(design: np.ndarray, target: np.ndarray) -> Fit:
    """OLS with standard errors inflated for autocorrelated residuals (AR(1) plus white noise:
    n_eff = n / long_run_variance_factor)."""
    coefficients = least_squares(design, target)
    residual = target - design @ coefficients
    n, p = design.shape
    r1, phi = _ar1_plus_white(residual)
    inflation = math.sqrt(_variance_factor(r1, phi))
    dof = max(n - p, 1)
    sigma2 = float(np.dot(residual, residual)) / dof
    try:
        covariance = sigma2 * np.linalg.inv(design.T @ design)
        standard_errors = np.sqrt(np.clip(np.diag(covariance), 0, None)) * inflation
    except np.linalg.LinAlgError:
        standard_errors = np.full(p, math.inf)
    return Fit(coefficients, standard_errors, residual, rms(residual), phi)


def ljung_box(residual: np.ndarray, lags: int = 20) -> float:
    """The Ljung-Box Q statistic (reported as evidence of structure, not used as a gate)."""
    n = len(residual)
    if n <= lags + 1:
        return math.nan
    return n * (n + 2) * sum(autocorrelation(residual, k) ** 2 / (n - k) for k in range(1, lags + 1))
