"""Readings: glitches bridged, each sensor's white noise measured, averaging, resampling of runs."""

from __future__ import annotations

import numpy as np
import pytest

from nckemu.thermal.discovery.readings import prepare, resample, smooth_sensor, white_noise_C
from nckemu.thermal.discovery.settings import Settings
from nckemu.thermal.recordings.recording import Recording


def _recording(step_s: float = 60.0, hours: float = 12.0, seed: int = 1) -> Recording:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, hours * 3600, step_s)
    slow = 20 + 3 * np.sin(2 * np.pi * t / 86400)
    error = 2 * (slow - 20) + rng.normal(0, 0.3, len(t))
    return Recording("<r>", t, {"temp_a_C": slow + rng.normal(0, 0.05, len(t))}, None, {}, {"Z": error})


def test_white_noise_is_measured_on_a_slowly_curving_reading() -> None:
    recording = _recording()
    assert white_noise_C(recording.temperatures_C["temp_a_C"]) == pytest.approx(0.05, rel=0.15)
    assert white_noise_C(np.ones(5)) == 0.0


def test_prepare_bridges_a_glitch_and_reports_it() -> None:
    recording = _recording()
    recording.temperatures_C["temp_a_C"][300:302] += 4.0
    readings = prepare(recording, Settings())
    assert any(note.startswith("temp_a_C: 1 glitch burst") for note in readings.data_quality)
    assert np.max(np.abs(np.diff(readings.recording.temperatures_C["temp_a_C"]))) < 0.2
    assert readings.raw is recording
    # the noise draw differs from the averaged readings by about the averaged noise, no more
    difference = readings.noisy.temperatures_C["temp_a_C"] - readings.recording.temperatures_C["temp_a_C"]
    assert 0 < np.std(difference) < 0.05


def test_smoothing_keeps_short_records_and_zero_windows() -> None:
    t, values = np.arange(3.0), np.array([1.0, 5.0, 1.0])
    assert np.array_equal(smooth_sensor(t, values, 0.0), values)
    assert np.array_equal(smooth_sensor(t, values, 1.0), values)


def test_resample_averages_the_gauge_per_step_and_keeps_slow_records() -> None:
    fast = _recording(step_s=1.0, hours=1.0)
    fast.errors_um["Z"][::7] = np.nan  # gaps: the step's mean is over the readings it has
    coarse = resample(fast, 30.0)
    assert len(coarse.t_s) == 120 and np.all(np.diff(coarse.t_s) == 30.0)
    first = fast.errors_um["Z"][:30]
    assert coarse.errors_um["Z"][0] == pytest.approx(np.nanmean(first))
    slow = _recording(step_s=60.0)
    assert resample(slow, 30.0) is slow
