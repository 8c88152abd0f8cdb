"""First-order lags of a signal sampled in time: what a structure does with the heat a sensor sees."""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter


def first_order_lag(t_s: np.ndarray, signal: np.ndarray, tau_s: float) -> np.ndarray:
    """x' = (u - x)/tau with zero-order hold between samples; starts settled at u[0]."""
    if len(signal) == 0:
        return signal.copy()
    dt = np.diff(t_s)
    if len(dt) and float(dt.max() - dt.min()) <= 1e-9 * abs(float(dt[0])):  # uniform sampling
        alpha = 1.0 - math.exp(-dt[0] / tau_s)
        state = lfilter([alpha], [1.0, alpha - 1.0], signal - signal[0])
        return state + signal[0]
    out = np.empty_like(signal)
    out[0] = signal[0]
    weights = 1.0 - np.exp(-dt / tau_s)
    for k in range(1, len(signal)):
        out[k] = out[k - 1] + weights[k - 1] * (signal[k] - out[k - 1])
    return out


def asymmetric_lag(t_s: np.ndarray, signal: np.ndarray, tau_heat_s: float, tau_cool_s: float) -> np.ndarray:
    """A first-order lag whose time constant depends on whether the structure heats or cools."""
    out = np.empty_like(signal)
    if len(signal) == 0:
        return out
    out[0] = signal[0]
    dt = np.diff(t_s)
    heat = 1.0 - np.exp(-dt / tau_heat_s)
    cool = 1.0 - np.exp(-dt / tau_cool_s)
    previous = float(signal[0])
    for k in range(1, len(signal)):
        target = signal[k]
        previous += (heat[k - 1] if target > previous else cool[k - 1]) * (target - previous)
        out[k] = previous
    return out
