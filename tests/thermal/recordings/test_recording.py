"""Recordings from the field: CSV and Parquet with the same checks, irregular time, many runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from nckemu.errors import NckConfigError
from nckemu.thermal.recordings.recording import (
    Recording,
    find_recordings,
    load_recording,
    load_runs,
    write_recording,
)


def _recording(rows: int = 20, seed: int = 0, axes: tuple[str, ...] = ("Z",), source: str = "<run>") -> Recording:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(5.0, 120.0, rows))  # irregular sampling
    t[rows // 2:] += 7200.0                         # and a two-hour gap
    errors = {axis: rng.normal(0.0, 1.0, rows) for axis in axes}
    for values in errors.values():
        values[::3] = np.nan
    return Recording(source, t, {"temp_spindle_C": 20 + rng.random(rows), "temp_bed_C": 20 + rng.random(rows)},
                     rng.choice([0.0, 3000.0], rows), {"Z": rng.uniform(-500, 0, rows)}, errors)


def _same(a: Recording, b: Recording) -> None:
    assert np.array_equal(a.t_s, b.t_s)
    for left, right in ((a.temperatures_C, b.temperatures_C), (a.positions_mm, b.positions_mm),
                        (a.errors_um, b.errors_um), (a.simulated_um, b.simulated_um)):
        assert left.keys() == right.keys()
        for key in left:
            assert np.array_equal(left[key], right[key], equal_nan=True), key
    assert (a.spindle_rpm is None) == (b.spindle_rpm is None)
    if a.spindle_rpm is not None and b.spindle_rpm is not None:
        assert np.array_equal(a.spindle_rpm, b.spindle_rpm)


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".pq"])
def test_irregular_time_and_gaps_round_trip_in_both_formats(tmp_path: Path, suffix: str) -> None:
    recording = _recording()
    path = tmp_path / f"day1{suffix}"
    write_recording(path, recording)
    again = load_recording(path)
    _same(recording, again)
    assert again.name == "day1"


def test_parquet_is_known_by_its_magic_bytes_and_nulls_are_empty_cells(tmp_path: Path) -> None:
    path = tmp_path / "logger.bin"
    t = pa.array([0, 60, 125, 300], pa.int64())
    pq.write_table(pa.table({"t_s": t, "temp_a_C": pa.array([20.0, 20.1, 20.3, 20.2], pa.float32()),
                             "err_Z_um": pa.array([1.0, None, 2.0, None])}), path)
    recording = load_recording(path)
    assert recording.t_s.tolist() == [0.0, 60.0, 125.0, 300.0]
    assert np.isnan(recording.errors_um["Z"]).tolist() == [False, True, False, True]


def test_parquet_time_stamps_are_seconds(tmp_path: Path) -> None:
    path = tmp_path / "stamped.parquet"
    stamps = pa.array(np.array(["2026-01-01T08:00:00", "2026-01-01T08:00:15", "2026-01-01T08:01:00"],
                               dtype="datetime64[ms]"))
    pq.write_table(pa.table({"t_s": stamps, "temp_a_C": [1.0, 2.0, 3.0], "err_Z_um": [0.0, 1.0, 2.0]}), path)
    t = load_recording(path).t_s
    assert (t - t[0]).tolist() == [0.0, 15.0, 60.0]


@pytest.mark.parametrize(("table", "where"), [
    ({"temp_a_C": [1.0, 2.0, 3.0], "err_Z_um": [1.0, 2.0, 3.0]}, "field 't_s'"),
    ({"t_s": [0.0, 1.0, 2.0], "velocity": [1.0, 1.0, 1.0], "err_Z_um": [1.0, 2.0, 3.0]}, "field 'velocity'"),
    ({"t_s": [0.0, 1.0, 2.0], "temp_a_C": [1.0, None, 3.0], "err_Z_um": [1.0, 2.0, 3.0]},
     "field 'temp_a_C': row 2: empty cell"),
    ({"t_s": [0.0, 2.0, 1.0], "temp_a_C": [1.0, 2.0, 3.0], "err_Z_um": [1.0, 2.0, 3.0]},
     "field 't_s': row 3: time 1 does not increase"),
    ({"t_s": [0.0, 1.0, 2.0], "temp_a_C": [1.0, float("inf"), 3.0], "err_Z_um": [1.0, 2.0, 3.0]},
     "field 'temp_a_C': row 2: not a finite number"),
    ({"t_s": [0.0, 1.0, 2.0], "temp_a_C": ["a", "b", "c"], "err_Z_um": [1.0, 2.0, 3.0]},
     "field 'temp_a_C': not numbers (Parquet type string)"),
    ({"t_s": [0.0, 1.0, 2.0], "temp_a_C": [1.0, 2.0, 3.0]}, "no err_<axis>_um column"),
    ({"t_s": [0.0], "temp_a_C": [1.0], "err_Z_um": [1.0]}, "1 data row; a run needs at least 3"),
    ({"t_s": pa.array([], pa.float64()), "err_Z_um": pa.array([], pa.float64())}, "no data rows (an empty run)"),
])
def test_parquet_gets_the_checks_of_csv(tmp_path: Path, table: dict, where: str) -> None:
    path = tmp_path / "bad.parquet"
    pq.write_table(pa.table(table), path)
    with pytest.raises(NckConfigError) as error:
        load_recording(path)
    assert str(error.value).startswith(str(path)) and where in str(error.value), str(error.value)


@pytest.mark.parametrize(("text", "message"), [
    ("t_s,err_Z_um\n", "no data rows (an empty run)"),
    ("t_s,err_Z_um\n0,1\n", "1 data row; a run needs at least 3"),
    ("t_s,err_Z_um\n0,1\n\n1,2\n", "2 data rows; a run needs at least 3"),
    ("", "line 1: empty file"),
    ("t_s,err_Z_um,t_s\n0,1,0\n", "line 1, field 't_s': the column appears twice"),
    ("t_s,err_Z_um\n0,1\n1,nan\n2,3\n", "line 3, field 'err_Z_um': not a finite number"),
])
def test_csv_refusals_name_the_file_and_line(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(NckConfigError) as error:
        load_recording(path)
    assert str(error.value).startswith(str(path)) and message in str(error.value), str(error.value)


def test_a_csv_with_a_byte_order_mark_loads(tmp_path: Path) -> None:
    path = tmp_path / "excel.csv"
    path.write_bytes("\ufefft_s,err_Z_um\n0,1\n1,2\n2,3\n".encode())
    assert load_recording(path).t_s.tolist() == [0.0, 1.0, 2.0]


def test_corrupt_parquet_is_one_clear_error(tmp_path: Path) -> None:
    good = tmp_path / "good.parquet"
    write_recording(good, _recording())
    data = bytearray(good.read_bytes())
    truncated = tmp_path / "truncated.parquet"
    truncated.write_bytes(bytes(data[: len(data) // 2]))
    with pytest.raises(NckConfigError, match=r"truncated.parquet: not a readable Parquet file"):
        load_recording(truncated)
    text = tmp_path / "text.parquet"
    text.write_text("t_s,err_Z_um\n0,1\n")
    with pytest.raises(NckConfigError, match=r"text.parquet: not a readable Parquet file"):
        load_recording(text)
    unreadable = tmp_path / "locked.parquet"
    with pytest.raises(NckConfigError, match=r"locked.parquet: cannot read"):
        load_recording(unreadable)


def test_the_name_defaults_to_the_file_name_and_survives_a_slice() -> None:
    assert Recording("/data/day 3.csv", np.arange(3.0)).name == "day 3"
    assert Recording("<scenario x seed 1>", np.arange(3.0)).name == "scenario x seed 1"
    named = Recording("/data/all.csv", np.arange(5.0), name="block01_1250rpm")
    assert named.slice(np.arange(5) < 3).name == "block01_1250rpm"
    assert named.slice(np.arange(5) < 3, "first").name == "first"


def _write_runs(directory: Path, names: list[str], axes: tuple[str, ...] = ("Z",)) -> list[Path]:
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for index, name in enumerate(names):
        path = directory / name
        write_recording(path, _recording(seed=index, axes=axes))
        paths.append(path)
    return paths


def test_load_runs_takes_files_directories_and_globs(tmp_path: Path) -> None:
    _write_runs(tmp_path / "a", ["mon.csv", "tue.parquet", "notes.txt.csv"])
    (tmp_path / "a" / "README.md").write_text("not a run")
    _write_runs(tmp_path / "b", ["wed.csv", "thu.pq"])
    single = _write_runs(tmp_path / "c", ["fri.csv"])[0]
    runs = load_runs([tmp_path / "a", str(tmp_path / "b" / "*"), single])
    assert [r.name for r in runs] == ["mon", "notes.txt", "tue", "thu", "wed", "fri"]
    assert len({r.name for r in runs}) == len(runs)
    assert [p.name for p in find_recordings([str(tmp_path / "**" / "*.pq")])] == ["thu.pq"]
    assert [r.name for r in load_runs([tmp_path / "a"], axis="Z")][:1] == ["mon"]


def test_load_runs_refusals(tmp_path: Path) -> None:
    paths = _write_runs(tmp_path / "one", ["day1.csv", "day2.csv"])
    other = _write_runs(tmp_path / "two", ["day1.parquet"])[0]
    two_axes = _write_runs(tmp_path / "xz", ["day3.csv"], axes=("X", "Z"))[0]
    (tmp_path / "empty").mkdir()
    empty_run = tmp_path / "day4.csv"
    empty_run.write_text("t_s,err_Z_um\n")
    one_row = tmp_path / "day5.csv"
    one_row.write_text("t_s,err_Z_um\n0,1\n")
    no_readings = tmp_path / "day6.csv"
    no_readings.write_text("t_s,err_Z_um\n0,\n1,\n2,3\n")
    cases = [
        ([paths[0], other], "day1.parquet: a second run named 'day1' (the first is"),
        ([paths[0], paths[0]], "day1.csv: the run 'day1' is given twice"),
        ([paths[0], two_axes], "day3.csv: its axes (err_X_um, err_Z_um) differ from those of"),
        ([tmp_path / "empty"], "empty: no recordings (*.csv, *.parquet, *.pq) in this directory"),
        ([str(tmp_path / "nothing*.csv")], "nothing*.csv: no recordings match this pattern"),
        ([tmp_path / "missing.csv"], "missing.csv: no such file or directory"),
        ([paths[0], empty_run], "day4.csv: no data rows (an empty run)"),
        ([paths[0], one_row], "day5.csv: 1 data row; a run needs at least 3"),
        ([], "no recordings given"),
    ]
    for specs, message in cases:
        with pytest.raises(NckConfigError) as error:
            load_runs(specs)
        assert message in str(error.value) and "\n" not in str(error.value), (message, str(error.value))
    with pytest.raises(NckConfigError, match=r"day1.csv, field 'err_Y_um': no err_Y_um column"):
        load_runs(paths, axis="Y")
    with pytest.raises(NckConfigError, match=r"day6.csv, field 'err_Z_um': 1 gauge reading in err_Z_um"):
        load_runs([paths[0], no_readings], axis="Z")
    assert len(load_runs([paths[0], two_axes], axis="Z")) == 2  # one axis chosen: the other may differ
