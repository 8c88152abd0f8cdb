"""Sensor glitches: bursts are found and bridged; clean readings are left alone."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.thermal.model.lags import first_order_lag
from nckemu.thermal.recordings.quality import bridge, find_glitches


def clean_reading(seed: int, dt_s: float, noise_C: float) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 12 * 3600.0, dt_s)
    load = rng.choice([0.0, 4.0, 8.0], size=6)[np.minimum((t // 7200).astype(int), 5)]
    # A structure's sensor: 1200 s or slower, so it moves at most 8 K x 60/1200 = 0.4 K a minute.
    truth = first_order_lag(t, 20.0 + load, float(rng.uniform(1200.0, 7200.0)))
    return t, truth + rng.normal(0.0, noise_C, len(t))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dt_s=st.sampled_from([15.0, 60.0]), noise_C=st.floats(0.005, 0.05),
       bursts=st.lists(st.tuples(st.floats(0.05, 0.95), st.integers(1, 4), st.floats(1.5, 4.0),
                                 st.sampled_from([-1.0, 1.0])), min_size=1, max_size=4))
def test_bursts_are_found_and_bridged(seed: int, dt_s: float, noise_C: float,
                                      bursts: list[tuple[float, int, float, float]]) -> None:
    """Bursts of 1-4 samples, 1.5 K or more off: several times what the sensor moves in a sample."""
    t, clean = clean_reading(seed, dt_s, noise_C)
    reading = clean.copy()
    hit = np.zeros(len(t), dtype=bool)
    quarter = len(t) // 4
    for index, (where, length, size_K, sign) in enumerate(bursts):  # one burst per quarter: apart
        start = index * quarter + int(where * (quarter - 10))
        reading[start:start + length] += sign * size_K
        hit[start:start + length] = True
    glitches = find_glitches(t, reading)
    assert glitches is not None
    assert glitches.samples[hit].all()
    repaired = bridge(t, reading, glitches.samples)
    assert np.max(np.abs(repaired - clean)) < 0.3 + 6 * noise_C


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dt_s=st.sampled_from([15.0, 60.0]), noise_C=st.floats(0.005, 0.05))
def test_clean_readings_are_left_alone(seed: int, dt_s: float, noise_C: float) -> None:
    t, reading = clean_reading(seed, dt_s, noise_C)
    assert find_glitches(t, reading) is None
