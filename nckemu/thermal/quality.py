"""Sensor glitches: short excursions of a temperature reading that the structure cannot follow.

A temperature sensor that jumps by several kelvin for a few samples and comes back (a bad contact,
a dropped conversion read as garbage) is not heat. Fed into a gradient or a lag term it becomes a
spike of the improved model that the gauge never saw. Such bursts are found against the sensor's own
scatter around a running median, reported, and bridged by linear interpolation before any feature is
computed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

from .stats import robust_sigma


@dataclass(frozen=True)
class Glitches:
    """Samples of one sensor judged to be glitches, and the bursts they form."""

    samples: np.ndarray          # boolean mask over the recording
    bursts: int
    first_t_s: float
    peak_K: float


def find_glitches(t_s: np.ndarray, values_C: np.ndarray, *, width_samples: int = 11, sigmas: float = 8.0,
                  min_jump_K: float = 0.3) -> Glitches | None:
    """Bursts shorter than half of ``width_samples`` that leave the running median by more than
    ``sigmas`` robust sigma of the sensor's scatter around it, and by at least ``min_jump_K``."""
    n = len(values_C)
    if n < width_samples:
        return None
    smooth = median_filter(values_C, size=width_samples, mode="nearest")
    deviation = values_C - smooth
    sigma = robust_sigma(deviation)
    threshold = max(sigmas * sigma, min_jump_K) if np.isfinite(sigma) else min_jump_K
    flagged = np.abs(deviation) > threshold
    if not flagged.any():
        return None
    # Widen each flagged sample by one neighbour on each side: the edges of a burst sit between
    # the glitch and the true value and are as untrustworthy.
    widened = flagged.copy()
    widened[1:] |= flagged[:-1]
    widened[:-1] |= flagged[1:]
    starts = np.flatnonzero(widened & ~np.concatenate(([False], widened[:-1])))
    return Glitches(widened, int(len(starts)), float(t_s[np.flatnonzero(flagged)[0]]),
                    float(np.max(np.abs(deviation[flagged]))))


def bridge(t_s: np.ndarray, values_C: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """The reading with ``samples`` replaced by linear interpolation between their good neighbours."""
    good = ~samples
    if good.sum() < 2:
        return values_C.copy()
    repaired = values_C.copy()
    repaired[samples] = np.interp(t_s[samples], t_s[good], values_C[good])
    return repaired
