"""Recordings from a known truth, to prove discovery on data where an effect is concealed.

A synthetic machine: a spindle schedule of 3 h blocks, sensors that follow it through lags
(spindle, bed, column front and rear) and an ambient sinusoid, an axis dwelling at positions.
The baseline model the "builder believes in" is offset + temperature(spindle) + temperature(bed);
the truth adds (or replaces) one effect of the vocabulary, concealed by correlation with an included
term, by smallness against the noise, or by acting in one window only. Null scenarios leave
nothing out but add AR(1) noise, outliers and gaps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .recording import Recording
from .terms import Term, ThermalModel, asymmetric_lag, first_order_lag

SCENARIOS = ("offset", "temperature", "position_dependent_expansion", "thermal_lag", "centrifugal_growth",
             "thermal_gradient", "quadratic_temperature", "gain_error", "heating_cooling_hysteresis",
             "time_drift", "null_ar1", "null_outliers_gaps")
AXIS = "Z"
SPINDLE_SCHEDULE_RPM = (0, 4000, 0, 8000, 0, 2000, 6000, 0, 10000, 0, 3000, 0)


@dataclass
class Scenario:
    name: str
    recording: Recording
    baseline: ThermalModel
    truth_effect: str | None
    truth_parameters: dict[str, float]
    window_s: tuple[float, float] | None = None


def baseline_model() -> ThermalModel:
    return ThermalModel(AXIS, [
        Term("offset", {"value_um": 0.0}),
        Term("temperature", {"sensor": "spindle", "t_ref_C": 20.0, "coeff_um_per_K": 3.0}),
        Term("temperature", {"sensor": "bed", "t_ref_C": 20.0, "coeff_um_per_K": 2.0}),
    ])


def make_scenario(name: str, seed: int = 1, duration_h: float = 36.0, dt_s: float = 60.0) -> Scenario:
    if name not in SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; known: {', '.join(SCENARIOS)}")
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_h * 3600.0, dt_s)
    block = np.minimum((t // (3 * 3600.0)).astype(int), len(SPINDLE_SCHEDULE_RPM) - 1)
    rpm = np.asarray(SPINDLE_SCHEDULE_RPM, dtype=float)[block]
    load = rpm / 10000.0
    ambient = 20.0 + 1.0 * np.sin(2 * np.pi * t / 86400.0)
    spindle = first_order_lag(t, ambient + 8.0 * load, 1200.0)
    bed = first_order_lag(t, ambient + 2.0 * load, 3 * 3600.0)
    front = first_order_lag(t, ambient + 4.0 * load, 3600.0)
    rear = first_order_lag(t, ambient + 2.5 * load, 1.5 * 3600.0)
    dwell = (t // 1800.0).astype(int)
    position = rng.uniform(-60.0, 0.0, dwell.max() + 1)[dwell]
    far_window = (12 * 3600.0, 18 * 3600.0)
    in_far = (t >= far_window[0]) & (t < far_window[1])
    position[in_far] = rng.uniform(-1000.0, -700.0, dwell.max() + 1)[dwell][in_far]
    sensors = {"spindle": spindle, "bed": bed, "front": front, "rear": rear, "ambient": ambient}

    def noisy(values: np.ndarray, sigma_C: float = 0.03) -> np.ndarray:
        return values + rng.normal(0.0, sigma_C, len(values))

    base = baseline_model()
    truth = 3.0 * (spindle - 20.0) + 2.0 * (bed - 20.0)
    effect: str | None = name
    parameters: dict[str, float] = {}
    window = None
    if name == "offset":
        parameters = {"value_um": 4.0}
        truth = truth + 4.0
        base = ThermalModel(AXIS, [t for t in base.terms if t.effect != "offset"])
    elif name == "temperature":
        parameters = {"coeff_um_per_K": 2.5}
        truth = truth + 2.5 * (front - 20.0)
    elif name == "position_dependent_expansion":
        parameters = {"slope_um_per_m_per_K": 11.5}
        truth = truth + 11.5 * position / 1000.0 * (bed - 20.0)
        window = far_window
    elif name == "thermal_lag":
        parameters = {"tau_s": 2400.0}
        truth = 3.0 * (first_order_lag(t, spindle, 2400.0) - 20.0) + 2.0 * (bed - 20.0)
    elif name == "centrifugal_growth":
        parameters = {"coeff_um_per_krpm2": -0.05}
        truth = truth - 0.05 * (rpm / 1000.0) ** 2
    elif name == "thermal_gradient":
        parameters = {"coeff_um_per_K": 6.0}
        truth = truth + 6.0 * (front - rear)
    elif name == "quadratic_temperature":
        parameters = {"coeff_um_per_K2": 0.08}
        truth = truth + 0.08 * (spindle - 20.0) ** 2
    elif name == "gain_error":
        parameters = {"gain": 1.3}
        truth = 1.3 * truth
    elif name == "heating_cooling_hysteresis":
        parameters = {"tau_heat_s": 1800.0, "tau_cool_s": 5400.0}
        truth = 3.0 * (asymmetric_lag(t, spindle, 1800.0, 5400.0) - 20.0) + 2.0 * (bed - 20.0)
    elif name == "time_drift":
        parameters = {"um_per_h": 0.25}
        truth = truth + 0.25 * t / 3600.0
    else:
        effect = None
    white_um, ar_um, phi = (0.3, 0.3, 0.95)
    if name == "null_ar1":
        white_um, ar_um, phi = (0.2, 0.5, 0.98)
    ar = np.zeros_like(t)
    innovations = rng.normal(0.0, ar_um * np.sqrt(1 - phi ** 2), len(t))
    for k in range(1, len(t)):
        ar[k] = phi * ar[k - 1] + innovations[k]
    measured = truth + rng.normal(0.0, white_um, len(t)) + ar
    measured[np.arange(len(t)) % 3 != 0] = np.nan  # the gauge is read every third sample
    if name == "null_outliers_gaps":
        gauge = np.flatnonzero(~np.isnan(measured))
        picks = rng.choice(gauge, size=max(2, len(gauge) // 200), replace=False)
        measured[picks] += rng.choice([-1.0, 1.0], len(picks)) * 25.0
        measured[(t >= 20 * 3600.0) & (t < 22 * 3600.0)] = np.nan
    recording = Recording(
        source=f"<scenario {name} seed {seed}>", t_s=t,
        temperatures_C={f"temp_{k}_C": noisy(v) for k, v in sensors.items()},
        spindle_rpm=rpm, positions_mm={AXIS: position}, errors_um={AXIS: measured},
    )
    return Scenario(name, recording, base, effect, parameters, window)


# ---------------------------------------------------------------------- the closed loop (issue 13)
LOOP_SCENARIOS = ("bed_program_spindle_lag",)
LOOP_BED_COEFF_UM_PER_K = 2.0
LOOP_SPINDLE_COEFF_UM_PER_K = 3.0
LOOP_SPINDLE_TAU_S = 2400.0


def make_loop_scenario(name: str = "bed_program_spindle_lag", seed: int = 1, duration_h: float = 36.0,
                       dt_s: float = 60.0) -> Scenario:
    """A machine whose compensation program knows only the bed: Z grows 2 um/K with the bed and 3 um/K
    with a spindle structure that follows its sensor through a 2400 s lag. ``baseline`` is the program's
    law (what a bed-only program compensates, e.g. ``fixtures/plc/bed_only_z.awl``); the missing effect
    is the spindle's lag. Sensors: spindle and bed only (both wired to the PLC in
    ``fixtures/machines/loop_mill.toml``)."""
    if name not in LOOP_SCENARIOS:
        raise ValueError(f"unknown loop scenario {name!r}; known: {', '.join(LOOP_SCENARIOS)}")
    base = make_scenario("temperature", seed, duration_h, dt_s)  # time base, inputs, positions, noise draws
    recording = base.recording
    t = recording.t_s
    rng = np.random.default_rng(seed + 1000)
    rpm = recording.spindle_rpm if recording.spindle_rpm is not None else np.zeros_like(t)
    ambient = 20.0 + 1.0 * np.sin(2 * np.pi * t / 86400.0)
    spindle = first_order_lag(t, ambient + 8.0 * rpm / 10000.0, 1200.0)
    bed = first_order_lag(t, ambient + 2.0 * rpm / 10000.0, 3 * 3600.0)
    truth = LOOP_BED_COEFF_UM_PER_K * (bed - 20.0) \
        + LOOP_SPINDLE_COEFF_UM_PER_K * (first_order_lag(t, spindle, LOOP_SPINDLE_TAU_S) - 20.0)
    phi = 0.95
    ar = np.zeros_like(t)
    innovations = rng.normal(0.0, 0.3 * np.sqrt(1 - phi ** 2), len(t))
    for k in range(1, len(t)):
        ar[k] = phi * ar[k - 1] + innovations[k]
    measured = truth + rng.normal(0.0, 0.3, len(t)) + ar
    measured[np.arange(len(t)) % 3 != 0] = np.nan
    loop_recording = Recording(
        source=f"<loop scenario {name} seed {seed}>", t_s=t,
        temperatures_C={"temp_spindle_C": spindle + rng.normal(0.0, 0.03, len(t)),
                        "temp_bed_C": bed + rng.normal(0.0, 0.03, len(t))},
        spindle_rpm=rpm, positions_mm=dict(recording.positions_mm), errors_um={AXIS: measured})
    program_law = ThermalModel(AXIS, [Term("temperature", {"sensor": "bed", "t_ref_C": 20.0,
                                                           "coeff_um_per_K": LOOP_BED_COEFF_UM_PER_K})])
    return Scenario(name, loop_recording, program_law, "thermal_lag",
                    {"tau_s": LOOP_SPINDLE_TAU_S, "coeff_um_per_K": LOOP_SPINDLE_COEFF_UM_PER_K})
