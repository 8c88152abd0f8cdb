"""The readings as discovery uses them: sensor glitches bridged, each sensor's white noise measured,
temperatures averaged, and one more draw of that noise (to measure what a feature passes on).

A structure does not follow a sensor's white noise, and a difference of two sensors (a gradient)
carries the noise of both against a small signal (errors in variables): features are built on the
averaged readings, and the noise draw tells how much noise each feature still carries.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.ndimage import uniform_filter1d

from nckemu.thermal import stats
from nckemu.thermal.recordings import quality
from nckemu.thermal.recordings.recording import Recording

from .settings import Settings


@dataclass
class Readings:
    raw: Recording            # as recorded (the calibration check judges the model on it)
    recording: Recording      # glitches bridged, temperatures averaged
    noisy: Recording          # the same plus one averaged draw of each sensor's white noise
    sensor_noise_C: dict[str, float] = field(default_factory=dict)
    data_quality: list[str] = field(default_factory=list)


def white_noise_C(values: np.ndarray) -> float:
    """A sensor's white noise: second differences cancel a slowly curving temperature and leave
    6 sigma^2 of white noise; the robust scale ignores the few samples where heating starts."""
    if len(values) < 8:
        return 0.0
    sigma = stats.robust_sigma(np.diff(values, 2)) / math.sqrt(6.0)
    return sigma if math.isfinite(sigma) else 0.0


def smooth_sensor(t_s: np.ndarray, values: np.ndarray, window_s: float) -> np.ndarray:
    """The centred moving average over ``window_s`` (odd number of samples)."""
    if len(t_s) < 3 or window_s <= 0:
        return values
    width = int(round(window_s / max(float(np.median(np.diff(t_s))), 1e-9)))
    if width < 3:
        return values
    return uniform_filter1d(values, size=width | 1, mode="nearest")


def _with(recording: Recording, temperatures: dict[str, np.ndarray]) -> Recording:
    return replace(recording, temperatures_C=temperatures)


def bridge_glitches(recording: Recording, settings: Settings) -> tuple[dict[str, np.ndarray], list[str]]:
    """The temperatures with short bursts that no structure follows bridged by interpolation, and a note
    per sensor that had any (also what fleet reduction repairs before it averages)."""
    notes: list[str] = []
    repaired = dict(recording.temperatures_C)
    for name, values in recording.temperatures_C.items():
        glitches = quality.find_glitches(recording.t_s, values, sigmas=settings.glitch_sigmas,
                                         min_jump_K=settings.glitch_min_K,
                                         max_span_s=settings.glitch_max_span_s)
        if glitches is None:
            continue
        repaired[name] = quality.bridge(recording.t_s, values, glitches.samples)
        notes.append(
            f"{name}: {glitches.bursts} glitch burst(s), {int(glitches.samples.sum())} sample(s), up to "
            f"{glitches.peak_K:.2f} K off the sensor's running median (first at t = {glitches.first_t_s:.0f} s "
            f"= {glitches.first_t_s / 3600:.2f} h): bridged by interpolation before fitting")
    return repaired, notes


def prepare(recording: Recording, settings: Settings) -> Readings:
    """Short bursts of a temperature reading that no structure follows are bridged before any
    feature sees them (fed through a gradient or a lag they become spikes of the improved model
    that the gauge never showed), and reported; then the readings are averaged."""
    repaired, notes = bridge_glitches(recording, settings)
    noise_C = {name: white_noise_C(values) for name, values in repaired.items()}
    window_s = settings.sensor_smoothing_s
    averaged = _with(recording, {name: smooth_sensor(recording.t_s, values, window_s)
                                 for name, values in repaired.items()})
    # The averaged readings plus one more draw of each sensor's white noise, averaged alike: a
    # feature computed on it minus the same feature on the readings is what the feature passes on of
    # the sensors' noise, whatever the feature does (a difference, a lag, a square).
    rng = np.random.default_rng(settings.noise_draw_seed)
    noisy = {}
    for name, values in averaged.temperatures_C.items():
        draw = rng.normal(0.0, noise_C.get(name, 0.0), len(values))
        noisy[name] = values + smooth_sensor(recording.t_s, draw, window_s)  # the averaging is linear
    return Readings(recording, averaged, _with(averaged, noisy), noise_C, notes)


def resample(recording: Recording, step_s: float) -> Recording:
    """The recording on a uniform grid of ``step_s`` (the centres of the steps): readings interpolated
    there (temperatures are averaged over minutes already), the gauge and the sim column averaged over
    each step (NaN where a step has none). A uniform grid lets every lag run as one linear filter.
    Recordings sampled at ``step_s / 2`` or slower come back as they are."""
    t = recording.t_s
    if len(t) < 3 or float(np.median(np.diff(t))) * 2 > step_s:
        return recording
    bins = np.floor((t - t[0]) / step_s).astype(np.int64)
    count = int(bins[-1]) + 1
    grid = t[0] + step_s * (np.arange(count) + 0.5)

    def at(values: np.ndarray) -> np.ndarray:
        return np.interp(grid, t, values)

    def mean(values: np.ndarray) -> np.ndarray:
        finite = np.isfinite(values)
        sums = np.bincount(bins[finite], weights=values[finite], minlength=count)
        counts = np.bincount(bins[finite], minlength=count)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)

    return replace(recording, t_s=grid, temperatures_C={k: at(v) for k, v in recording.temperatures_C.items()},
                   spindle_rpm=None if recording.spindle_rpm is None else at(recording.spindle_rpm),
                   positions_mm={k: at(v) for k, v in recording.positions_mm.items()},
                   errors_um={k: mean(v) for k, v in recording.errors_um.items()},
                   simulated_um={k: mean(v) for k, v in recording.simulated_um.items()})


def resampled(readings: Readings, step_s: float) -> Readings:
    """``readings`` with every recording on the same coarser grid (``resample``)."""
    return Readings(resample(readings.raw, step_s), resample(readings.recording, step_s),
                    resample(readings.noisy, step_s), readings.sensor_noise_C, readings.data_quality)
