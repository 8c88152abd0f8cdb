"""CSV sniffing and unit conversions (issue 36): a table written with any separator and decimal mark reads
back the same; every unit conversion is the scale it says, and undoes its inverse."""

from __future__ import annotations

import datetime as dt
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nckemu.thermal.recordings.recording import load_recording, parse_number, sniff_csv
from nckemu.thermal.recordings.recording_map import (
    TIME_UNITS,
    VALUE_UNITS,
    convert_value,
    excel_serial,
    excel_serial_seconds,
    load_mapped_runs,
)

VALUES = st.floats(min_value=-1e9, max_value=1e9, allow_nan=False, allow_infinity=False)
DIALECTS = st.sampled_from([(",", "."), (";", "."), (";", ","), ("\t", "."), ("\t", ",")])


@st.composite
def tables(draw: st.DrawFn) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    rows = draw(st.integers(3, 25))
    steps = draw(st.lists(st.floats(1e-3, 1e4), min_size=rows - 1, max_size=rows - 1))
    t = np.concatenate(([0.0], np.cumsum(steps)))
    if np.any(np.diff(t) <= 0):
        t = np.arange(rows, dtype=float)
    names = ["err_Z_um", *(f"temp_s{i}_C" for i in range(draw(st.integers(0, 3))))]
    columns = {name: np.asarray(draw(st.lists(VALUES, min_size=rows, max_size=rows))) for name in names}
    return t, columns


def _cell(value: float, decimal: str) -> str:
    return repr(float(value)).replace(".", decimal)


def _write(path: Path, t: np.ndarray, columns: dict[str, np.ndarray], separator: str, decimal: str,
           header: list[str] | None = None) -> None:
    names = header or ["t_s", *columns]
    lines = [separator.join(names)]
    for row in range(len(t)):
        lines.append(separator.join([_cell(t[row], decimal), *(_cell(v[row], decimal) for v in columns.values())]))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tables(), DIALECTS)
def test_any_separator_and_decimal_mark_reads_back_the_same(table, dialect) -> None:
    t, columns = table
    separator, decimal = dialect
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "r.csv"
        _write(path, t, columns, separator, decimal)
        sniffed = sniff_csv(path.read_text(encoding="utf-8"))
        assert sniffed.separator == separator
        assert sniffed.decimal in (decimal, None)  # None: no fraction in the table (all whole numbers)
        recording = load_recording(path)
        np.testing.assert_array_equal(recording.t_s, t)
        np.testing.assert_array_equal(recording.errors_um["Z"], columns["err_Z_um"])
        for name, values in columns.items():
            if name.startswith("temp_"):
                np.testing.assert_array_equal(recording.temperatures_C[name], values)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tables(), DIALECTS, st.sampled_from(sorted(TIME_UNITS)), st.sampled_from(["mm", "um", "nm", "in"]))
def test_a_mapped_csv_converts_time_and_error_units(table, dialect, time_unit, error_unit) -> None:
    t, columns = table
    separator, decimal = dialect
    scale_t = TIME_UNITS[time_unit]
    scale_e = VALUE_UNITS["err"][error_unit][0]
    source_t = t / scale_t
    source = {"err_Z_um": columns["err_Z_um"] / scale_e}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "foreign.csv"
        _write(path, source_t, source, separator, decimal, header=[" Zeit ", "Weg Z"])
        mapping = Path(folder) / "map.toml"
        mapping.write_text(f'[time]\ncolumn = "Zeit"\nunit = "{time_unit}"\n[columns]\n'
                           f'err_Z_um = {{ column = " Weg Z", unit = "{error_unit}" }}\n', encoding="utf-8")
        (recording,) = load_mapped_runs([path], mapping)
    np.testing.assert_allclose(recording.t_s, (source_t - source_t[0]) * scale_t, rtol=1e-12, atol=0)
    np.testing.assert_allclose(recording.errors_um["Z"], source["err_Z_um"] * scale_e, rtol=1e-12, atol=0)


@given(st.lists(VALUES, min_size=1, max_size=20), st.sampled_from(sorted(VALUE_UNITS)), st.data())
def test_a_conversion_is_its_scale_and_offset_and_has_an_inverse(values, kind, data) -> None:
    unit = data.draw(st.sampled_from(sorted(VALUE_UNITS[kind])))
    array = np.asarray(values)
    scale, offset = VALUE_UNITS[kind][unit]
    converted = convert_value(array, kind, unit)
    np.testing.assert_array_equal(converted, array * scale + offset)
    np.testing.assert_allclose((converted - offset) / scale, array, rtol=1e-12, atol=1e-6)


@given(st.lists(VALUES, min_size=1, max_size=20))
def test_mm_to_um_and_hours_to_seconds(values) -> None:
    array = np.asarray(values)
    np.testing.assert_array_equal(convert_value(array, "err", "mm"), array * 1000.0)
    np.testing.assert_array_equal(convert_value(array, "pos", "mm"), array)
    np.testing.assert_allclose(convert_value(convert_value(array, "err", "mm") / 1000.0, "err", "mm"),
                               array * 1000.0)
    assert TIME_UNITS["h"] == 3600.0 and TIME_UNITS["min"] == 60.0


@given(st.datetimes(min_value=dt.datetime(1950, 1, 1), max_value=dt.datetime(2100, 1, 1)))
def test_an_excel_serial_is_the_moment_it_names(moment: dt.datetime) -> None:
    seconds = moment.replace(tzinfo=dt.UTC).timestamp()
    assert abs(excel_serial_seconds(excel_serial(moment)) - seconds) < 1e-4


@given(VALUES, st.sampled_from([".", ",", None]))
def test_a_number_cell_reads_in_its_decimal_mark(value, decimal) -> None:
    text = repr(value)
    written = text.replace(".", ",") if decimal == "," else text
    assert parse_number(written, decimal) == value
    assert parse_number("1.234,5", ",") is None  # a thousands separator is not guessed
