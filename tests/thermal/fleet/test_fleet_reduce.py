"""Stage 1 of fleet discovery without a cluster: window means, the per-file task, what is up to date."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.thermal.fleet.discover import MachineFolder, scan_root
from nckemu.thermal.fleet.reduce import ReduceTask, plan, reduce_file, reduced_root, window_means
from nckemu.thermal.recordings.recording import Recording, load_recording, write_recording
from nckemu.thermal.synthetic.scenarios import make_scenario


def _recording(t_s: np.ndarray, rng: np.random.Generator, gauge_missing: np.ndarray) -> Recording:
    err = rng.normal(0.0, 1.0, len(t_s))
    err[gauge_missing] = np.nan
    return Recording(source="test", t_s=t_s, temperatures_C={"temp_bed_C": 20.0 + rng.normal(0.0, 0.1, len(t_s))},
                     spindle_rpm=rng.uniform(0, 8000, len(t_s)), positions_mm={"Z": rng.uniform(-500, 0, len(t_s))},
                     errors_um={"Z": err})


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 400), st.floats(0.5, 5.0), st.floats(0.0, 1000.0), st.sampled_from([10.0, 60.0, 90.0]),
       st.integers(0, 2**32 - 1))
def test_window_means_are_the_mean_of_each_window(rows: int, dt_s: float, start_s: float, step_s: float,
                                                 seed: int) -> None:
    rng = np.random.default_rng(seed)
    t_s = start_s + np.cumsum(rng.uniform(0.2, 2.0, rows) * dt_s)  # uneven, with gaps
    recording = _recording(t_s, rng, rng.random(rows) < 0.3)
    reduced = window_means(recording, step_s)
    windows = np.floor(t_s / step_s)
    expected_t = (np.unique(windows) + 0.5) * step_s
    assert np.array_equal(reduced.t_s, expected_t)  # window centres, aligned to multiples of step_s
    for row, window in enumerate(np.unique(windows)):
        inside = windows == window
        assert reduced.temperatures_C["temp_bed_C"][row] == pytest.approx(recording.temperatures_C["temp_bed_C"][inside].mean())
        gauge = recording.errors_um["Z"][inside]
        if np.isfinite(gauge).any():
            assert reduced.errors_um["Z"][row] == pytest.approx(np.nanmean(gauge))
        else:
            assert np.isnan(reduced.errors_um["Z"][row])


def test_a_day_reduces_to_a_file_that_loads_and_is_not_made_twice(tmp_path: Path) -> None:
    made = make_scenario("thermal_lag", seed=3, duration_h=6.0, dt_s=5.0)
    source = tmp_path / "m1" / "day001.csv"
    source.parent.mkdir()
    write_recording(source, made.recording)
    tasks = plan([MachineFolder("m1", (str(source),))], tmp_path, 60.0)
    assert tasks == [ReduceTask("m1", str(source), str(reduced_root(tmp_path, 60.0) / "m1" / "day001.parquet"))]
    assert not tasks[0].up_to_date()
    result = reduce_file(tasks[0], 60.0)
    assert "error" not in result and result["rows_in"] == 6 * 720 and result["rows_out"] == 6 * 60
    reduced = load_recording(tasks[0].target)
    assert len(reduced.t_s) == 360 and reduced.t_s[0] == 30.0
    assert tasks[0].up_to_date()
    later = time.time() + 5
    os.utime(source, (later, later))  # the day was written again: reduce again
    assert not tasks[0].up_to_date()
    assert [p.name for p in Path(tasks[0].target).parent.iterdir()] == ["day001.parquet"]  # no partial file


def test_a_damaged_day_is_its_own_error_and_leaves_no_file(tmp_path: Path) -> None:
    source = tmp_path / "m1" / "day002.csv"
    source.parent.mkdir()
    source.write_text("t_s,temp_bed_C,err_Z_um\n0,20.0,1.0\n1,twenty,1.0\n", encoding="utf-8")
    task = plan([MachineFolder("m1", (str(source),))], tmp_path, 60.0)[0]
    result = reduce_file(task, 60.0)
    assert "day002.csv" in result["error"] and "line 3" in result["error"]
    assert not Path(task.target).exists()
    assert not Path(task.target).parent.exists() or not list(Path(task.target).parent.iterdir())


def test_the_reduced_tree_is_not_a_machine(tmp_path: Path) -> None:
    for name in ("m1", "_60s"):
        (tmp_path / name).mkdir()
        write_recording(tmp_path / name / "day001.csv", make_scenario("thermal_lag", duration_h=2.0).recording)
    assert [machine.name for machine in scan_root(tmp_path)] == ["m1"]
