"""A heat fit in words and as a machine file section.

Per sensor: the named terms with their figures, the held-out RMS before and after, and where the
response still fails: the window of time where the held-out residual is largest, what the machine was
doing there (heating, cooling, a speed step) and what the residual follows there, in discovery's words
(discovery/explain.py).
"""

from __future__ import annotations

import numpy as np

from nckemu.heat_response import SPINDLE, HeatTerm
from nckemu.thermal.discovery import explain
from nckemu.thermal.recordings.recording import Recording

from .fit import HeatFit, SensorHeat
from .judge import Judge
from .table import HeatRun

# A sensor whose held-out RMS stays above this is said to still fail (K).
STILL_FAILS_K = 1.0
SPEED_STEP_RPM = 100.0


def term_words(term: HeatTerm) -> str:
    return term.words()


def sensor_lines(result: SensorHeat) -> list[str]:
    if not result.terms and result.left:
        return [f"{result.sensor}: {result.left} (range {result.range_K:.2f} K)"]
    head = (f"{result.sensor}: held-out {result.heldout_before_K:.3f} -> {result.heldout_after_K:.3f} K "
            f"(range {result.range_K:.2f} K, {result.improvement:.0%} better)")
    if result.terms:
        head += ": " + "; ".join(f"{term_words(n.term)} ({n.share:.0%})" for n in result.terms)
    else:
        head += ": nothing named"
    lines = [head]
    lines += [f"  withdrawn: {line}" for line in result.withdrawn]
    if result.closest:
        lines.append(f"  closest: {result.closest}")
    if result.left:
        lines.append(f"  still fails: {result.left}")
    return lines


def fit_lines(fit: HeatFit) -> list[str]:
    lines = [f"heat fit over {', '.join(fit.runs)}: {fit.judged_on}"]
    if fit.reference:
        lines.append(f"the room: {', '.join(fit.reference)} (read as recorded; ambient terms follow it)")
    for result in fit.sensors:
        lines += sensor_lines(result)
    fitted = [s.heldout_after_K for s in fit.sensors if s.terms]
    if fitted:
        hottest = max((s for s in fit.sensors if s.terms), key=lambda s: s.range_K)
        lines.append(f"median over {len(fitted)} fitted sensors: held-out {float(np.median(fitted)):.3f} K; "
                     f"the hottest ({hottest.sensor}, range {hottest.range_K:.1f} K): {hottest.heldout_after_K:.3f} K")
    return lines


def _phase(run: HeatRun, sensor: str, inside: np.ndarray) -> str:
    """What the machine did in the window: the spindle, its steps, whether the sensor heated or cooled."""
    parts = []
    t_h = (run.t_s[inside] - run.t_s[0]) / 3600.0
    values = run.sensors_C[sensor][inside]
    change = float(values[-1] - values[0])
    parts.append("heating" if change > 0.2 else "cooling" if change < -0.2 else "steady")
    rpm = run.inputs.get(SPINDLE)
    if rpm is not None:
        window = rpm[inside]
        steps = np.flatnonzero(np.abs(np.diff(window)) > SPEED_STEP_RPM)
        if len(steps):
            k = end = int(steps[0])
            while end + 1 in steps:   # a step the time grid averaged over two samples
                end += 1
            before, after = float(window[k]), float(window[end + 1])
            what = "the spindle stops" if after < 1 else "the spindle starts" if before < 1 else "a speed step"
            parts.append(f"{what} from {before:.0f} to {after:.0f} rpm at {t_h[k + 1]:.2f} h")
        else:
            parts.append(f"spindle at {float(np.mean(window)):.0f} rpm")
    return f"{sensor} {parts[0]} ({change:+.1f} K), " + ", ".join(parts[1:])


def explain_left(result: SensorHeat, runs: list[HeatRun], judge: Judge) -> str:
    """Where the held-out residual of a sensor that still fails is largest, and what it follows there."""
    if result.heldout_after_K < STILL_FAILS_K or not len(result.heldout_residual_K):
        return ""
    residual = result.heldout_residual_K
    if judge.per_run:
        worst = int(np.argmax([np.mean(residual[judge.groups == g] ** 2) for g in range(len(runs))]))
        mine = judge.groups == worst
    else:
        worst, mine = 0, ~judge.train
    run = runs[worst]
    offset = int(np.flatnonzero(judge.groups == worst)[0])
    rows = np.flatnonzero(mine) - offset
    t_s, r = run.t_s[rows], residual[mine]
    windows = explain.structured_windows(t_s, r, limit=1)
    start_s, end_s = windows[0] if windows else (float(t_s[0]), float(t_s[-1]))
    inside = np.zeros(len(run.t_s), dtype=bool)
    inside[rows] = (t_s >= start_s) & (t_s <= end_s)
    if inside.sum() < 2:
        return ""
    recording = Recording(run.name, run.t_s, {f"temp_{k}_C": v for k, v in run.sensors_C.items()},
                          spindle_rpm=run.inputs.get(SPINDLE))
    at = inside[rows]
    follows = explain.follows(recording, t_s[explain.widened(at)], r[explain.widened(at)])
    where = "" if len(runs) == 1 else f"in {run.name} "
    t0 = float(run.t_s[0])
    words = (f"largest {where}from {(start_s - t0) / 3600:.2f} h to {(end_s - t0) / 3600:.2f} h (mean residual "
             f"{float(np.mean(r[at])):+.2f} K; {_phase(run, result.sensor, inside)})")
    return f"{words}; {follows}" if follows else words


def machine_section(fit: HeatFit, source: str) -> str:
    """The fitted sensors as ``[[sensor]]`` tables with their ``[[sensor.response]]`` terms."""
    lines = [f"# Heat fitted by `nckemu machine fit` from {source}: {fit.judged_on}.",
             "# Each sensor reads temperature_C plus its terms (docs/heat.md)."]
    for result in fit.sensors:
        lines += ["", "[[sensor]]", f'name = "{result.sensor}"', f"temperature_C = {result.base_C:.4f}"]
        if result.terms:
            lines.append(f"# held-out RMS {result.heldout_before_K:.3f} -> {result.heldout_after_K:.3f} K")
        else:   # no heat of its own: not the older keys' assumed defaults either
            lines.append(f"# {result.left or 'no term passed on held-out data'}")
            lines += ["heat_spindle_K_per_krpm = 0.0", "heat_axes_K_per_m_min = 0.0"]
        for named in result.terms:
            lines.append("[[sensor.response]]")
            for key, value in named.term.to_table().items():
                lines.append(f'{key} = "{value}"' if isinstance(value, str) else f"{key} = {value!r}")
    return "\n".join(lines) + "\n"
