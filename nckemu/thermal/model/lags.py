"""First-order lags of a signal sampled in time: what a structure does with the heat a sensor sees."""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter


def uniform_step_s(dt: np.ndarray) -> float | None:
    """The sampling step when the steps ``dt`` are all one (to a part in 1e9), else None: a uniformly
    sampled series is one linear filter (``lfilter``), not a pass over time."""
    if len(dt) and float(dt.max() - dt.min()) <= 1e-9 * abs(float(dt[0])):
        return float(dt[0])
    return None


def first_order_lag(t_s: np.ndarray, signal: np.ndarray, tau_s: float) -> np.ndarray:
    """x' = (u - x)/tau with zero-order hold between samples; starts settled at u[0]."""
    if len(signal) == 0:
        return signal.copy()
    dt = np.diff(t_s)
    step_s = uniform_step_s(dt)
    if step_s is not None:
        alpha = 1.0 - math.exp(-step_s / tau_s)
        state = lfilter([alpha], [1.0, alpha - 1.0], signal - signal[0])
        return state + signal[0]
    out = np.empty_like(signal)
    out[0] = signal[0]
    weights = 1.0 - np.exp(-dt / tau_s)
    for k in range(1, len(signal)):
        out[k] = out[k - 1] + weights[k - 1] * (signal[k] - out[k - 1])
    return out


def first_order_lags(series: list[tuple[np.ndarray, np.ndarray]], tau_s: float) -> list[np.ndarray]:
    """``first_order_lag`` of several (t_s, signal) series (the runs of a machine) at one time
    constant, the same numbers: the uniformly sampled series of one step in one ``lfilter`` call (a
    column each, the shorter padded at their end, which a causal filter never sees), the others in one
    pass over time for all of them."""
    out: list[np.ndarray] = [signal.copy() if len(signal) == 0 else signal for _t, signal in series]
    uniform: dict[float, list[int]] = {}
    stepped: list[tuple[int, np.ndarray]] = []
    for index, (t_s, signal) in enumerate(series):
        if len(signal) == 0:
            continue
        dt = np.diff(t_s)
        step_s = uniform_step_s(dt)
        if step_s is not None:
            uniform.setdefault(step_s, []).append(index)
        else:
            stepped.append((index, 1.0 - np.exp(-dt / tau_s)))
    for step_s, indices in uniform.items():
        alpha = 1.0 - math.exp(-step_s / tau_s)
        columns = np.zeros((max(len(series[i][1]) for i in indices), len(indices)))
        for column, index in enumerate(indices):
            signal = series[index][1]
            columns[:len(signal), column] = signal - signal[0]
        state = lfilter([alpha], [1.0, alpha - 1.0], columns, axis=0)
        for column, index in enumerate(indices):
            signal = series[index][1]
            out[index] = state[:len(signal), column] + signal[0]
    if stepped:
        longest = max(len(series[index][1]) for index, _w in stepped)
        signals = np.zeros((longest, len(stepped)))
        weights = np.zeros((longest - 1, len(stepped)))
        for column, (index, step_weights) in enumerate(stepped):
            signal = series[index][1]
            signals[:len(signal), column] = signal
            weights[:len(signal) - 1, column] = step_weights
        lagged = np.empty_like(signals)
        lagged[0] = signals[0]
        for k in range(1, longest):
            lagged[k] = lagged[k - 1] + weights[k - 1] * (signals[k] - lagged[k - 1])
        for column, (index, _w) in enumerate(stepped):
            out[index] = lagged[:len(series[index][1]), column]
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


def asymmetric_lags(series: list[tuple[np.ndarray, np.ndarray]], pairs: list[tuple[float, float]]) -> list[np.ndarray]:
    """``asymmetric_lag`` of every (t_s, signal) series (a run each) for every (tau_heat_s,
    tau_cool_s) pair, one (samples, pairs) array per series: the same operations in the same order per
    series and pair (so the same numbers), one pass over time for all of them (the loop over time is in
    Python; a shorter series is padded at its end with its last value, and the padding dropped)."""
    longest = max((len(signal) for _t, signal in series), default=0)
    if longest == 0:
        return [np.empty((0, len(pairs))) for _ in series]
    signals = np.zeros((longest, len(series)))
    steps_s = np.ones((longest - 1, len(series)))
    for index, (t_s, signal) in enumerate(series):
        if len(signal):
            signals[:len(signal), index] = signal
            signals[len(signal):, index] = signal[-1]
            steps_s[:len(signal) - 1, index] = np.diff(t_s)
    heat = 1.0 - np.exp(-steps_s[:, :, None] / np.array([tau_heat for tau_heat, _ in pairs]))
    cool = 1.0 - np.exp(-steps_s[:, :, None] / np.array([tau_cool for _, tau_cool in pairs]))
    out = np.empty((longest, len(series), len(pairs)))
    previous = np.repeat(signals[0][:, None], len(pairs), axis=1)
    out[0] = previous
    for k in range(1, longest):
        target = signals[k][:, None]
        previous = previous + np.where(target > previous, heat[k - 1], cool[k - 1]) * (target - previous)
        out[k] = previous
    return [out[:len(signal), index] for index, (_t, signal) in enumerate(series)]
