"""The recordings a heat fit reads: time, temperatures and the machine's inputs, on a uniform grid.

A recording's columns are the project's (``t_s``, ``temp_<name>_C``, ``spindle_rpm``, ``pos_<axis>_mm``;
``err_``/``sim_`` are read past) plus any input the user names (``coolant``: a 0/1 switch). The axes'
positions become one input, the path speed in m/min. Temperatures are slow beside any sampling a
logger uses: the fit works on a grid of ``step_s`` (readings interpolated there, inputs averaged over
each step), which lets every lag run as one linear filter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nckemu.errors import NckConfigError
from nckemu.heat_response import PATH, SPINDLE
from nckemu.thermal.recordings.recording import find_recordings, is_parquet

DEFAULT_STEP_S = 60.0


@dataclass
class HeatRun:
    """One run: its name, a uniform time grid, the temperatures and the inputs on it."""

    name: str
    t_s: np.ndarray
    sensors_C: dict[str, np.ndarray]
    inputs: dict[str, np.ndarray] = field(default_factory=dict)
    # The gauge's err_<axis>_um columns where recorded (NaN where it was not read): what `machine compare
    # --model` judges the twin's temperatures by.
    errors_um: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if len(self.t_s) > 1 else 0.0

    def head(self, share: float) -> HeatRun:
        """The first ``share`` of the run's samples."""
        cut = int(round(len(self.t_s) * share))
        return HeatRun(self.name, self.t_s[:cut], {k: v[:cut] for k, v in self.sensors_C.items()},
                       {k: v[:cut] for k, v in self.inputs.items()}, {k: v[:cut] for k, v in self.errors_um.items()})


def _columns(path: Path) -> dict[str, np.ndarray]:
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    source = str(path)
    try:
        table = pq.read_table(path) if is_parquet(path) else pacsv.read_csv(path)
    except (pa.ArrowInvalid, OSError) as exc:
        raise NckConfigError(f"cannot read it as CSV or Parquet: {str(exc).splitlines()[0]}", path=source) from None
    columns = {}
    for name in table.column_names:
        column = table.column(name)
        if not (pa.types.is_integer(column.type) or pa.types.is_floating(column.type) or pa.types.is_null(column.type)):
            raise NckConfigError(f"not a number column ({column.type})", path=source, field=name)
        columns[name.strip()] = column.to_numpy(zero_copy_only=False).astype(float)
    return columns


def _path_speed_m_min(t_s: np.ndarray, positions: list[np.ndarray]) -> np.ndarray:
    """The path speed between samples (m/min), held over each step's end sample."""
    if not positions or len(t_s) < 2:
        return np.zeros(len(t_s))
    step = np.diff(np.stack(positions), axis=1)
    speed_mm_s = np.sqrt(np.sum(step ** 2, axis=0)) / np.maximum(np.diff(t_s), 1e-9)
    return np.concatenate(([0.0], speed_mm_s * 60.0 / 1000.0))


def to_grid(name: str, t_s: np.ndarray, sensors: dict[str, np.ndarray], inputs: dict[str, np.ndarray],
            step_s: float, errors: dict[str, np.ndarray] | None = None) -> HeatRun:
    """The run on a uniform grid of ``step_s`` (as recorded when it is sampled that coarsely already)."""
    errors = errors or {}
    if len(t_s) < 3 or float(np.median(np.diff(t_s))) * 1.5 >= step_s:
        return HeatRun(name, t_s, sensors, inputs, errors)
    bins = np.floor((t_s - t_s[0]) / step_s).astype(np.int64)
    count = int(bins[-1]) + 1
    grid = t_s[0] + step_s * (np.arange(count) + 1.0)   # each step's end: what the inputs held up to
    counts = np.maximum(np.bincount(bins, minlength=count), 1)

    def mean(values: np.ndarray) -> np.ndarray:
        return np.bincount(bins, weights=values, minlength=count) / counts

    def gauge(values: np.ndarray) -> np.ndarray:   # the readings in each step, NaN where none
        read = np.isfinite(values)
        sums = np.bincount(bins[read], weights=values[read], minlength=count)
        counts = np.bincount(bins[read], minlength=count)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)

    keep = np.bincount(bins, minlength=count) > 0
    return HeatRun(name, grid[keep], {k: np.interp(grid, t_s, v)[keep] for k, v in sensors.items()},
                   {k: mean(v)[keep] for k, v in inputs.items()}, {k: gauge(v)[keep] for k, v in errors.items()})


def load_heat_runs(specs: list[str], input_names: list[str], step_s: float = DEFAULT_STEP_S) -> list[HeatRun]:
    """Each recording (files, folders, globs) as a run with the inputs ``input_names`` (``spindle_rpm``;
    ``axes`` or ``path``: the path speed from the pos_ columns; any other column by its name)."""
    runs = []
    for path in find_recordings(specs):
        columns = _columns(path)
        source = str(path)
        if "t_s" not in columns:
            raise NckConfigError("no t_s column", path=source, field="t_s")
        t_s = columns["t_s"]
        if len(t_s) < 3 or not np.all(np.diff(t_s) > 0):
            raise NckConfigError("t_s must rise from row to row (and a run needs 3 rows)", path=source, field="t_s")
        sensors = {name[5:-2]: values for name, values in columns.items()
                   if name.startswith("temp_") and name.endswith("_C")}
        if not sensors:
            raise NckConfigError("no temp_<name>_C column: nothing to fit", path=source)
        for name, values in sensors.items():
            if not np.all(np.isfinite(values)):
                raise NckConfigError("empty or non-finite temperature cells: a heat fit needs every reading",
                                     path=source, field=f"temp_{name}_C")
        inputs: dict[str, np.ndarray] = {}
        for name in input_names:
            if name in ("axes", "path", PATH):
                positions = [v for k, v in columns.items() if k.startswith("pos_") and k.endswith("_mm")]
                if not positions:
                    raise NckConfigError("--inputs axes: no pos_<axis>_mm column", path=source)
                inputs[PATH] = _path_speed_m_min(t_s, positions)
                continue
            if name not in columns:
                raise NckConfigError(f"--inputs {name}: no such column (it has: {', '.join(columns)})", path=source)
            values = columns[name]
            if not np.all(np.isfinite(values)):
                raise NckConfigError("empty or non-finite cells in an input", path=source, field=name)
            inputs[name] = values
        errors = {name[4:-3]: values for name, values in columns.items()
                  if name.startswith("err_") and name.endswith("_um")}
        runs.append(to_grid(path.stem, t_s, sensors, inputs, step_s, errors))
    names = [run.name for run in runs]
    if len(set(names)) != len(names):
        raise NckConfigError(f"two runs named {sorted({n for n in names if names.count(n) > 1})[0]!r}: "
                             f"runs need unique file names")
    common = set.intersection(*(set(run.sensors_C) for run in runs))
    if not common:
        raise NckConfigError("no temperature the runs share: a heat fit needs the same sensors in each run")
    for run in runs:
        run.sensors_C = {k: v for k, v in run.sensors_C.items() if k in common}
    return runs


def switch_inputs(runs: list[HeatRun]) -> list[str]:
    """The inputs other than the spindle and the path speed: switches (coolant) and other signals."""
    return sorted({k for run in runs for k in run.inputs if k not in (SPINDLE, PATH)})


def hours(seconds: float) -> str:
    return f"{seconds / 3600:.2f} h" if seconds >= 3600 or not math.isfinite(seconds) else f"{seconds / 60:.0f} min"
