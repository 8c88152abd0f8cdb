"""One long recording cut into runs: at spindle-speed blocks and at gaps in time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from nckemu.errors import NckConfigError
from nckemu.thermal.recordings.recording import Recording, load_recording, split_runs


def _schedule(speeds_rpm: list[float], rows_per_step: int = 10, dt_s: float = 60.0) -> Recording:
    rpm = np.repeat(np.asarray(speeds_rpm, dtype=float), rows_per_step)
    t = np.arange(len(rpm)) * dt_s
    return Recording("/data/day.csv", t, {"temp_a_C": 20 + rpm / 1000}, rpm, {}, {"Z": rpm / 100})


def test_a_block_is_a_start_of_the_spindle_with_the_standstill_after_it() -> None:
    recording = _schedule([0, 1250, 0, 2500, 0, 500, 1500, 4500, 0])
    runs = split_runs(recording)
    assert [r.name for r in runs] == ["day_block01_1250rpm", "day_block02_2500rpm", "day_block03_500-4500rpm"]
    assert [len(r.t_s) for r in runs] == [30, 20, 40]  # the lead-in at rest belongs to the first block
    assert np.array_equal(np.concatenate([r.t_s for r in runs]), recording.t_s)
    assert all(r.source == recording.source for r in runs)
    assert np.array_equal(runs[1].spindle_rpm, np.repeat([2500.0, 0.0], 10))


def test_gaps_longer_than_the_threshold_cut_runs() -> None:
    t = np.concatenate([np.arange(10.0) * 60, 5000 + np.arange(10.0) * 60, 20000 + np.arange(2.0) * 60])
    recording = Recording("<logger>", t, {"temp_a_C": np.full(22, 20.0)}, None, {}, {"Z": np.zeros(22)})
    runs = split_runs(recording, max_gap_s=3600)
    assert [(r.name, len(r.t_s)) for r in runs] == [("logger_part1", 10), ("logger_part2", 10)]  # 2 rows: no run
    assert split_runs(recording, max_gap_s=None) == [recording]
    assert [len(r.t_s) for r in split_runs(recording, max_gap_s=600)] == [10, 10]


def test_speed_blocks_and_gaps_together() -> None:
    recording = _schedule([0, 3000, 0, 3000, 0])
    recording.t_s[35:] += 7200.0  # the logger was off in the second block's running part
    names = [r.name for r in split_runs(recording)]
    assert names == ["day_block01_3000rpm", "day_block02_3000rpm_part1", "day_block02_3000rpm_part2"]
    assert [r.name for r in split_runs(recording, speed_blocks=False)] == ["day_part1", "day_part2"]


def test_nothing_to_cut_and_no_speed() -> None:
    steady = _schedule([2000, 2000])
    assert split_runs(steady) == [steady]
    without_speed = Recording("<x>", np.arange(5.0), {}, None, {}, {"Z": np.zeros(5)})
    assert split_runs(without_speed) == [without_speed]
    with pytest.raises(NckConfigError, match="field 'spindle_rpm': cannot cut at speed blocks"):
        split_runs(without_speed, speed_blocks=True)


def test_fl_thermal_speed_blocks(shared_dir: Path) -> None:
    recording = load_recording(shared_dir / "data" / "fl_thermal" / "recording.csv")
    runs = split_runs(recording)
    assert [r.name.removeprefix("recording_") for r in runs] == [
            "block01_1250rpm", "block02_2500rpm", "block03_3750rpm", "block04_5000rpm", "block05_3500rpm",
            "block06_500-4500rpm"]
    assert [round(r.duration_s / 3600, 1) for r in runs] == [8.1, 8.0, 8.0, 8.0, 8.0, 6.2]
    assert sum(len(r.t_s) for r in runs) == len(recording.t_s)
