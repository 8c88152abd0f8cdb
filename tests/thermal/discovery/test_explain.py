"""The explainer's parts: windows, the residual's autocorrelation, why nothing passed."""

from __future__ import annotations

import numpy as np

from nckemu.thermal.discovery import explain


def test_locate_finds_and_merges_windows_heaviest_first() -> None:
    t = np.arange(100.0)
    values = np.zeros(100)
    values[10:20] = 0.8
    values[60:90] = -2.0
    windows = explain.locate(t, values)
    assert [(w[0], w[1]) for w in windows] == [(60.0, 89.0)]  # half the peak: only the larger one
    assert explain.locate(t, np.zeros(100)) == [] and explain.locate(t[:0], values[:0]) == []


def test_structured_windows_ignore_white_noise_and_find_a_step() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(400.0) * 60
    noise = rng.normal(0, 0.3, 400)
    assert explain.structured_windows(t, noise) == []
    stepped = noise.copy()
    stepped[200:260] += 3.0
    (start, end), *_ = explain.structured_windows(t, stepped)
    assert 190 * 60 <= start <= 205 * 60 and 255 * 60 <= end <= 270 * 60


def test_autocorrelation_words_tell_white_from_structured() -> None:
    rng = np.random.default_rng(1)
    white = rng.normal(size=2000)
    assert explain.autocorrelation_words(white)[0] is False
    wander = np.cumsum(rng.normal(size=2000)) * 0.1 + white
    beyond, words = explain.autocorrelation_words(wander)
    assert beyond and "beyond white noise" in words
    assert explain.autocorrelation_words(white[:10])[1].startswith("too few")


def test_nothing_passed_is_one_line_with_the_sizes() -> None:
    line = explain.nothing_passed(5, "blocks of time", {"temperature": 0.42, "thermal_lag": 1.3}, "r")
    assert "\n" not in line and "5 independent blocks of time" in line
    assert "temperature 0.42" in line and "thermal_lag 1.3" in line
