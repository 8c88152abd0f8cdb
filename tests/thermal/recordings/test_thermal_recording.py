"""Recording writers and readers: what is written reads back the same, in CSV and Parquet; any bytes
either load or give one NckConfigError."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nckemu.errors import NckConfigError
from nckemu.thermal.recordings.recording import Recording, load_recording, write_recording

NAMES = st.text("abcdefghijklmnopqrstuvwxyzABCZ0123456789_", min_size=1, max_size=6)
VALUES = st.floats(allow_nan=False, allow_infinity=False, width=64)


@st.composite
def recordings(draw: st.DrawFn) -> Recording:
    rows = draw(st.integers(3, 30))
    start = draw(st.floats(-1e6, 1e6, allow_nan=False))
    steps = draw(st.lists(st.floats(1e-3, 1e4, allow_nan=False), min_size=rows - 1, max_size=rows - 1))
    t = start + np.concatenate(([0.0], np.cumsum(steps)))
    if np.any(np.diff(t) <= 0):  # floating-point sums may tie on a large start: keep time increasing
        t = start + np.arange(rows, dtype=float)

    def column(nullable: bool) -> np.ndarray:
        values = np.asarray(draw(st.lists(VALUES, min_size=rows, max_size=rows)), dtype=float)
        if nullable:
            values[np.asarray(draw(st.lists(st.booleans(), min_size=rows, max_size=rows)))] = np.nan
        return values

    sensors = draw(st.lists(NAMES, max_size=3, unique=True))
    axes = draw(st.lists(NAMES, min_size=1, max_size=2, unique=True))
    return Recording(
        "<drawn>", t, {f"temp_{name}_C": column(False) for name in sensors},
        column(False) if draw(st.booleans()) else None,
        {axis: column(False) for axis in draw(st.lists(NAMES, max_size=2, unique=True))},
        {axis: column(True) for axis in axes},
        {axis: column(True) for axis in axes if draw(st.booleans())})


def _equal(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return np.array_equal(a, b, equal_nan=True)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(recordings(), st.sampled_from([".csv", ".parquet"]))
def test_written_recordings_read_back_the_same(recording: Recording, suffix: str) -> None:
    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / f"run{suffix}"
        write_recording(path, recording)
        again = load_recording(path)
    assert _equal(recording.t_s, again.t_s) and _equal(recording.spindle_rpm, again.spindle_rpm)
    for left, right in ((recording.temperatures_C, again.temperatures_C), (recording.positions_mm,
                        again.positions_mm), (recording.errors_um, again.errors_um),
                        (recording.simulated_um, again.simulated_um)):
        assert left.keys() == right.keys() and all(_equal(left[k], right[k]) for k in left)
    assert again.name == "run"


def _load_or_refuse(data: bytes, suffix: str) -> None:
    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / f"any{suffix}"
        path.write_bytes(data)
        try:
            recording = load_recording(path)
        except NckConfigError as error:
            assert str(error).startswith(str(path)) and "\n" not in str(error)
        else:
            assert len(recording.t_s) >= 3 and np.all(np.diff(recording.t_s) > 0)


@settings(max_examples=150, deadline=None)
@given(st.binary(max_size=400), st.sampled_from([".csv", ".parquet", ".dat"]))
def test_random_bytes_never_crash_the_readers(data: bytes, suffix: str) -> None:
    _load_or_refuse(data, suffix)
    _load_or_refuse(b"PAR1" + data + b"PAR1", suffix)


@settings(max_examples=150, deadline=None)
@given(recordings(), st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255)), min_size=1, max_size=8),
       st.sampled_from([".csv", ".parquet"]))
def test_damaged_files_never_crash_the_readers(recording: Recording, damage: list[tuple[int, int]],
                                              suffix: str) -> None:
    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / f"good{suffix}"
        write_recording(path, recording)
        data = bytearray(path.read_bytes())
    for position, value in damage:
        data[position % len(data)] = value
    _load_or_refuse(bytes(data), suffix)
    _load_or_refuse(bytes(data[: damage[0][0] % len(data)]), suffix)  # and cut short
