"""Imports that write all or nothing, name the cell that breaks the decimal mark, and write numbers as a
person reads them (issue 44, item 3)."""

from __future__ import annotations

import csv
from pathlib import Path

from nckemu.cli import main

REPO = Path(__file__).resolve().parents[3]
FOREIGN = REPO / "fixtures" / "thermal" / "foreign"


def _mixed(tmp_path: Path) -> Path:
    """The European CSV with one cell (line 10, 'Dehnung [µm]') written with a point."""
    lines = (FOREIGN / "seed003_eu.csv").read_text(encoding="utf-8").splitlines()
    assert ";44,5;" in lines[9]
    lines[9] = lines[9].replace(";44,5;", ";44.5;")
    path = tmp_path / "mixed.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_a_mixed_decimal_mark_names_the_first_cell_that_breaks_it(tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    code = main(["recording", "import", str(_mixed(tmp_path)), "--map", str(FOREIGN / "seed003_eu_map.toml"),
                 "--out", str(out), "--format", "csv"])
    err = capsys.readouterr().err
    assert code == 1 and "line 10, column 'Dehnung [µm]': '44.5' writes '.' as the decimal mark" in err
    assert "line 2" not in err and not out.exists()


def test_imported_numbers_carry_no_float_noise(tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["recording", "import", str(FOREIGN / "seed003_eu.csv"), "--map",
                 str(FOREIGN / "seed003_eu_map.toml"), "--out", str(out), "--format", "csv"]) == 0
    (written,) = out.iterdir()
    with written.open(encoding="utf-8") as handle:
        cells = [cell for row in list(csv.reader(handle))[1:] for cell in row if cell]
    assert "24.5" in cells and "3.0" in cells  # 0,0245 mm and 0,003 mm as um
    assert all(len(cell.split(".")[-1]) < 12 for cell in cells), [c for c in cells if len(c) > 14]


def test_a_failing_source_writes_nothing_and_keep_going_writes_the_good(tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    mapping = str(FOREIGN / "seed003_eu_map.toml")
    good, bad = str(FOREIGN / "seed003_eu.csv"), str(_mixed(tmp_path))
    assert main(["recording", "import", good, bad, "--map", mapping, "--out", str(out), "--format", "csv"]) == 1
    captured = capsys.readouterr()
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]
    assert "nothing written" in captured.out and "--keep-going" in captured.out
    assert main(["recording", "import", good, bad, "--map", mapping, "--out", str(out), "--format", "csv",
                 "--keep-going"]) == 1
    captured = capsys.readouterr()
    assert [p.name for p in out.iterdir()] == ["seed003_eu.csv"]
    assert "1 run written" in captured.out and "mixed: " in captured.out and "decimal mark" in captured.out


def test_simulate_writes_no_float_noise(tmp_path: Path, capsys) -> None:
    out = tmp_path / "sim.csv"
    assert main(["simulate", "--model", str(REPO / "fixtures/thermal/baseline_spindle_bed.toml"), "--inputs",
                 str(REPO / "fixtures/thermal/runs/day1.csv"), "--out", str(out)]) == 0
    with out.open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert all(len(row["sim_Z_um"]) <= 16 for row in rows), max((row["sim_Z_um"] for row in rows), key=len)
    assert not list(tmp_path.glob(".sim.csv.partial"))


def test_a_project_format_csv_with_a_mixed_mark_names_the_cell(tmp_path: Path, capsys) -> None:
    path = tmp_path / "proj.csv"
    path.write_text("t_s;temp_a_C;err_Z_um\n0;20,5;1,5\n60;20,6;1,6\n120;20.7;1,7\n180;20,8;1,8\n", encoding="utf-8")
    assert main(["recording", "check", str(path)]) == 1
    assert "line 4, field 'temp_a_C': '20.7' writes '.' as the decimal mark" in capsys.readouterr().err
