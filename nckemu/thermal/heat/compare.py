"""The twin against a recording: the recording's own inputs replayed through a machine's heat responses
(nckemu/heat_response.simulate, the twin's math), and per sensor where the two part ways."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nckemu.heat_response import SPINDLE, HeatTerm, simulate
from nckemu.thermal import stats
from nckemu.thermal.discovery import explain
from nckemu.thermal.model.terms import ThermalModel
from nckemu.thermal.recordings.recording import Recording

from .table import HeatRun
from .words import _phase

# Where the twin and the recording differ by more than this, they part ways (K).
PART_K = 0.5


@dataclass
class SensorComparison:
    sensor: str
    run: str
    rms_K: float
    max_K: float
    responds: bool                      # the machine file gives it a response (else: read as recorded)
    windows: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, object]:
        return {"sensor": self.sensor, "run": self.run, "rms_K": round(self.rms_K, 4), "max_K": round(self.max_K, 4),
                "responds": self.responds, "windows": self.windows}


@dataclass
class Comparison:
    rows: list[SensorComparison]
    simulated: dict[str, dict[str, np.ndarray]]    # run -> sensor -> the twin's temperature


def compare(runs: Sequence[HeatRun], base_C: Mapping[str, float],
            responses: Mapping[str, Sequence[HeatTerm]]) -> Comparison:
    rows, simulated = [], {}
    for run in runs:
        twin = simulate(run.t_s, run.inputs, base_C, responses, run.sensors_C)
        # Each run starts where its recording starts: the twin's offsets are those of the fitted run.
        simulated[run.name] = twin
        for sensor in sorted(run.sensors_C):
            if sensor not in responses:
                continue
            difference = twin[sensor] - run.sensors_C[sensor]
            row = SensorComparison(sensor, run.name, stats.rms(difference), float(np.max(np.abs(difference))), True)
            for start_s, end_s in explain.structured_windows(run.t_s, difference, limit=2):
                inside = (run.t_s >= start_s) & (run.t_s <= end_s)
                mean_K = float(np.mean(difference[inside]))
                if abs(mean_K) < PART_K or inside.sum() < 2:
                    continue
                t0 = float(run.t_s[0])
                row.windows.append(f"from {(start_s - t0) / 3600:.2f} h to {(end_s - t0) / 3600:.2f} h the twin reads "
                                   f"{mean_K:+.2f} K against the recording ({_phase(run, sensor, inside)})")
            rows.append(row)
    return Comparison(rows, simulated)


# Where the error the model gives from the twin's temperatures and from the recorded ones differ by more
# than this, the twin's heat costs the error there (µm).
PART_UM = 1.0


def _model_error(model: ThermalModel, run: HeatRun, sensors_C: Mapping[str, np.ndarray]) -> np.ndarray:
    recording = Recording(run.name, run.t_s, {f"temp_{name}_C": values for name, values in sensors_C.items()},
                          spindle_rpm=run.inputs.get(SPINDLE))
    return model.predict_um(recording)


def error_lines(runs: Sequence[HeatRun], comparison: Comparison, model: ThermalModel) -> list[str]:
    """The recorded error against the error model (a discovered one) fed the recorded temperatures and
    fed the twin's: what the twin's heat costs in µm, and where. Each run keeps its own offset (the
    model's offset is no part of the heat)."""
    axis = model.axis
    lines = []
    for run in runs:
        measured = run.errors_um.get(axis)
        if measured is None or not np.isfinite(measured).any():
            lines.append(f"err_{axis}_um: not in {run.name}; the model's error from the twin is not judged there")
            continue
        read = np.isfinite(measured)
        from_recorded = _model_error(model, run, run.sensors_C)
        from_twin = _model_error(model, run, comparison.simulated[run.name])

        def rms_within(predicted: np.ndarray, read: np.ndarray = read, measured: np.ndarray = measured) -> float:
            residual = measured[read] - predicted[read]
            return stats.rms(residual - np.mean(residual))

        where = f" in {run.name}" if len(runs) > 1 else ""
        lines.append(f"err_{axis}_um{where} through {model.source}: from the recorded temperatures RMS "
                     f"{rms_within(from_recorded):.2f} um, from the twin's {rms_within(from_twin):.2f} um")
        difference = from_twin - from_recorded
        t0 = float(run.t_s[0])
        for start_s, end_s in explain.structured_windows(run.t_s, difference, limit=2):
            inside = (run.t_s >= start_s) & (run.t_s <= end_s)
            mean_um = float(np.mean(difference[inside]))
            if abs(mean_um) >= PART_UM and inside.sum() >= 2:
                lines.append(f"  from {(start_s - t0) / 3600:.2f} h to {(end_s - t0) / 3600:.2f} h the twin's heat "
                             f"gives the error {mean_um:+.2f} um beside what the recorded temperatures give")
    return lines


def comparison_lines(comparison: Comparison) -> list[str]:
    lines = []
    for row in comparison.rows:
        where = f" in {row.run}" if len({r.run for r in comparison.rows}) > 1 else ""
        head = f"{row.sensor}{where}: twin against recording RMS {row.rms_K:.3f} K, at most {row.max_K:.2f} K"
        lines.append(head + ("" if row.windows else f"; they never part by {PART_K:g} K over a window"))
        lines += [f"  {window}" for window in row.windows]
    return lines


def write_figure(path: str | Path, runs: Sequence[HeatRun], comparison: Comparison) -> None:
    """Recorded against simulated, one panel per sensor with a response, the windows where they part shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run = runs[0]
    rows = [row for row in comparison.rows if row.run == run.name]
    count = max(len(rows), 1)
    figure, axes = plt.subplots(count, 1, figsize=(10, 2.2 * count), sharex=True, squeeze=False)
    hours = (run.t_s - run.t_s[0]) / 3600.0
    twin = comparison.simulated[run.name]
    for panel, row in zip(axes[:, 0], rows, strict=False):
        difference = twin[row.sensor] - run.sensors_C[row.sensor]
        panel.plot(hours, run.sensors_C[row.sensor], label="recorded", color="black", linewidth=1)
        panel.plot(hours, twin[row.sensor], label="twin", color="tab:red", linewidth=1)
        for start_s, end_s in explain.structured_windows(run.t_s, difference, limit=2):
            inside = (run.t_s >= start_s) & (run.t_s <= end_s)
            if abs(float(np.mean(difference[inside]))) >= PART_K:
                panel.axvspan((start_s - run.t_s[0]) / 3600, (end_s - run.t_s[0]) / 3600, color="tab:orange", alpha=0.2)
        panel.set_ylabel(f"{row.sensor} (C)")
        panel.legend(loc="upper right", fontsize=7)
    axes[-1, 0].set_xlabel(f"hours of {run.name}")
    figure.tight_layout()
    figure.savefig(path, dpi=60, format="png")
    plt.close(figure)
