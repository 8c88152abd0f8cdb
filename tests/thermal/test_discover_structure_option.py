"""``nckemu discover --structure MATERIAL[:LENGTH_M]``: what the machine's structure lets a term be,
for runs without a model file (docs/thermal.md), in place of the 3 m of steel taken when nothing is
declared; a bad value is an error naming the option and the field."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from nckemu.cli import main
from nckemu.errors import NckConfigError
from nckemu.thermal.commands import parse_structure_option
from nckemu.thermal.model.terms import render_model
from nckemu.thermal.recordings.recording import write_recording
from nckemu.thermal.synthetic.scenarios import AXIS, baseline_model, make_shape_family


def test_the_option_reads_as_a_structure_table() -> None:
    cast = parse_structure_option("cast_iron:1.2")
    assert cast.material == "cast_iron" and cast.length_m == 1.2 and cast.um_per_K == pytest.approx(12.6)
    given = parse_structure_option("9:2")
    assert given.um_per_K == pytest.approx(18.0) and "2 m of a material at 9 um/(m K)" == given.words()
    assert parse_structure_option("granite").length_m == 1.0  # a declared structure without its length: a metre
    with pytest.raises(NckConfigError, match="unknown material 'cheese'") as unknown:
        parse_structure_option("cheese:1")
    assert unknown.value.field == "structure.material"
    with pytest.raises(NckConfigError, match="not a number of metres"):
        parse_structure_option("steel:long")
    with pytest.raises(NckConfigError, match="length_m must be a positive number"):
        parse_structure_option("steel:-1")


@pytest.fixture(scope="module")
def room_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Twelve days on which the room acts through a lag of 3 h at 2.5 um/K, written as files, with
    the baseline model beside them."""
    folder = tmp_path_factory.mktemp("room")
    shape = make_shape_family("room_acts", 1, runs=12)
    for run in shape.runs:
        write_recording(folder / f"{run.name}.csv", run)
    (folder / "model.toml").write_text(render_model(baseline_model()), encoding="utf-8")
    return folder


def _named(folder: Path, tmp_path: Path, *extra: str) -> dict[str, object]:
    out = tmp_path / "found.json"
    runs = sorted(str(p) for p in folder.glob("*.csv"))
    assert main(["discover", *runs, "--axis", AXIS, "--model", str(folder / "model.toml"),
                 "--json-out", str(out), *extra]) == 0
    return json.loads(out.read_text(encoding="utf-8"))


def test_a_short_structure_lists_the_room_lag_it_cannot_have(room_runs: Path, tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    default = _named(room_runs, tmp_path)
    assert any(m["parameters"].get("sensor") == "ambient" for m in default["missing_physics"])  # type: ignore[union-attr,index]
    short = _named(room_runs, tmp_path, "--structure", "steel:0.1")
    assert not any(m["parameters"].get("sensor") == "ambient" for m in short["missing_physics"])  # type: ignore[union-attr,index]
    assert short["cannot_have"] and "0.1 m of steel" in capsys.readouterr().out


def test_the_improved_model_carries_the_structure(room_runs: Path, tmp_path: Path) -> None:
    improved = tmp_path / "improved.toml"
    _named(room_runs, tmp_path, "--structure", "cast_iron:1.5", "--write-model", str(improved))
    text = improved.read_text(encoding="utf-8")
    assert "[structure]" in text and 'material = "cast_iron"' in text and "length_m = 1.5" in text


def test_fleet_takes_the_structure_from_each_model(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _exit_status(["discover", "--fleet", str(tmp_path), "--structure", "steel:1"]) != 0
    assert "[structure] table of its model TOML" in capsys.readouterr().err


def test_a_bad_structure_is_one_line_naming_the_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = make_shape_family("null_shape_days", 1, runs=3).runs[0]
    write_recording(tmp_path / "run.csv", replace(run, name="run"))
    status = _exit_status(["discover", str(tmp_path / "run.csv"), "--axis", AXIS, "--structure", "cheese"])
    err = capsys.readouterr().err
    assert status != 0 and "--structure" in err and "unknown material 'cheese'" in err and "Traceback" not in err


def _exit_status(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as stop:
        return int(stop.code or 0)
