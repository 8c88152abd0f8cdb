"""The noise model behind discovery's t-tests: the long-run variance of AR(1) plus white noise."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.thermal import stats


def ar1_plus_white(phi: float, ar_sigma: float, white_sigma: float, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    innovations = rng.normal(0.0, ar_sigma * np.sqrt(1 - phi ** 2), n)
    ar = np.empty(n)
    ar[0] = rng.normal(0.0, ar_sigma)
    for k in range(1, n):
        ar[k] = phi * ar[k - 1] + innovations[k]
    return ar + rng.normal(0.0, white_sigma, n)


def true_factor(phi: float, ar_sigma: float, white_sigma: float) -> float:
    """n·Var(mean)/Var(sample) for n large: (AR long-run variance + white variance) / total variance."""
    ar_long_run = ar_sigma ** 2 * (1 + phi) / (1 - phi)
    return (ar_long_run + white_sigma ** 2) / (ar_sigma ** 2 + white_sigma ** 2)


@settings(max_examples=30, deadline=None)
@given(phi=st.floats(0.5, 0.95), white_share=st.floats(0.0, 1.0), seed=st.integers(0, 2**32 - 1))
def test_long_run_variance_of_ar1_plus_white_noise(phi: float, white_share: float, seed: int) -> None:
    series = ar1_plus_white(phi, 1.0, white_share, 100_000, seed)
    estimated, expected = stats.long_run_variance_factor(series), true_factor(phi, 1.0, white_share)
    assert estimated == pytest.approx(expected, rel=0.25)


def test_white_noise_alone_needs_no_inflation() -> None:
    assert stats.long_run_variance_factor(np.random.default_rng(1).normal(size=50_000)) == pytest.approx(1.0, abs=0.05)


def test_the_lag_one_fit_alone_would_understate_it() -> None:
    """The case that let the nulls through: φ = 0.94 with a third of the variance white."""
    series = ar1_plus_white(0.94, 0.5, 0.2 * np.sqrt(2), 200_000, 3)
    r1 = stats.autocorrelation(series, 1)
    lag_one_only = (1 + r1) / (1 - r1)
    assert stats.long_run_variance_factor(series) > 2.5 * lag_one_only
