"""Stage 1 of fleet discovery (docs/fleet.md): each machine-day file reduced to window means.

A logger closes one file per machine and day, sampled at 1 Hz or so; thermal time constants are
minutes to hours. One task per file reads it, bridges the temperature glitches as discovery does
(``readings.bridge_glitches``) and writes the means over windows of ``step_s`` (60 s by default) to
``ROOT/_60s/<machine>/<file stem>.parquet``; discovery (stage 2) then reads 1/60 of the data. Windows are
aligned to multiples of ``step_s`` from t = 0 (each day's file reduces alone, and the days still join),
and a row stands at its window's centre. A window without a gauge reading has an empty gauge cell.

An output newer than its input is not made again; outputs are written to a temporary name and renamed,
so a task killed midway leaves nothing a later run would take as done.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

REDUCED_PREFIX = "_"  # a folder under ROOT starting with it holds reduced data, not a machine


def reduced_root(root: str | Path, step_s: float) -> Path:
    return Path(root) / f"{REDUCED_PREFIX}{step_s:g}s"


@dataclass(frozen=True)
class ReduceTask:
    machine: str
    source: str
    target: str

    def up_to_date(self) -> bool:
        try:
            return os.stat(self.target).st_mtime >= os.stat(self.source).st_mtime
        except OSError:
            return False


def window_means(recording: Any, step_s: float) -> Any:
    """Every column's mean over windows of ``step_s`` aligned to multiples of it; rows at the window
    centres; empty (NaN) gauge cells where a window has no reading."""
    t = recording.t_s
    if len(t) == 0:
        return recording
    bins = np.floor(t / step_s).astype(np.int64)
    first = int(bins[0])
    index = bins - first
    count = int(index[-1]) + 1
    used = np.bincount(index, minlength=count) > 0

    def mean(values: np.ndarray) -> np.ndarray:
        finite = np.isfinite(values)
        sums = np.bincount(index[finite], weights=values[finite], minlength=count)
        counts = np.bincount(index[finite], minlength=count)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)[used]

    grid = ((np.arange(count) + first + 0.5) * step_s)[used]
    return replace(recording, t_s=grid, temperatures_C={k: mean(v) for k, v in recording.temperatures_C.items()},
                   spindle_rpm=None if recording.spindle_rpm is None else mean(recording.spindle_rpm),
                   positions_mm={k: mean(v) for k, v in recording.positions_mm.items()},
                   errors_um={k: mean(v) for k, v in recording.errors_um.items()},
                   simulated_um={k: mean(v) for k, v in recording.simulated_um.items()})


def reduce_file(task: ReduceTask, step_s: float) -> dict[str, Any]:
    """The Dask task: read, bridge glitches, reduce, write atomically. A bad file is its own error."""
    from nckemu.errors import NckError
    from nckemu.thermal.discovery.readings import bridge_glitches
    from nckemu.thermal.discovery.settings import Settings
    from nckemu.thermal.recordings.recording import load_recording, write_recording

    result: dict[str, Any] = {"machine": task.machine, "source": task.source, "target": task.target}
    try:
        recording = load_recording(task.source)
        repaired, notes = bridge_glitches(recording, Settings())
        reduced = window_means(replace(recording, temperatures_C=repaired), step_s)
        target = Path(task.target)
        target.parent.mkdir(parents=True, exist_ok=True)
        temporary = target.with_name(f".{target.name}.{os.getpid()}.partial.parquet")
        write_recording(temporary, reduced)
        os.replace(temporary, target)
    except NckError as exc:
        result["error"] = str(exc)
        return result
    except Exception as exc:  # noqa: BLE001 - one file's failure is its own, never the fleet's
        result["error"] = f"{task.source}: not reduced: {exc.__class__.__name__}: {exc}"
        return result
    result.update(rows_in=len(recording.t_s), rows_out=len(reduced.t_s), glitches=notes)
    return result


def plan(machines: list[Any], root: str | Path, step_s: float) -> list[ReduceTask]:
    """One task per run file of every machine folder, aimed at the reduced tree."""
    reduced = reduced_root(root, step_s)
    return [ReduceTask(machine.name, run, str(reduced / machine.name / f"{Path(run).stem}.parquet"))
            for machine in machines for run in machine.runs]
