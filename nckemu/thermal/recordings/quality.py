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

from nckemu.thermal.stats import robust_sigma


@dataclass(frozen=True)
class Glitches:
    """Samples of one sensor judged to be glitches, and the bursts they form."""

    samples: np.ndarray          # boolean mask over the recording
    bursts: int
    first_t_s: float
    peak_K: float


def find_glitches(t_s: np.ndarray, values_C: np.ndarray, *, width_samples: int = 11, sigmas: float = 8.0,
                  min_jump_K: float = 0.3, max_span_s: float = 600.0) -> Glitches | None:
    """Bursts shorter than half of ``width_samples`` that leave the running median by more than
    ``sigmas`` robust sigma of the sensor's scatter around it, and by at least ``min_jump_K``, and are
    over within ``max_span_s`` (from the good reading before to the good reading after): logged every
    few minutes, a heating pulse of a spindle spans a few samples too, and that is heat, not a glitch."""
    n = len(values_C)
    if n < width_samples:
        return None
    flagged, deviation, threshold = _off_the_median(values_C, values_C, width_samples, sigmas, min_jump_K)
    if not flagged.any():
        return None
    # Once more with the first bursts bridged: a burst inside the median's window pulls the median
    # towards it, and where the true reading turns (a load step's knee) that is enough to flag good
    # samples beside the burst, which a straight bridge would then cut across.
    first = flagged
    flagged, deviation, _ = _off_the_median(values_C, bridge(t_s, values_C, first), width_samples, sigmas,
                                            min_jump_K, threshold)
    flagged &= first
    flagged = _brief(t_s, flagged, max_span_s)
    if not flagged.any():
        return None
    widened = _widened(flagged)
    starts = np.flatnonzero(widened & ~np.concatenate(([False], widened[:-1])))
    return Glitches(widened, int(len(starts)), float(t_s[np.flatnonzero(flagged)[0]]),
                    float(np.max(np.abs(deviation[flagged]))))


def _off_the_median(values_C: np.ndarray, reference_C: np.ndarray, width_samples: int, sigmas: float,
                    min_jump_K: float, threshold: float | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Samples further from the running median of ``reference_C`` than the threshold (``sigmas``
    robust sigma of the scatter, at least ``min_jump_K``), the deviations, and the threshold."""
    smooth = median_filter(reference_C, size=width_samples, mode="nearest")
    deviation = values_C - smooth
    if threshold is None:
        sigma = robust_sigma(deviation)
        threshold = max(sigmas * sigma, min_jump_K) if np.isfinite(sigma) else min_jump_K
    return np.abs(deviation) > threshold, deviation, threshold


def _brief(t_s: np.ndarray, flagged: np.ndarray, max_span_s: float) -> np.ndarray:
    """The flagged bursts whose good neighbours are at most ``max_span_s`` apart."""
    out = flagged.copy()
    edges = np.diff(np.concatenate(([0], flagged.astype(np.int8), [0])))
    for start, end in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        before, after = t_s[max(start - 1, 0)], t_s[min(end, len(t_s) - 1)]
        if after - before > max_span_s:
            out[start:end] = False
    return out


def _widened(flagged: np.ndarray) -> np.ndarray:
    """Each flagged sample and one neighbour on each side: the edges of a burst sit between the
    glitch and the true value and are as untrustworthy."""
    widened = flagged.copy()
    widened[1:] |= flagged[:-1]
    widened[:-1] |= flagged[1:]
    return widened


def bridge(t_s: np.ndarray, values_C: np.ndarray, samples: np.ndarray, *, slope_samples: int = 3) -> np.ndarray:
    """The reading with ``samples`` replaced by a cubic (Hermite) bridge between their good neighbours,
    leaving each side with the slope the reading had there (fitted over up to ``slope_samples`` good
    samples). A straight bridge cuts the corner where a structure starts to heat or cool under the
    burst (up to half a sample's movement per bridged sample); the slopes carry the turn across."""
    good = ~samples
    if good.sum() < 2:
        return values_C.copy()
    repaired = values_C.copy()
    repaired[samples] = np.interp(t_s[samples], t_s[good], values_C[good])
    n = len(values_C)
    bad = np.flatnonzero(samples)
    if len(bad) == 0:
        return repaired
    breaks = np.flatnonzero(np.diff(bad) > 1)
    for first, last in zip(np.r_[bad[0], bad[breaks + 1]], np.r_[bad[breaks], bad[-1]], strict=True):
        left, right = first - 1, last + 1
        if left < 0 or right >= n:
            continue  # at an end: the nearest good value (np.interp) is all there is
        left_slope = _edge_slope(t_s, values_C, good, left, -1, slope_samples)
        right_slope = _edge_slope(t_s, values_C, good, right, +1, slope_samples)
        span_s = t_s[right] - t_s[left]
        s = (t_s[first:last + 1] - t_s[left]) / span_s
        h00, h10 = 1 - 3 * s**2 + 2 * s**3, s - 2 * s**2 + s**3
        h01, h11 = 3 * s**2 - 2 * s**3, s**3 - s**2
        repaired[first:last + 1] = (h00 * values_C[left] + h01 * values_C[right]
                                    + span_s * (h10 * left_slope + h11 * right_slope))
    return repaired


def _edge_slope(t_s: np.ndarray, values_C: np.ndarray, good: np.ndarray, edge: int, step: int,
                count: int) -> float:
    """The reading's slope (K/s) at a bridge's edge, from up to ``count`` consecutive good samples
    going away from the gap; 0 when only the edge itself is good (then the bridge is level there)."""
    indices = [edge]
    while len(indices) < count:
        nxt = indices[-1] + step
        if nxt < 0 or nxt >= len(values_C) or not good[nxt]:
            break
        indices.append(nxt)
    if len(indices) < 2:
        return 0.0
    slope, _ = np.polyfit(t_s[indices], values_C[indices], 1)
    return float(slope)
