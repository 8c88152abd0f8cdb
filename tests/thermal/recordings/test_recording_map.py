"""Recordings as they come (issue 36): workbooks, European CSV, other column names, a map file."""

from __future__ import annotations

import datetime as dt
import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

openpyxl = pytest.importorskip("openpyxl")

from nckemu.cli import main  # noqa: E402
from nckemu.errors import NckConfigError  # noqa: E402
from nckemu.thermal.recordings.recording_map import (  # noqa: E402
    excel_serial,
    load_map,
    load_mapped_runs,
    load_recording,
    load_runs,
    read_sources,
    read_tables,
)
from tests.conftest import SHARED  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
FOREIGN = REPO / "fixtures" / "thermal" / "foreign"
FL_MAP = FOREIGN / "fl_thermal_map.toml"


def write_map(path: Path, text: str) -> Path:
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path


def eu_text(value: object) -> str:
    """A cell as a German Excel writes it: ',' as the decimal mark."""
    if value is None:
        return ""
    if isinstance(value, float | int) and not isinstance(value, bool):
        return repr(float(value)).replace(".", ",") if isinstance(value, float) else str(value)
    return str(value)


# ------------------------------------------------------------------------------ the public workbook
@pytest.fixture(scope="module")
def fl_paths() -> tuple[Path, Path]:
    folder = SHARED / "data" / "fl_thermal"
    if not (folder / "data.xlsx").is_file():
        pytest.skip("../shared/data/fl_thermal/data.xlsx is not there")
    return folder / "data.xlsx", folder / "recording.csv"


@pytest.fixture(scope="module")
def fl_imported(fl_paths: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("fl")
    assert main(["recording", "import", str(fl_paths[0]), "--map", str(FL_MAP), "--out", str(out)]) == 0
    return out


def _columns(recording) -> dict[str, np.ndarray]:
    columns = {"t_s": recording.t_s, **recording.temperatures_C}
    if recording.spindle_rpm is not None:
        columns["spindle_rpm"] = recording.spindle_rpm
    columns.update({f"err_{k}_um": v for k, v in recording.errors_um.items()})
    columns.update({f"pos_{k}_mm": v for k, v in recording.positions_mm.items()})
    return columns


def test_fl_workbook_imported_with_the_map_is_its_recording_csv(fl_paths, fl_imported: Path) -> None:
    written = sorted(fl_imported.iterdir())
    assert [p.name for p in written] == ["data.parquet"]
    imported = _columns(load_recording(written[0]))
    expected = _columns(load_recording(fl_paths[1]))
    assert list(imported) and set(imported) == set(expected)
    for name, values in expected.items():
        # recording.csv holds the workbook's values written with 6 significant digits
        rounded = np.array([float(f"{v:.6g}") for v in imported[name]])
        np.testing.assert_array_equal(rounded, values, err_msg=name)
    assert len(imported["t_s"]) == 11115


def test_fl_workbook_saved_as_european_csv_gives_the_same_runs(fl_paths, fl_imported: Path, tmp_path: Path) -> None:
    (table,) = read_tables(fl_paths[0])
    eu = tmp_path / "fl_eu.csv"
    lines = [";".join(table.header)]
    lines += [";".join(eu_text(column[row]) for column in table.cells) for row in range(len(table.rows))]
    eu.write_text("\r\n".join(lines) + "\r\n", encoding="utf-8-sig")
    (from_csv,) = load_mapped_runs([eu], FL_MAP)
    from_workbook = load_recording(fl_imported / "data.parquet")
    a, b = _columns(from_csv), _columns(from_workbook)
    assert set(a) == set(b)
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


# ------------------------------------------------------------------------ a workbook made here
T_H = np.array([0.0, 0.25, 0.5, 1.0, 1.5, 2.25])
DISP_MM = np.array([0.0012, 0.0031, -0.0047, 0.0105, None, 0.0203], dtype=object)
REAR_C = np.array([21.5, 22.25, 23.0, 24.125, 25.0, 25.5])
FRONT_F = np.array([70.7, 71.6, 73.4, 75.2, 77.0, 78.8])


def make_run_workbook(path: Path, *, with_notes: bool = True) -> Path:
    """Two run sheets named like a logger's days, odd header whitespace, hours, mm and °F."""
    workbook = openpyxl.Workbook()
    first = workbook.active
    sheets = [first, workbook.create_sheet("6-18-2017 TM16")]
    first.title = "6-17-2017 TM16"
    for number, sheet in enumerate(sheets):
        sheet.append(["Time", " Dia Disp", "Spindle Rear ", "Spindle Front", "Comment"])
        for row in range(len(T_H)):
            disp = DISP_MM[row]
            sheet.append([T_H[row] + 10 * number, None if disp is None else disp + number,
                          REAR_C[row] + number, FRONT_F[row], "ok" if row % 2 else None])
    if with_notes:
        workbook.create_sheet("Notes")  # blank: no time column, no run
    workbook.save(path)
    return path


RUN_MAP = """\
    [time]
    column = "Time"
    unit = "h"
    [columns]
    err_dia_um = { column = "Dia Disp", unit = "mm" }
    temp_spindle_rear_C = "Spindle Rear"
    temp_spindle_front_C = { column = "Spindle Front", unit = "F" }
    [runs]
    sheets = "*"
    """


def test_workbook_with_run_sheets_round_trips(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = make_run_workbook(tmp_path / "days.xlsx")
    mapping = write_map(tmp_path / "days.toml", RUN_MAP)
    out = tmp_path / "runs"
    assert main(["recording", "import", str(source), "--map", str(mapping), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "6-17-2017 TM16: 6 rows, 2.25 h, sampling 1800 s (largest gap 2700 s) -> " in printed
    assert sorted(p.name for p in out.iterdir()) == ["6-17-2017_TM16.parquet", "6-18-2017_TM16.parquet"]
    for number, name in enumerate(["6-17-2017_TM16", "6-18-2017_TM16"]):
        run = load_recording(out / f"{name}.parquet")
        np.testing.assert_allclose(run.t_s, T_H * 3600.0, rtol=0, atol=1e-9)  # each run from 0
        disp = np.array([np.nan if v is None else (v + number) * 1000.0 for v in DISP_MM])
        np.testing.assert_allclose(run.errors_um["dia"], disp, rtol=1e-12)
        np.testing.assert_allclose(run.temperatures_C["temp_spindle_rear_C"], REAR_C + number)
        np.testing.assert_allclose(run.temperatures_C["temp_spindle_front_C"], (FRONT_F - 32) * 5 / 9, atol=1e-12)
    # the files written are recordings of one machine: discover's loader takes the directory
    assert [r.name for r in load_runs([out])] == ["6-17-2017_TM16", "6-18-2017_TM16"]
    # and the runs read straight through the map are the same, named after the sheets
    direct = load_runs([source], map_path=mapping)
    assert [r.name for r in direct] == ["6-17-2017 TM16", "6-18-2017 TM16"]
    np.testing.assert_array_equal(direct[1].errors_um["dia"], load_recording(out / "6-18-2017_TM16.parquet").errors_um["dia"])


def test_excel_datetimes_and_a_run_column(tmp_path: Path) -> None:
    start = dt.datetime(2017, 6, 17, 8, 0, 0)
    offsets_s = [0, 15, 30, 60, 75, 0, 20, 40]
    runs = ["A", "A", "A", "A", "A", "B", "B", "B"]
    workbook = openpyxl.Workbook()
    sheet = workbook.active
    sheet.title = "log"
    sheet.append(["  Stamp", "Run", "X disp", "T1 "])
    for row, (offset, run) in enumerate(zip(offsets_s, runs, strict=True)):
        day = 0 if run == "A" else 1
        sheet.append([start + dt.timedelta(days=day, seconds=offset), run, 0.001 * row, 20.0 + row])
    # the second run's last stamp as an Excel serial number (a cell without a date format)
    sheet.cell(row=9, column=1).value = excel_serial(start + dt.timedelta(days=1, seconds=40))
    source = tmp_path / "stamps.xlsx"
    workbook.save(source)
    mapping = write_map(tmp_path / "stamps.toml", """\
        [time]
        column = "Stamp"
        unit = "datetime"
        [columns]
        err_x_um = { column = "X disp", unit = "mm" }
        temp_t1_C = "T1"
        [runs]
        column = "Run"
        """)
    a, b = load_mapped_runs([source], mapping)
    assert (a.name, b.name) == ("A", "B")
    np.testing.assert_allclose(a.t_s, [0, 15, 30, 60, 75], atol=1e-3)
    np.testing.assert_allclose(b.t_s, [0, 20, 40], atol=1e-3)
    np.testing.assert_allclose(b.errors_um["x"], [5.0, 6.0, 7.0], rtol=1e-12)
    np.testing.assert_allclose(a.temperatures_C["temp_t1_C"], [20, 21, 22, 23, 24])


def test_check_says_what_it_understood(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = make_run_workbook(tmp_path / "days.xlsx")
    mapping = write_map(tmp_path / "days.toml", RUN_MAP)
    assert main(["recording", "check", str(source), "--map", str(mapping), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert [(r["name"], r["rows"], r["median_s"], r["largest_gap_s"]) for r in document["runs"]] == [
        ("6-17-2017 TM16", 6, 1800.0, 2700.0), ("6-18-2017 TM16", 6, 1800.0, 2700.0)]
    assert document["ignored"] == ["Comment"]
    assert document["skipped_sheets"] == ["Notes"]
    roles = {c["column"]: (c["name"], c["role"], c["unit"]) for c in document["columns"]}
    assert roles["Dia Disp"] == ("err_dia_um", "measured error", "mm")
    assert roles["Time"] == ("t_s", "time", "h")
    assert main(["recording", "check", str(source), "--map", str(mapping)]) == 0
    text = capsys.readouterr().out
    assert "'Dia Disp'" in text and "mm -> um" in text and "ignored: 'Comment'" in text
    assert main(["recording", "check", str(REPO / "fixtures/thermal/runs/day1.csv")]) == 0
    assert "the project's format" in capsys.readouterr().out


# --------------------------------------------------------------------------- European CSV, no map
def test_european_csv_in_the_project_format_needs_no_map(tmp_path: Path) -> None:
    plain = REPO / "fixtures" / "thermal" / "runs" / "day1.csv"
    text = plain.read_text(encoding="utf-8")
    eu = tmp_path / "eu.csv"
    eu.write_text(text.replace(",", ";").replace(".", ","), encoding="utf-8")
    a, b = load_recording(plain), load_recording(eu)
    np.testing.assert_array_equal(a.t_s, b.t_s)
    for axis in a.errors_um:
        np.testing.assert_array_equal(a.errors_um[axis], b.errors_um[axis])
    tabbed = tmp_path / "tab.csv"
    tabbed.write_text(text.replace(",", "\t"), encoding="utf-8")
    np.testing.assert_array_equal(load_recording(tabbed).t_s, a.t_s)


def test_a_foreign_header_without_a_map_gets_one_line_naming_the_way(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    foreign = tmp_path / "foreign.csv"
    foreign.write_text("Zeit;Temp Spindel;X Abw\n0;20,5;1,5\n1;20,6;1,7\n2;20,7;1,9\n", encoding="utf-8")
    assert main(["discover", str(foreign)]) == 1
    message = capsys.readouterr().err.strip()
    assert len(message.splitlines()) == 1
    assert "'Zeit', 'Temp Spindel', 'X Abw'" in message and "--map MAP.toml" in message
    assert "field" not in message and "unknown column" not in message
    assert main(["discover", str(FOREIGN / "days.xlsx")]) == 1
    assert "a workbook (or another zip file), not a recording" in capsys.readouterr().err


# ------------------------------------------------------------------------------------ bad input
def _bad(tmp_path: Path, rows: list[list[object]], map_text: str = RUN_MAP,
         extra: list[list[object]] | None = None, options: tuple[str, ...] = ()) -> tuple[int, str, Path]:
    workbook = openpyxl.Workbook()
    good = workbook.active
    good.title = "good"
    good.append(["Time", "Dia Disp", "Spindle Rear", "Spindle Front"])
    for row in range(4):
        good.append([row * 0.5, 0.001 * row, 20.0 + row, 70.0])
    bad = workbook.create_sheet("bad day")
    for row in rows:
        bad.append(row)
    source = tmp_path / "bad.xlsx"
    workbook.save(source)
    mapping = write_map(tmp_path / "bad.toml", map_text)
    out = tmp_path / "out"
    return (main(["recording", "import", str(source), "--map", str(mapping), "--out", str(out), *options]),
            str(source), out)


HEADER = ["Time", "Dia Disp", "Spindle Rear", "Spindle Front"]


@pytest.mark.parametrize(("rows", "expected"), [
    ([HEADER, [0, 0.1, 20, 70], [0.5, 0.2, 21, 70], [0.25, 0.3, 22, 70]],
     "sheet 'bad day', row 4, column 'Time': the time goes backwards (900 s after 1800 s"),
    ([HEADER, [0, 0.1, 20, 70], [0.5, 0.2, 21, 70], [0.5, 0.3, 22, 70]],
     "sheet 'bad day', row 4, column 'Time': the time repeats"),
    ([HEADER, [0, 0.1, 20, 70], [0.5, "n/a", 21, 70], [1, 0.3, 22, 70]],
     "sheet 'bad day', row 3, column 'Dia Disp': text in a number column: 'n/a'"),
    ([HEADER], "sheet 'bad day': no data rows under the header"),
])
def test_a_bad_run_is_one_line_and_is_not_written(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                  rows: list[list[object]], expected: str) -> None:
    code, source, out = _bad(tmp_path, rows)  # all or nothing (issue 44): nothing written at all
    captured = capsys.readouterr()
    assert code == 1
    errors = [line for line in captured.err.splitlines() if line]
    assert len(errors) == 1 and f"{source}, {expected}" in errors[0], captured.err
    assert not out.exists() and not list(tmp_path.glob(".out.*"))
    assert "nothing written" in captured.out and "1 of 2 runs failed (bad day)" in captured.out
    code, source, out = _bad(tmp_path, rows, options=("--keep-going",))  # the good runs, on request
    captured = capsys.readouterr()
    assert code == 1
    assert sorted(p.name for p in out.iterdir()) == ["good.parquet"]  # nothing for the failed run
    assert "1 run written" in captured.out and "1 failed" in captured.out
    assert f"  bad day: {source}, {expected}" in captured.out  # which failed, and why


def test_a_header_only_sheet_fails_but_a_blank_one_is_no_run(tmp_path: Path, capsys) -> None:
    code, _source, _out = _bad(tmp_path, [])  # blank: no time column, so no run under sheets = "*"
    assert code == 0
    named = RUN_MAP.replace('sheets = "*"', 'sheets = ["good", "bad day"]')
    code, source, out = _bad(tmp_path, [], named)
    assert code == 1
    assert f"{source}, sheet 'bad day': empty sheet" in capsys.readouterr().err


def test_a_map_naming_a_column_the_sheet_lacks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, source, _out = _bad(tmp_path, [["Time", "Dia", "Spindle Rear", "Spindle Front"], [0, 1, 2, 3]])
    assert code == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert f"{source}, sheet 'bad day', row 1: no column 'Dia Disp' (" in err
    assert "bad.toml, line 5, columns.err_dia_um); the header has 'Time', 'Dia'" in err


@pytest.mark.parametrize(("text", "expected"), [
    ('[time]\ncolumn = "T"\nunit = "h"\n[columns]\nerr_x_um = { column = "X", unit = "furlong" }\n',
     "line 5, field 'columns.err_x_um': unknown unit 'furlong' for a measured error column (expected um"),
    ('[time]\ncolumn = "T"\nunit = "weeks"\n', "line 3, field 'time.unit': unknown time unit 'weeks'"),
    ('[time]\ncolumn = "T"\n[columns]\nerr_x_um = "X"\ntemp_a_C = "A"\nerr_x_um = "Y"\n',
     "line 6, field 'columns.err_x_um': two sources for one name (the first on line 4)"),
    ('[time]\ncolumn = "T"\n[columns]\nt_s = "X"\n', "line 4, field 'columns.t_s': two sources for one name"),
    ('[time]\ncolumn = "T"\n[columns]\nx_disp = "X"\n', "line 4, field 'columns.x_disp': not a project column"),
    ('[columns]\nerr_x_um = "X"\n', "field 'time': no [time] table"),
])
def test_a_bad_map_is_one_line_naming_its_line_and_field(tmp_path: Path, text: str, expected: str) -> None:
    path = write_map(tmp_path / "m.toml", text)
    with pytest.raises(NckConfigError) as caught:
        load_map(path)
    assert str(caught.value).startswith(f"{path}, {expected}"), str(caught.value)


def test_two_runs_of_one_name_across_sources(tmp_path: Path) -> None:
    make_run_workbook(tmp_path / "a.xlsx")
    make_run_workbook(tmp_path / "b.xlsx")
    mapping = load_map(write_map(tmp_path / "days.toml", RUN_MAP))
    with pytest.raises(NckConfigError, match="a second run named '6-17-2017 TM16'"):
        read_sources([tmp_path / "a.xlsx", tmp_path / "b.xlsx"], mapping)


# -------------------------------------------------------------- commands that read recordings
def test_discover_with_a_map_gives_what_the_project_file_gives(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    plain = REPO / "fixtures" / "thermal" / "seed003_spindle_elongation.csv"
    recording = load_recording(plain)
    workbook = openpyxl.Workbook()
    sheet = workbook.active
    sheet.append(["Minutes", "Gauge (mm)", "PLC (mm)"])
    for row in range(len(recording.t_s)):
        sheet.append([recording.t_s[row] / 60.0, recording.errors_um["Z"][row] / 1000.0,
                      recording.simulated_um["Z"][row] / 1000.0])
    source = tmp_path / "seed003.xlsx"
    workbook.save(source)
    mapping = write_map(tmp_path / "seed003.toml", """\
        [time]
        column = "Minutes"
        unit = "min"
        [columns]
        err_Z_um = { column = "Gauge (mm)", unit = "mm" }
        sim_Z_um = { column = "PLC (mm)", unit = "mm" }
        """)
    assert main(["discover", str(plain), "--json"]) == 0
    expected = json.loads(capsys.readouterr().out)
    assert main(["discover", str(source), "--map", str(mapping), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["axis"] == expected["axis"] == "Z"
    for key in ("baseline_rms_um", "heldout_rms_before_um", "heldout_rms_after_um"):
        assert got[key] == pytest.approx(expected[key], rel=1e-9, abs=1e-9), key


def test_plc_commands_take_a_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plain = REPO / "fixtures" / "thermal" / "seed003_loop.csv"
    rows = plain.read_text(encoding="utf-8").splitlines()
    header = rows[0].split(",")
    renamed = {"t_s": "Zeit [s]", "temp_elongation_C": "Dehnung", "err_Z_um": "Messuhr Z"}
    eu = tmp_path / "seed003_eu.csv"
    eu.write_text("\n".join([";".join(renamed.get(h, h) for h in header)]
                            + [r.replace(",", ";").replace(".", ",") for r in rows[1:]]) + "\n", encoding="utf-8")
    mapping = write_map(tmp_path / "eu.toml", """\
        [time]
        column = "Zeit [s]"
        [columns]
        temp_elongation_C = "Dehnung"
        err_Z_um = "Messuhr Z"
        """)
    assert set(header) <= set(renamed), header  # the map keeps every column of this recording
    machine = str(REPO / "fixtures" / "machines" / "seed003_spindle.toml")
    program = str(REPO / "fixtures" / "plc" / "seed003_elongation.awl")
    if not Path(program).is_file():
        pytest.skip("no seed003 program fixture")
    base = ["plc", "run", program, "--machine", machine, "--axis", "Z", "--json"]
    assert main([*base, "--inputs", str(plain)]) == 0
    expected = json.loads(capsys.readouterr().out)
    assert main([*base, "--inputs", str(eu), "--map", str(mapping)]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got == expected


def test_loop_takes_a_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = ["loop", str(REPO / "fixtures/plc/seed003_elongation.awl"), "--machine",
            str(REPO / "fixtures/machines/seed003_spindle.toml"), "--axis", "Z", "--cycle", "60s", "--folds", "3",
            "--json"]
    assert main([*base, "--inputs", str(REPO / "fixtures/thermal/seed003_loop.csv")]) == 0
    expected = json.loads(capsys.readouterr().out)
    assert main([*base, "--inputs", str(FOREIGN / "seed003_eu.csv"), "--map", str(FOREIGN / "seed003_eu_map.toml")]) == 0
    assert json.loads(capsys.readouterr().out) == expected


def test_serve_inputs_takes_a_map(tmp_path: Path) -> None:
    import subprocess
    import sys

    argv = [sys.executable, "-m", "nckemu", "serve", "--port", "0", "--machine",
            str(REPO / "fixtures/machines/seed003_spindle.toml"), "--inputs", str(FOREIGN / "seed003_eu.csv"),
            "--speed", "600x"]
    bad = subprocess.run([*argv, "--map", str(FOREIGN / "days_map.toml")], capture_output=True, text=True,
                         timeout=60)
    assert bad.returncode == 1 and "no column 'Time'" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    process = subprocess.Popen([*argv, "--map", str(FOREIGN / "seed003_eu_map.toml")], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        ready = process.stdout.readline() if process.stdout else ""
        assert ready.startswith("nckemu: machine") and "127.0.0.1:" in ready, \
            process.stderr.read() if process.stderr else ready
    finally:
        process.terminate()
        process.wait(timeout=20)


def test_a_parquet_source_with_time_stamps(tmp_path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    start = dt.datetime(2024, 3, 1, 6, 0, tzinfo=dt.UTC)
    stamps = [start + dt.timedelta(seconds=s) for s in (0, 30, 90, 120)]
    pq.write_table(pa.table({"stamp": stamps, "Y disp [mm]": [0.001, None, 0.003, 0.004],
                             "Motor Temp [K]": [293.15, 294.15, 295.15, 296.15]}), tmp_path / "log.parquet")
    mapping = write_map(tmp_path / "pq.toml", """\
        [time]
        column = "stamp"
        unit = "datetime"
        [columns]
        err_Y_um = { column = "Y disp [mm]", unit = "mm" }
        temp_motor_C = { column = "Motor Temp [K]", unit = "K" }
        """)
    (run,) = load_mapped_runs([tmp_path / "log.parquet"], mapping)
    np.testing.assert_allclose(run.t_s, [0, 30, 90, 120])
    np.testing.assert_allclose(run.errors_um["Y"], [1.0, np.nan, 3.0, 4.0])
    np.testing.assert_allclose(run.temperatures_C["temp_motor_C"], [20.0, 21.0, 22.0, 23.0], atol=1e-9)
