"""Recordings from a known truth, to prove discovery on data where an effect is concealed.

A synthetic machine: a spindle schedule of 3 h blocks, sensors that follow it through lags
(spindle, bed, column front and rear) and an ambient sinusoid, an axis dwelling at positions.
The baseline model the "builder believes in" is offset + temperature(spindle) + temperature(bed);
the truth adds (or replaces) one effect of the vocabulary, concealed by correlation with an included
term, by smallness against the noise, or by acting in one window only. Null scenarios leave
nothing out but add AR(1) noise, outliers and gaps. ``make_run_family`` builds many runs of one
machine instead, where the concealed physics shows across runs (issue 23).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from nckemu.thermal.model.lags import asymmetric_lag, first_order_lag
from nckemu.thermal.model.terms import Term, ThermalModel
from nckemu.thermal.recordings.recording import Recording

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


# ---------------------------------------------------------------------------------------------------
# Variants: the failures seen on cases written outside the project, reproduced in spirit.
# Built on top of make_scenario (same seed, same sensors and noise draws), so they need no change to it.

VARIANTS = ("position_dependent_expansion_calibrated", "quadratic_temperature_calibrated",
            "thermal_gradient_calibrated", "quadratic_temperature_small", "thermal_lag_small",
            "thermal_gradient_glitch", "null_ar1_gaps_outliers", "null_calibrated_gaps",
            "null_slow_ar_gaps_outliers")
ALL_SCENARIOS = SCENARIOS + VARIANTS
# How much of an effect a "small" variant keeps: near the detection limit (docs/thermal.md).
SMALL_SCALE = 0.5
# Parameters that size an effect (scaled with it); the others (time constants) shape it.
_SIZE_PARAMETERS = {"value_um", "coeff_um_per_K", "slope_um_per_m_per_K", "coeff_um_per_krpm2",
                    "coeff_um_per_K2", "um_per_h"}


def calibrated_baseline(model: ThermalModel, recording: Recording) -> ThermalModel:
    """The model with its coefficients fitted by least squares on ``recording`` itself (every gauge
    reading, the effect's window included): what a builder who calibrates on the test record gives."""
    error = recording.errors_um[model.axis]
    measured = ~np.isnan(error)
    terms = model.additive_terms()
    design = np.column_stack([term.feature(recording, model.axis)[measured] for term in terms])
    coefficients, *_ = np.linalg.lstsq(design, error[measured], rcond=None)
    return ThermalModel(model.axis, [t.with_coefficient(float(c)) for t, c in zip(terms, coefficients, strict=True)],
                        "<calibrated on the record>")


def scaled_scenario(name: str, seed: int, scale: float) -> Scenario:
    """``name``'s scenario with its concealed effect multiplied by ``scale`` (noise unchanged).

    Every scenario of one seed draws the same sensors and noise, so the effect's contribution is the
    difference to the ``offset`` scenario, whose truth is the baseline plus 4 um."""
    if name not in SCENARIOS or name.startswith("null"):
        raise ValueError(f"no effect to scale in {name!r}")
    scenario = make_scenario(name, seed)
    reference = make_scenario("offset", seed).recording.errors_um[AXIS] - 4.0
    measured = scenario.recording.errors_um[AXIS]
    errors = {AXIS: reference + scale * (measured - reference)}
    parameters = dict(scenario.truth_parameters)
    for key in parameters:
        if key in _SIZE_PARAMETERS:
            parameters[key] *= scale
    if name == "gain_error":
        parameters["gain"] = 1.0 + scale * (parameters["gain"] - 1.0)
    recording = Recording(f"<scenario {name} x{scale:g} seed {seed}>", scenario.recording.t_s,
                          scenario.recording.temperatures_C, scenario.recording.spindle_rpm,
                          scenario.recording.positions_mm, errors)
    return Scenario(f"{name} x{scale:g}", recording, scenario.baseline, scenario.truth_effect, parameters,
                    scenario.window_s)


def _with_gaps_and_outliers(recording: Recording, seed: int, outlier_um: float = 25.0) -> Recording:
    rng = np.random.default_rng(10_000 + seed)
    t = recording.t_s
    measured = recording.errors_um[AXIS].copy()
    for _ in range(3):  # three gauge gaps of 1-3 h
        start = rng.uniform(0.0, t[-1] - 3 * 3600.0)
        measured[(t >= start) & (t < start + rng.uniform(1.0, 3.0) * 3600.0)] = np.nan
    gauge = np.flatnonzero(~np.isnan(measured))
    picks = rng.choice(gauge, size=max(2, len(gauge) // 150), replace=False)
    measured[picks] += rng.choice([-1.0, 1.0], len(picks)) * outlier_um * rng.uniform(0.6, 1.4, len(picks))
    return Recording(recording.source + " with gaps and outliers", t, recording.temperatures_C,
                     recording.spindle_rpm, recording.positions_mm, {AXIS: measured})


def _with_sensor_glitches(recording: Recording, sensor: str, seed: int) -> Recording:
    """Bursts of 1-4 samples, 1.5-3 K off, in one sensor's reading (the gauge does not see them)."""
    rng = np.random.default_rng(20_000 + seed)
    values = recording.temperatures_C[f"temp_{sensor}_C"].copy()
    for start in rng.choice(len(values) - 5, size=5, replace=False):
        values[start:start + int(rng.integers(1, 5))] += rng.uniform(1.5, 3.0) * rng.choice([-1.0, 1.0])
    temperatures = {**recording.temperatures_C, f"temp_{sensor}_C": values}
    return Recording(recording.source + f" with {sensor} glitches", recording.t_s, temperatures,
                     recording.spindle_rpm, recording.positions_mm, recording.errors_um)


def _with_slow_wander(recording: Recording, seed: int, sigma_um: float = 0.6, phi: float = 0.995) -> Recording:
    """A slower gauge wander on top (AR(1), phi per sample): hours-long excursions that a lag with a
    long enough time constant can chase."""
    rng = np.random.default_rng(30_000 + seed)
    innovations = rng.normal(0.0, sigma_um * np.sqrt(1 - phi ** 2), len(recording.t_s))
    wander = np.zeros_like(recording.t_s)
    for k in range(1, len(wander)):
        wander[k] = phi * wander[k - 1] + innovations[k]
    return Recording(recording.source + " with slow wander", recording.t_s, recording.temperatures_C,
                     recording.spindle_rpm, recording.positions_mm, {AXIS: recording.errors_um[AXIS] + wander})


def make_variant(name: str, seed: int = 1) -> Scenario:
    if name in SCENARIOS:
        return make_scenario(name, seed)
    if name not in VARIANTS:
        raise ValueError(f"unknown scenario {name!r}; known: {', '.join(ALL_SCENARIOS)}")
    if name.endswith("_calibrated"):
        scenario = make_scenario(name[:-len("_calibrated")], seed)
        scenario.baseline = calibrated_baseline(scenario.baseline, scenario.recording)
    elif name.endswith("_small"):
        scenario = scaled_scenario(name[:-len("_small")], seed, SMALL_SCALE)
    elif name == "thermal_gradient_glitch":
        scenario = make_scenario("thermal_gradient", seed)
        scenario.recording = _with_sensor_glitches(scenario.recording, "front", seed)
    elif name == "null_ar1_gaps_outliers":
        scenario = make_scenario("null_ar1", seed)
        scenario.recording = _with_gaps_and_outliers(scenario.recording, seed)
    elif name == "null_slow_ar_gaps_outliers":
        scenario = make_scenario("null_ar1", seed)
        scenario.recording = _with_slow_wander(_with_gaps_and_outliers(scenario.recording, seed), seed)
    else:  # null_calibrated_gaps: nothing missing, the baseline calibrated on the record, gauge gaps
        scenario = make_scenario("null_ar1", seed)
        scenario.recording = _with_gaps_and_outliers(scenario.recording, seed, outlier_um=0.0)
        scenario.baseline = calibrated_baseline(scenario.baseline, scenario.recording)
    scenario.name = name
    return scenario


# ---------------------------------------------------------------------------------------------------
# Families of runs (issue 23): many runs of one machine, where the concealed physics shows only across
# runs. Within one run the missing term is (nearly) a multiple of what the baseline already has, so a
# refit of the baseline's coefficients on that run absorbs it; the multiple changes from run to run,
# and coefficients shared by all runs cannot. Each run is re-referenced at its start (the gauge reads 0
# there: its own constant offset), logged at irregular intervals with gaps, and some runs lack the
# spindle speed or a sensor, as recordings from the field do.

RUN_FAMILIES = ("job_mix_gradient", "heating_cooling_days", "null_job_mix", "null_heating_cooling")
# The six sensors of the family's machine; the baseline needs spindle and bed, the others may be absent.
FAMILY_SENSORS = ("spindle", "bed", "front", "rear", "ambient", "coolant")
_OPTIONAL_SENSORS = ("front", "rear", "ambient", "coolant")
# The sensors a run may lack by default: none the concealed physics needs (front and rear carry the
# gradient). A run without a sensor the physics needs is another question (can a candidate be judged
# on the runs that have its columns?): ask it with ``missing_from=_OPTIONAL_SENSORS``.
_MAY_LACK = {"job_mix": ("ambient", "coolant"), "heating_cooling": _OPTIONAL_SENSORS}
FAMILY_GRADIENT_UM_PER_K = 6.0
FAMILY_TAU_HEAT_S = 1800.0
FAMILY_TAU_COOL_S = 5400.0


@dataclass(frozen=True)
class FamilyTruth:
    effect: str | None                   # the physics the baseline leaves out (None: nothing)
    parameters: dict[str, float]
    offsets_um: tuple[float, ...]        # per run: what re-referencing the gauge at the run's start added
    kinds: tuple[str, ...]               # per run: the run's job mix ("spindle 0.62 axes 0.21") or "heating"/"cooling"


@dataclass
class RunFamily:
    name: str
    runs: list[Recording]
    model: ThermalModel                  # the baseline the builder believes in
    truth: FamilyTruth


def _check_family(name: str, known: tuple[str, ...], runs: int) -> None:
    """A run family's arguments: one of ``known``, at least 2 runs."""
    if name not in known:
        raise ValueError(f"unknown run family {name!r}; known: {', '.join(known)}")
    if runs < 2:
        raise ValueError("a family has at least 2 runs")


def _lag_from(grid_s: np.ndarray, signal: np.ndarray, tau_s: float) -> np.ndarray:
    return first_order_lag(grid_s, signal, tau_s)


def _run_inputs(kind: str, rng: np.random.Generator, grid_s: np.ndarray,
                ramp_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, str]:
    """Spindle and feed-drive loads (0..1) over one run, and the run's label.

    job_mix: jobs of 1-3 h with pauses of 0.5-2 h; the day's job mix sets the spindle speed and how
    hard the axes work, the same for every job of the day; a job ramps up and down over ``ramp_s``.
    heating/cooling: the machine starts settled
    at one load and steps monotonically to others (up on a heating day, down on a cooling day), so a
    run holds one direction of heat flow only."""
    hours = grid_s / 3600.0
    if kind == "job_mix":
        spindle_share = float(rng.uniform(0.15, 0.9))
        axis_share = float(rng.uniform(0.15, 0.9))
        on = np.zeros_like(grid_s)
        clock_h = float(rng.uniform(0.2, 1.0))
        while clock_h < hours[-1]:
            length_h = float(rng.uniform(1.0, 3.0))
            on[(hours >= clock_h) & (hours < clock_h + length_h)] = 1.0
            clock_h += length_h + float(rng.uniform(0.5, 2.0))
        if ramp_s > 0:  # slow transients, where lags of different time constants look alike
            on = uniform_filter1d(on, max(1, int(ramp_s / float(grid_s[1] - grid_s[0]))), mode="nearest")
        return spindle_share * on, axis_share * on, f"spindle {spindle_share:.2f} axes {axis_share:.2f}"
    steps = int(rng.integers(1, 4))
    levels = np.sort(rng.uniform(0.0, 1.0, steps + 1))
    if kind == "cooling":
        levels = levels[::-1]
    level_at = np.full_like(grid_s, levels[0])
    step_times_h = np.sort(rng.uniform(0.5, max(0.6, 0.6 * hours[-1]), steps))
    for time_h, level in zip(step_times_h, levels[1:], strict=True):
        level_at[hours >= time_h] = level
    return level_at, 0.3 * level_at, kind


def _irregular_times(rng: np.random.Generator, duration_s: float, dt_s: float) -> np.ndarray:
    """Sample times with intervals of 0.5-1.5 dt_s and, in half of the runs, one gap of 10-45 min."""
    count = int(duration_s / dt_s * 1.2) + 10
    t = np.cumsum(rng.uniform(0.5, 1.5, count) * dt_s)
    t = np.concatenate(([0.0], t[t < duration_s]))
    if rng.random() < 0.5:
        start = float(rng.uniform(0.2, 0.8) * duration_s)
        t = t[(t < start) | (t >= start + rng.uniform(600.0, 2700.0))]
    return t


def _ar1(rng: np.random.Generator, grid_s: np.ndarray, sigma: float, phi_per_minute: float) -> np.ndarray:
    from scipy.signal import lfilter

    step_min = float(grid_s[1] - grid_s[0]) / 60.0
    phi = phi_per_minute ** step_min
    innovations = rng.normal(0.0, sigma * math.sqrt(1 - phi ** 2), len(grid_s))
    return lfilter([1.0], [1.0, -phi], innovations)


def make_run_family(name: str, seed: int = 1, runs: int = 8, hours_per_run: float = 10.0,
                    dt_s: float = 60.0, *, missing_share: float = 0.15,
                    missing_from: tuple[str, ...] | None = None, ramp_s: float = 0.0) -> RunFamily:
    """``runs`` runs of one machine (deterministic per ``seed``; a null shares its counterpart's inputs
    and noise draws, seed for seed, and differs only by the truth).

    - ``job_mix_gradient``: the column bends with the difference of its front and rear temperatures
      (6 um/K), heated by the spindle and by the feed drives. Every job of a day has the same mix, so
      within a day front - rear follows the spindle's heat and a refit of the baseline absorbs it; the
      mix changes from day to day, and across days the gradient shows. Within a day the jobs' steps
      still show it now and then (single-run discovery names it on about half of the runs);
      ``ramp_s`` (jobs ramping up and down over that time) hides it further.
    - ``heating_cooling_days``: the spindle structure follows its sensor through a lag of 30 min while
      heating and of 90 min while cooling. A day heats or cools, never both: within a day a single lag
      (or a refit) explains it; only between heating and cooling days does the hysteresis show. At
      least two days of each kind.
    - ``null_job_mix``, ``null_heating_cooling``: the same days, nothing left out.

    A share ``missing_share`` of the runs lacks the spindle speed, and as many one sensor of
    ``missing_from`` (by default one the concealed physics does not need; never spindle or bed, which
    the baseline needs)."""
    _check_family(name, RUN_FAMILIES, runs)
    base_name = name.removeprefix("null_")
    job_mix = base_name in ("job_mix", "job_mix_gradient")
    rng = np.random.default_rng([seed, 0 if job_mix else 1])
    duration_s = hours_per_run * 3600.0
    grid_step_s = min(dt_s, 30.0)
    grid = np.arange(0.0, duration_s + grid_step_s, grid_step_s)
    if job_mix:
        kinds = ["job_mix"] * runs
    else:
        kinds = ["heating", "cooling"] * 2 + [str(k) for k in rng.choice(["heating", "cooling"], runs - 4)] \
            if runs >= 4 else ["heating", "cooling"][:runs]
        kinds = [kinds[i] for i in rng.permutation(runs)]
    concealed = not name.startswith("null_")
    may_lack = missing_from if missing_from is not None else _MAY_LACK["job_mix" if job_mix else "heating_cooling"]
    if not set(may_lack) <= set(_OPTIONAL_SENSORS):
        raise ValueError(f"a run may lack only {', '.join(_OPTIONAL_SENSORS)}, not {', '.join(may_lack)}")
    recordings: list[Recording] = []
    offsets: list[float] = []
    labels: list[str] = []
    for index, kind in enumerate(kinds):
        spindle_load, axis_load, label = _run_inputs(kind, rng, grid, ramp_s)
        ambient = rng.uniform(18.0, 24.0) + 0.4 * np.sin(2 * np.pi * (grid / 86400.0 + rng.random()))
        spindle = _lag_from(grid, ambient + 8.0 * spindle_load, 1200.0)
        bed = _lag_from(grid, ambient + 2.0 * spindle_load + 1.5 * axis_load, 3 * 3600.0)
        front = _lag_from(grid, ambient + 4.0 * spindle_load, 3600.0)
        rear = _lag_from(grid, ambient + 4.0 * axis_load, 3600.0)
        coolant = _lag_from(grid, ambient + 1.0 * spindle_load, 2400.0)
        sensors = {"spindle": spindle, "bed": bed, "front": front, "rear": rear, "ambient": ambient,
                   "coolant": coolant}
        truth = 3.0 * (spindle - 20.0) + 2.0 * (bed - 20.0)
        if concealed and job_mix:
            truth = truth + FAMILY_GRADIENT_UM_PER_K * (front - rear)
        elif concealed:
            truth = 3.0 * (asymmetric_lag(grid, spindle, FAMILY_TAU_HEAT_S, FAMILY_TAU_COOL_S) - 20.0) \
                + 2.0 * (bed - 20.0)
        wander = _ar1(rng, grid, 0.3, 0.95)
        t = _irregular_times(rng, duration_s, dt_s)
        offset = -float(np.interp(t[0], grid, truth + wander))
        measured = np.interp(t, grid, truth + wander) + offset + rng.normal(0.0, 0.3, len(t))
        if rng.random() < 0.3:  # the gauge was not read for 5-20 min
            start = float(rng.uniform(0.1, 0.9) * duration_s)
            measured[(t >= start) & (t < start + rng.uniform(300.0, 1200.0))] = np.nan
        temperatures = {f"temp_{k}_C": np.interp(t, grid, v) + rng.normal(0.0, 0.03, len(t))
                        for k, v in sensors.items()}
        if rng.random() < missing_share:
            del temperatures[f"temp_{may_lack[int(rng.integers(len(may_lack)))]}_C"]
        rpm = np.round(np.interp(t, grid, spindle_load) * 10000.0 / 250.0) * 250.0
        run_name = f"{name}_s{seed}_run{index + 1:02d}"
        recordings.append(Recording(f"<{run_name}>", t, temperatures, None if rng.random() < missing_share else rpm,
                                    {}, {AXIS: measured}, name=run_name))
        offsets.append(offset)
        labels.append(label)
    if not concealed:
        effect, parameters = None, {}
    elif job_mix:
        effect, parameters = "thermal_gradient", {"coeff_um_per_K": FAMILY_GRADIENT_UM_PER_K}
    else:
        effect, parameters = "heating_cooling_hysteresis", {"tau_heat_s": FAMILY_TAU_HEAT_S,
                                                             "tau_cool_s": FAMILY_TAU_COOL_S}
    return RunFamily(name, recordings, baseline_model(), FamilyTruth(effect, parameters, tuple(offsets),
                                                                      tuple(labels)))


# ---------------------------------------------------------------------------------------------------
# Short days logged slowly (issue 31): 30 runs of 5-9 h, logged every 130-1 200 s, each re-referenced
# at its start, the machine's duty cycles differing from day to day. The concealed effect is either a
# transient (the column bends while heat from the hydraulic unit bolted to its front crosses it, and
# straightens as it evens out: the error overshoots and falls while the front sensor still rises), or
# a pair that shows only together (the front and rear sensors see the hydraulic unit's heat at
# different sensitivities, the rear also the chips' heat; the column follows the rear's reading less
# half the front's, the chips' heat alone, so either sensor alone follows mostly the common heat,
# which the error does not).

TRANSIENT_FAMILIES = ("skin_core_days", "pair_days", "null_skin_core_days")
TRANSIENT_SENSOR = "front"
TRANSIENT_TAU_S = 5400.0
TRANSIENT_UM_PER_K = 4.0
PAIR_REAR_UM_PER_K = 3.0
PAIR_FRONT_UM_PER_K = -1.5


def _duty_cycle(rng: np.random.Generator, grid_s: np.ndarray) -> np.ndarray:
    """On/off (0/1) over a day: a start 0-0.6 h in, then periods of 1-3 h on for 30-90 % of each (the
    day's own duty cycle), at the day's own level (0.4-1)."""
    hours = grid_s / 3600.0
    period_h, duty, level = float(rng.uniform(1.0, 3.0)), float(rng.uniform(0.3, 0.9)), float(rng.uniform(0.4, 1.0))
    start_h = float(rng.uniform(0.0, 0.6))
    phase = (hours - start_h) % period_h
    return level * ((hours >= start_h) & (phase < duty * period_h)).astype(float)


def _logged_day(rng: np.random.Generator, run_name: str, grid: np.ndarray, truth: np.ndarray, wander: np.ndarray,
                sensors: dict[str, np.ndarray], spindle_load: np.ndarray,
                t: np.ndarray | None = None) -> tuple[Recording, float]:
    """One day of a run family as its logger wrote it, at ``t`` (default: the simulation's grid): the
    gauge reading truth and wander from zero (its offset returned) with 0.3 um of noise, the sensors
    with 0.03 K, the spindle speed in 250 rpm steps. Noise is drawn gauge first, then the sensors in
    order, so every family keeps its seeds' days."""
    t = grid if t is None else t
    offset = -float(np.interp(t[0], grid, truth + wander))
    measured = np.interp(t, grid, truth + wander) + offset + rng.normal(0.0, 0.3, len(t))
    temperatures = {f"temp_{k}_C": np.interp(t, grid, v) + rng.normal(0.0, 0.03, len(t)) for k, v in sensors.items()}
    rpm = np.round(np.interp(t, grid, spindle_load) * 10000.0 / 250.0) * 250.0
    return Recording(f"<{run_name}>", t, temperatures, rpm, {}, {AXIS: measured}, name=run_name), offset


def _slow_sampling(rng: np.random.Generator, duration_s: float) -> np.ndarray:
    """Logged every 130-1 200 s (log-uniform: mostly a few minutes, now and then 20 min)."""
    steps = np.exp(rng.uniform(math.log(130.0), math.log(1200.0), int(duration_s / 130.0) + 2))
    t = np.concatenate(([0.0], np.cumsum(steps)))
    return t[t <= duration_s]


def make_transient_family(name: str, seed: int = 1, runs: int = 30) -> RunFamily:
    """``runs`` days of 5-9 h (deterministic per ``seed``; the families share inputs and noise draws
    seed for seed, and differ only by the truth). Baseline: ``baseline_model()``.

    - ``skin_core_days``: ``transient_gradient(front)``, tau 1.5 h, 4 um/K on top of the baseline.
    - ``pair_days``: 3 um/K x rear - 1.5 um/K x front (temperature terms, 20 C reference): the
      hydraulic unit's heat cancels, the chips' heat (seen by the rear alone, a quarter of its
      reading's swing) is left.
    - ``null_skin_core_days``: the same days, nothing left out."""
    _check_family(name, TRANSIENT_FAMILIES, runs)
    rng = np.random.default_rng([seed, 31])
    recordings: list[Recording] = []
    offsets: list[float] = []
    labels: list[str] = []
    for index in range(runs):
        duration_s = float(rng.uniform(5.0, 9.0)) * 3600.0
        grid = np.arange(0.0, duration_s + 30.0, 30.0)
        spindle_load, axis_load, hydraulic_load, chip_load = (_duty_cycle(rng, grid) for _ in range(4))
        ambient = rng.uniform(18.0, 24.0) + 0.4 * np.sin(2 * np.pi * (grid / 86400.0 + rng.random()))
        sensors = {"spindle": _lag_from(grid, ambient + 8.0 * spindle_load, 1200.0),
                   "bed": _lag_from(grid, ambient + 2.0 * spindle_load + 1.5 * axis_load, 3 * 3600.0),
                   "front": _lag_from(grid, ambient + 12.0 * hydraulic_load, 2400.0),
                   "rear": _lag_from(grid, ambient + 6.0 * hydraulic_load + 2.0 * chip_load, 2400.0),
                   "ambient": ambient,
                   "coolant": _lag_from(grid, ambient + 1.0 * spindle_load, 2400.0)}
        truth = 3.0 * (sensors["spindle"] - 20.0) + 2.0 * (sensors["bed"] - 20.0)
        front = sensors[TRANSIENT_SENSOR]
        if name == "skin_core_days":
            truth = truth + TRANSIENT_UM_PER_K * (front - first_order_lag(grid, front, TRANSIENT_TAU_S))
        elif name == "pair_days":
            truth = truth + PAIR_REAR_UM_PER_K * (sensors["rear"] - 20.0) + PAIR_FRONT_UM_PER_K * (front - 20.0)
        wander = _ar1(rng, grid, 0.3, 0.95)
        recording, offset = _logged_day(rng, f"{name}_s{seed}_run{index + 1:02d}", grid, truth, wander, sensors,
                                        spindle_load, _slow_sampling(rng, duration_s))
        recordings.append(recording)
        offsets.append(offset)
        labels.append(f"{duration_s / 3600:.1f} h")
    if name == "skin_core_days":
        effect, parameters = "transient_gradient", {"tau_s": TRANSIENT_TAU_S, "coeff_um_per_K": TRANSIENT_UM_PER_K}
    elif name == "pair_days":
        effect, parameters = "temperature", {"rear": PAIR_REAR_UM_PER_K, "front": PAIR_FRONT_UM_PER_K}
    else:
        effect, parameters = None, {}
    return RunFamily(name, recordings, baseline_model(), FamilyTruth(effect, parameters, tuple(offsets),
                                                                      tuple(labels)))


# ---------------------------------------------------------------------- issue 42: light and heavy days
DUTY_MIX_FAMILIES = ("duty_mix_days", "null_duty_mix_days")
DUTY_MIX_SENSOR = "rear"
DUTY_MIX_UM_PER_K = 1.5
DUTY_MIX_LIGHT_RUNS = 10


def make_duty_mix_family(name: str, seed: int = 1, runs: int = 30) -> RunFamily:
    """``runs`` days of 8-12 h logged every 2 min, the first ``DUTY_MIX_LIGHT_RUNS`` light (the
    spindle at 10-25 % of the heavy days' load) and the rest heavy (deterministic per ``seed``; the two
    families share inputs and noise draws seed for seed). Baseline: ``baseline_model()``.

    - ``duty_mix_days``: a plain ``temperature(rear)`` term, 1.5 um/K from 20 C, left out. The rear
      structure warms with heavy cutting's chips and coolant: by several kelvin on a heavy day, next to
      nothing on a light one. Its sensor sits by a coolant line whose pump cycles it by up to 0.8 K
      (3.5 K on a light day, when the coolant idles warm), which
      the structure does not follow: on a light day the term then adds more of that than it explains,
      so the light days (already near the gauge's own wander) come out slightly worse while the heavy days come out
      much better. A share of runs that must improve refuses it; the runs' paired test admits it.
    - ``null_duty_mix_days``: the same days, nothing left out."""
    _check_family(name, DUTY_MIX_FAMILIES, runs)
    rng = np.random.default_rng([seed, 42])
    recordings: list[Recording] = []
    offsets: list[float] = []
    labels: list[str] = []
    for index in range(runs):
        light = index < DUTY_MIX_LIGHT_RUNS
        duration_s = float(rng.uniform(8.0, 12.0)) * 3600.0
        grid = np.arange(0.0, duration_s + 120.0, 120.0)
        spindle_load = _duty_cycle(rng, grid) * (float(rng.uniform(0.1, 0.25)) if light else 1.0)
        axis_load = _duty_cycle(rng, grid)
        # Heavy cutting's chips and coolant heat the rear structure; a light day makes next to none.
        chip_load = _duty_cycle(rng, grid) * (float(rng.uniform(0.0, 0.01)) if light else 1.0)
        mean_ambient = float(rng.uniform(14.0, 28.0))  # a month of days, winter to summer
        ambient = mean_ambient + 0.1 * np.sin(2 * np.pi * (grid / 86400.0 + rng.random()))  # a steady hall
        rear_structure = _lag_from(grid, ambient + 16.0 * chip_load, 3600.0)
        sensors = {"spindle": _lag_from(grid, ambient + 8.0 * spindle_load, 1200.0),
                   "bed": _lag_from(grid, ambient + 2.0 * spindle_load + 1.5 * axis_load, 3 * 3600.0),
                   "front": _lag_from(grid, ambient + 1.5 * axis_load, 2400.0),
                   # the coolant line's pump cycling, by the sensor only (more on a light day: it idles warm)
                   "rear": rear_structure + _lag_from(grid, (3.5 if light else 0.8) * _duty_cycle(rng, grid), 300.0)
                   + _ar1(rng, grid, 0.2, 0.99),
                   "ambient": ambient,
                   "coolant": _lag_from(grid, ambient + 1.0 * spindle_load, 2400.0)}
        truth = 3.0 * (sensors["spindle"] - 20.0) + 2.0 * (sensors["bed"] - 20.0)
        if name == "duty_mix_days":
            truth = truth + DUTY_MIX_UM_PER_K * (rear_structure - 20.0)
        recording, offset = _logged_day(rng, f"{name}_s{seed}_run{index + 1:02d}", grid, truth,
                                        _ar1(rng, grid, 0.5, 0.99), sensors, spindle_load)
        recordings.append(recording)
        offsets.append(offset)
        labels.append("light" if light else "heavy")
    effect, parameters = (("temperature", {"sensor_um_per_K": DUTY_MIX_UM_PER_K}) if name == "duty_mix_days"
                          else (None, {}))
    return RunFamily(name, recordings, baseline_model(), FamilyTruth(effect, parameters, tuple(offsets),
                                                                      tuple(labels)))


# ---------------------------------------------------------------------- issue 42: one sensor, two time constants
TWO_TAU_FAMILIES = ("two_tau_days", "null_two_tau_days")
TWO_TAU_SENSOR = "front"
TWO_TAU_FAST_S = 1800.0
TWO_TAU_SLOW_S = 3 * 3600.0
TWO_TAU_FAST_UM_PER_K = 3.0
TWO_TAU_SLOW_UM_PER_K = 3.0


def make_two_tau_family(name: str, seed: int = 1, runs: int = 30) -> RunFamily:
    """``runs`` days of 10-14 h logged every 4 min (deterministic per ``seed``; the two families share
    inputs and noise draws seed for seed). Baseline: ``baseline_model()``.

    - ``two_tau_days``: the column by the hydraulic unit bends twice over while the unit's heat crosses
      it, a thin skin that evens out in half an hour and a thick core that takes three:
      ``transient_gradient(front)`` at tau 0.5 h and again at tau 3 h, 3 um/K each, left out.
    - ``null_two_tau_days``: the same days, nothing left out."""
    _check_family(name, TWO_TAU_FAMILIES, runs)
    rng = np.random.default_rng([seed, 4242])
    recordings: list[Recording] = []
    offsets: list[float] = []
    labels: list[str] = []
    for index in range(runs):
        duration_s = float(rng.uniform(10.0, 14.0)) * 3600.0
        grid = np.arange(0.0, duration_s + 240.0, 240.0)
        spindle_load, axis_load, hydraulic_load = (_duty_cycle(rng, grid) for _ in range(3))
        ambient = rng.uniform(18.0, 24.0) + 0.4 * np.sin(2 * np.pi * (grid / 86400.0 + rng.random()))
        sensors = {"spindle": _lag_from(grid, ambient + 8.0 * spindle_load, 1200.0),
                   "bed": _lag_from(grid, ambient + 2.0 * spindle_load + 1.5 * axis_load, 3 * 3600.0),
                   "front": _lag_from(grid, ambient + 10.0 * hydraulic_load, 600.0),
                   "rear": _lag_from(grid, ambient + 4.0 * axis_load, 3600.0),
                   "ambient": ambient,
                   "coolant": _lag_from(grid, ambient + 1.0 * spindle_load, 2400.0)}
        truth = 3.0 * (sensors["spindle"] - 20.0) + 2.0 * (sensors["bed"] - 20.0)
        front = sensors[TWO_TAU_SENSOR]
        if name == "two_tau_days":
            truth = truth + TWO_TAU_FAST_UM_PER_K * (front - first_order_lag(grid, front, TWO_TAU_FAST_S)) \
                + TWO_TAU_SLOW_UM_PER_K * (front - first_order_lag(grid, front, TWO_TAU_SLOW_S))
        recording, offset = _logged_day(rng, f"{name}_s{seed}_run{index + 1:02d}", grid, truth,
                                        _ar1(rng, grid, 0.3, 0.95), sensors, spindle_load)
        recordings.append(recording)
        offsets.append(offset)
        labels.append(f"{duration_s / 3600:.1f} h")
    effect, parameters = (("transient_gradient", {"fast_tau_s": TWO_TAU_FAST_S, "slow_tau_s": TWO_TAU_SLOW_S,
                                                  "fast_um_per_K": TWO_TAU_FAST_UM_PER_K,
                                                  "slow_um_per_K": TWO_TAU_SLOW_UM_PER_K})
                          if name == "two_tau_days" else (None, {}))
    return RunFamily(name, recordings, baseline_model(), FamilyTruth(effect, parameters, tuple(offsets),
                                                                      tuple(labels)))


# ---------------------------------------------------------------------- issue 42: two true terms, shared drivers
CORRELATED_FAMILIES = ("correlated_lag_bed", "null_correlated_lag_bed")
CORRELATED_LAG_TAU_S = 2400.0
CORRELATED_LAG_UM_PER_K = 3.0
CORRELATED_BED_UM_PER_K = 1.2


def make_correlated_family(name: str, seed: int = 1, runs: int | None = None, *, coolant: bool = False) -> RunFamily:
    """Two or three days (``runs``; by default 2 or 3 per ``seed``) of 10-14 h logged every minute, as a
    user with a few days of data has them, with no model: the baseline is each run's own offset.

    - ``correlated_lag_bed``: the spindle structure follows its sensor through a lag of 2400 s at
      3 um/K, and the bed grows 1.2 um/K with its own temperature; the bed follows the hall's ambient
      and part of the spindle's heat, so the two true terms share drivers (and a hysteresis of the
      spindle or a lag of the ambient can mimic their sum).
    - ``null_correlated_lag_bed``: the same days and sensors, the gauge reads wander and noise only.

    The sensors are the spindle, the bed and the ambient (the workbook of the issue); ``coolant`` adds
    a coolant sensor that follows the ambient and an eighth of the spindle's heating, a third sensor
    that shares the bed's drivers (its noise draw shifts the draws that follow: other days)."""
    if name not in CORRELATED_FAMILIES:
        raise ValueError(f"unknown run family {name!r}; known: {', '.join(CORRELATED_FAMILIES)}")
    rng = np.random.default_rng([seed, 4243])
    count = int(rng.integers(2, 4)) if runs is None else runs
    if count < 2:
        raise ValueError("a family has at least 2 runs")
    recordings: list[Recording] = []
    offsets: list[float] = []
    labels: list[str] = []
    for index in range(count):
        duration_s = float(rng.uniform(10.0, 14.0)) * 3600.0
        grid = np.arange(0.0, duration_s + 60.0, 60.0)
        spindle_load, axis_load = _duty_cycle(rng, grid), _duty_cycle(rng, grid)
        # The hall warms through the day by 1-3 K and swings a little with the doors.
        ambient = rng.uniform(18.0, 23.0) + rng.uniform(1.0, 3.0) * np.sin(np.pi * grid / (2 * duration_s)) \
            + _lag_from(grid, _ar1(rng, grid, 0.4, 0.999), 1800.0)
        spindle = _lag_from(grid, ambient + 8.0 * spindle_load, 1200.0)
        sensors = {"spindle": spindle,
                   "bed": _lag_from(grid, ambient + 2.5 * spindle_load + 0.8 * axis_load, 2 * 3600.0),
                   "ambient": ambient}
        if coolant:
            sensors["coolant"] = _lag_from(grid, ambient + 1.0 * spindle_load, 2400.0)
        if name == "correlated_lag_bed":
            truth = CORRELATED_LAG_UM_PER_K * (first_order_lag(grid, spindle, CORRELATED_LAG_TAU_S) - 20.0) \
                + CORRELATED_BED_UM_PER_K * (sensors["bed"] - 20.0)
        else:
            truth = np.zeros_like(grid)
        recording, offset = _logged_day(rng, f"{name}_s{seed}_run{index + 1:02d}", grid, truth,
                                        _ar1(rng, grid, 0.3, 0.95), sensors, spindle_load)
        recordings.append(recording)
        offsets.append(offset)
        labels.append(f"{duration_s / 3600:.1f} h")
    effect, parameters = (("thermal_lag", {"tau_s": CORRELATED_LAG_TAU_S, "spindle_um_per_K": CORRELATED_LAG_UM_PER_K,
                                           "bed_um_per_K": CORRELATED_BED_UM_PER_K})
                          if name == "correlated_lag_bed" else (None, {}))
    return RunFamily(name, recordings, ThermalModel(AXIS, [], "<each run's own offset>"),
                     FamilyTruth(effect, parameters, tuple(offsets), tuple(labels)))


# ---------------------------------------------------------------------- issue 42: the measured month's shape
MONTH_FAMILIES = ("duty_month", "null_duty_month", "reversed_month")
MONTH_SENSORS = ("ambient", "coolant_wall", "spindle_rear", "spindle_front", "bed", "hydraulic")
MONTH_LEVELS = {"light": 0.15, "medium": 0.5, "heavy": 1.0}
MONTH_SLOW_TAU_S = 2.74 * 3600.0
MONTH_FAST_TAU_S = 0.5 * 3600.0


# reversed_month: the runs (the 7th to the 12th, as the held-back month's TM7-TM12) on which the
# spindle rear's heat moves the structure the other way.
MONTH_REVERSED_RUNS = range(6, 12)


def month_truth(reversed_run: bool = False) -> ThermalModel:
    """The terms ``duty_month`` hides: a gradient of the hall against the coolant-cooled wall, the
    spindle rear's transient at a slow and a fast time constant, and its plain temperature
    (``reversed_run``: the spindle rear's three of the other sign)."""
    rear = -1.0 if reversed_run else 1.0
    return ThermalModel(AXIS, [
        Term("thermal_gradient", {"sensors": ["ambient", "coolant_wall"], "coeff_um_per_K": -4.67}),
        Term("transient_gradient", {"sensor": "spindle_rear", "tau_s": MONTH_SLOW_TAU_S,
                                    "coeff_um_per_K": rear * 4.61}),
        Term("temperature", {"sensor": "spindle_rear", "t_ref_C": 20.0, "coeff_um_per_K": rear * 0.8}),
        Term("transient_gradient", {"sensor": "spindle_rear", "tau_s": MONTH_FAST_TAU_S,
                                    "coeff_um_per_K": rear * 2.5})],
        "<duty_month's truth>" if not reversed_run else "<reversed_month's truth on its reversed runs>")


def make_month_family(name: str, seed: int = 1, runs: int = 30) -> RunFamily:
    """A month of daily runs of 8-14 h logged every minute, light, medium and heavy spindle duty in
    turn (the shape of the measured month of issue 42, whose runs are held back from the project),
    with no model: the baseline is each run's own offset. A heavy day starts with two hours at full
    load (the spindle rear heats fast: its first half hour is where one time constant fails).

    - ``duty_month``: ``month_truth()``; the spindle's front sensor follows the same heat through
      another lag (a stand-in a search may name), the rear sensor carries a slow wander of its own.
      The gauge wanders by 3.5 um (r(1) near 1): the light days sit near 2-3 um whatever is named.
    - ``null_duty_month``: the same days and sensors, the gauge reads wander and noise only.
    - ``reversed_month``: ``duty_month``, except on the six runs of ``MONTH_REVERSED_RUNS``, where the
      spindle rear's terms change sign (the held-back month's TM7-TM12, on which the error falls while
      the rear keeps warming). Runs are named by date, ``2017-02-DD_TM<n>_<duty>``."""
    _check_family(name, MONTH_FAMILIES, runs)
    rng = np.random.default_rng([seed, 4244])
    truth_models = (month_truth(), month_truth(reversed_run=True))
    recordings: list[Recording] = []
    offsets: list[float] = []
    labels: list[str] = []
    for index in range(runs):
        kind = tuple(MONTH_LEVELS)[index % 3]
        duration_s = float(rng.uniform(8.0, 14.0)) * 3600.0
        grid = np.arange(0.0, duration_s + 60.0, 60.0)
        spindle_load = _duty_cycle(rng, grid) * MONTH_LEVELS[kind]
        if kind == "heavy":
            spindle_load[grid < 2 * 3600.0] = 1.0
        ambient = rng.uniform(15.0, 27.0) + rng.uniform(0.5, 2.5) * np.sin(np.pi * grid / (2 * duration_s)) \
            + _lag_from(grid, _ar1(rng, grid, 0.3, 0.999), 1800.0)
        rear = _lag_from(grid, ambient + 7.0 * spindle_load, 1500.0)
        sensors = {"ambient": ambient,
                   "coolant_wall": _lag_from(grid, ambient + 1.5 * spindle_load, 3000.0) + _ar1(rng, grid, 0.05, 0.99),
                   "spindle_rear": rear + _ar1(rng, grid, 0.1, 0.99),
                   "spindle_front": _lag_from(grid, ambient + 10.0 * spindle_load, 900.0),
                   "bed": _lag_from(grid, ambient + 2.0 * spindle_load, 3 * 3600.0),
                   "hydraulic": _lag_from(grid, ambient + 6.0 * _duty_cycle(rng, grid), 2400.0)}
        reversed_run = name == "reversed_month" and index in MONTH_REVERSED_RUNS
        if name != "null_duty_month":
            # The structure follows the rear's heat, not its sensor's own wander.
            structure = Recording("<truth>", grid, {f"temp_{k}_C": v for k, v in {**sensors, "spindle_rear": rear}.items()},
                                  name="truth")
            truth = truth_models[reversed_run].predict_um(structure)
        else:
            truth = np.zeros_like(grid)
        run_name = f"{name}_s{seed}_{index + 1:02d}_{kind}" if name != "reversed_month" \
            else f"2017-02-{index + 1:02d}_TM{index + 1}_{kind}"
        recording, offset = _logged_day(rng, run_name, grid, truth, _ar1(rng, grid, 3.5, 0.995), sensors, spindle_load)
        recordings.append(recording)
        offsets.append(offset)
        labels.append(f"{kind}, reversed" if reversed_run else kind)
    effect, parameters = ((None, {}) if name == "null_duty_month" else ("several", {"terms": len(truth_models[0].terms)}))
    return RunFamily(name, recordings, ThermalModel(AXIS, [], "<each run's own offset>"),
                     FamilyTruth(effect, parameters, tuple(offsets), tuple(labels)))


# ---------------------------------------------------------------------- issue 51: shapes, regimes, the room
SHAPE_FAMILIES = ("transient_as_pair", "regime_days", "room_acts", "null_shape_days")
SHAPE_SENSOR = "rear"
SHAPE_TAU_S = 900.0
SHAPE_TRANSIENT_UM_PER_K = 3.0
SHAPE_STATIC_UM_PER_K = 4.0
REGIME_UM_PER_K = 2.0
# The runs of the reversed regime: a third of the month, one stretch of dates (runs 11-20).
REGIME_RUNS = range(10, 20)
ROOM_TAU_S = 3 * 3600.0
ROOM_UM_PER_K = 2.5


def shape_truth(name: str, reversed_run: bool = False) -> ThermalModel:
    """The terms a shape family hides beside ``baseline_model()`` (none for the null)."""
    if name == "transient_as_pair":
        terms = [Term("transient_gradient", {"sensor": SHAPE_SENSOR, "tau_s": SHAPE_TAU_S,
                                             "coeff_um_per_K": SHAPE_TRANSIENT_UM_PER_K}),
                 Term("temperature", {"sensor": SHAPE_SENSOR, "t_ref_C": 20.0, "coeff_um_per_K": SHAPE_STATIC_UM_PER_K})]
    elif name == "regime_days":
        sign = -1.0 if reversed_run else 1.0
        terms = [Term("temperature", {"sensor": SHAPE_SENSOR, "t_ref_C": 20.0, "coeff_um_per_K": sign * REGIME_UM_PER_K})]
    elif name == "room_acts":
        terms = [Term("thermal_lag", {"sensor": "ambient", "t_ref_C": 20.0, "tau_s": ROOM_TAU_S,
                                      "coeff_um_per_K": ROOM_UM_PER_K})]
    else:
        terms = []
    return ThermalModel(AXIS, terms, f"<{name}'s truth>")


def make_shape_family(name: str, seed: int = 1, runs: int = 30) -> RunFamily:
    """A month of daily runs (one a day, named by date) of 8-12 h logged every 2 min, with the room
    swinging by several kelvin between day and night and with the doors (deterministic per ``seed``;
    the four families share inputs and noise draws seed for seed). Baseline: ``baseline_model()``.

    - ``transient_as_pair``: the rear structure bends while the axes' heat crosses it (a transient of
      the rear sensor at 0.5 h, 5 um/K) and grows a little with it (1 um/K): the shape a search names
      as the rear's temperature plus its own lag of opposite sign, unless it names shapes.
    - ``regime_days``: the structure grows 2 um/K with the rear temperature, except on the ten days
      of ``REGIME_RUNS`` (a fixture was mounted the other way round), where it shrinks by as much.
    - ``room_acts``: the room acts through the structure: a lag of the ambient at 3 h, 2.5 um/K.
    - ``null_shape_days``: the same days, nothing left out."""
    _check_family(name, SHAPE_FAMILIES, runs)
    rng = np.random.default_rng([seed, 51])
    recordings: list[Recording] = []
    offsets: list[float] = []
    labels: list[str] = []
    for index in range(runs):
        duration_s = float(rng.uniform(8.0, 12.0)) * 3600.0
        grid = np.arange(0.0, duration_s + 120.0, 120.0)
        spindle_load, axis_load = _duty_cycle(rng, grid), _duty_cycle(rng, grid)
        # The hall: the day's level, a warming through the shift, and the doors' swings.
        ambient = rng.uniform(16.0, 26.0) + rng.uniform(1.5, 4.0) * np.sin(np.pi * grid / (2 * duration_s)) \
            + _lag_from(grid, _ar1(rng, grid, 1.0, 0.999), 900.0)
        sensors = {"spindle": _lag_from(grid, ambient + 8.0 * spindle_load, 1200.0),
                   "bed": _lag_from(grid, ambient + 2.0 * spindle_load + 1.5 * axis_load, 3 * 3600.0),
                   "front": _lag_from(grid, ambient + 1.5 * spindle_load, 2400.0),
                   "rear": _lag_from(grid, ambient + 6.0 * axis_load, 900.0),
                   "ambient": ambient,
                   "coolant": _lag_from(grid, ambient + 1.0 * spindle_load, 2400.0)}
        truth = 3.0 * (sensors["spindle"] - 20.0) + 2.0 * (sensors["bed"] - 20.0)
        reversed_run = index in REGIME_RUNS
        structure = Recording("<truth>", grid, {f"temp_{k}_C": v for k, v in sensors.items()}, name="truth")
        truth = truth + shape_truth(name, reversed_run).predict_um(structure)
        day = f"2026-03-{index + 1:02d}" if index < 31 else f"day{index + 1:03d}"
        recording, offset = _logged_day(rng, f"{day}_{name}_s{seed}", grid, truth, _ar1(rng, grid, 0.3, 0.95),
                                        sensors, spindle_load)
        recordings.append(recording)
        offsets.append(offset)
        labels.append("reversed" if reversed_run and name == "regime_days" else "usual")
    effect = {"transient_as_pair": "transient_gradient", "regime_days": "temperature",
              "room_acts": "thermal_lag"}.get(name)
    return RunFamily(name, recordings, baseline_model(), FamilyTruth(effect, {}, tuple(offsets), tuple(labels)))
