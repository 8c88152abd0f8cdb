"""Issue 50: `nckemu machine fit` writes a machine file whose sensors heat as the recording's did, and
`nckemu machine compare` replays a recording's inputs through it and says where the twin parts ways."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from nckemu.cli import main
from nckemu.emulator.machine.machine_file import load_machine
from nckemu.thermal.heat.scenarios import generate


def _write(path: Path, family: str, seed: int = 0) -> Path:
    run = generate(family, seed).run
    names = ["t_s", "spindle_rpm", "coolant", *(f"temp_{name}_C" for name in run.sensors_C)]
    columns = [run.t_s, run.inputs["spindle_rpm"], run.inputs["coolant"], *run.sensors_C.values()]
    np.savetxt(path, np.column_stack(columns), delimiter=",", header=",".join(names), comments="", fmt="%.6g")
    return path


def test_fit_writes_a_machine_file_that_show_and_compare_read(tmp_path, capsys):
    recording = _write(tmp_path / "table.csv", "coolant")
    fitted = tmp_path / "fitted.toml"
    assert main(["machine", "fit", str(recording), "--inputs", "spindle_rpm,coolant", "--out", str(fitted)]) == 0
    out = capsys.readouterr().out
    assert "the room: ambient" in out
    table_line = next(line for line in out.splitlines() if line.startswith("table:"))
    assert "coolant" in table_line and "spindle" in table_line
    assert "cabinet: held-out" in out and "nothing named" in next(row for row in out.splitlines() if row.startswith("cabinet"))
    machine = load_machine(fitted)
    assert [s.name for s in machine.sensors if s.response] == ["bed", "table"]   # the built-in bed kept
    assert {a.name for a in machine.axes} >= {"X1", "Z1"}          # the built-in machine's axes are kept
    assert main(["machine", "compare", str(recording), "--machine", str(fitted), "--figure",
                 str(tmp_path / "compare.png")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("table: twin against recording RMS 0.0")
    assert (tmp_path / "compare.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["machine", "compare", str(recording), "--machine", str(fitted), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["sensors"][0]["sensor"] == "table" and document["sensors"][0]["rms_K"] < 0.1


def test_fit_json_and_bad_input(tmp_path, capsys):
    recording = _write(tmp_path / "frame.csv", "neighbour")
    assert main(["machine", "fit", str(recording), "--json", "--sensors", "head,frame"]) == 0
    document = json.loads(capsys.readouterr().out)
    frame = next(s for s in document["sensors"] if s["sensor"] == "frame")
    assert [t["name"] for t in frame["terms"]] == ["neighbour"] and frame["terms"][0]["sensor"] == "head"
    assert main(["machine", "fit", str(recording), "--inputs", "spindle_rpm,flood"]) == 1
    assert "--inputs flood: no such column" in capsys.readouterr().err
    assert main(["machine", "fit", str(recording), "--reference", "nowhere"]) == 1
    assert "no temp_nowhere_C" in capsys.readouterr().err


@pytest.mark.slow
def test_fl_thermal_fitted_on_the_first_60_percent(shared_dir, tmp_path, capsys):
    """The measured recording: the figures docs/heat.md gives (median over sensors, the hottest)."""
    recording = shared_dir / "data" / "fl_thermal" / "recording.csv"
    if not recording.exists():
        pytest.skip("../shared/data/fl_thermal is absent")
    assert main(["machine", "fit", str(recording), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    fitted = [s for s in document["sensors"] if s["terms"]]
    median = float(np.median([s["heldout_rms_after_K"] for s in fitted]))
    hottest = max(fitted, key=lambda s: s["range_K"])
    assert median <= 0.5
    assert hottest["sensor"] == "t5" and hottest["heldout_rms_after_K"] <= 1.5
    assert hottest["left"]   # above 1 K: what the residual follows where it still fails
    assert all(s["terms"] for s in document["sensors"] if s["sensor"] != "t15")


def test_a_fit_onto_a_fitted_machine_replaces_its_sensors(tmp_path, capsys):
    """--machine names the base: its [[sensor]] tables of the fitted names go, with their responses;
    the others (the built-in bed) stay."""
    recording = _write(tmp_path / "table.csv", "coolant", seed=1)
    first, second = tmp_path / "first.toml", tmp_path / "second.toml"
    assert main(["machine", "fit", str(recording), "--inputs", "spindle_rpm,coolant", "--out", str(first)]) == 0
    assert main(["machine", "fit", str(recording), "--inputs", "spindle_rpm,coolant", "--machine", str(first),
                 "--out", str(second)]) == 0
    capsys.readouterr()
    names = [s.name for s in load_machine(second).sensors]
    assert sorted(names) == ["ambient", "bed", "cabinet", "table"]
    assert second.read_text().count("[[sensor]]") == 4


def test_compare_judges_the_twin_by_an_error_model(tmp_path, capsys):
    """--model: the recorded err_Z_um against the model fed the recorded temperatures and the twin's."""
    run = generate("coolant", 2).run
    error_um = 3.0 * (run.sensors_C["table"] - 20.0)
    names = ["t_s", "spindle_rpm", "coolant", "err_Z_um", *(f"temp_{name}_C" for name in run.sensors_C)]
    columns = [run.t_s, run.inputs["spindle_rpm"], run.inputs["coolant"], error_um, *run.sensors_C.values()]
    recording = tmp_path / "table.csv"
    np.savetxt(recording, np.column_stack(columns), delimiter=",", header=",".join(names), comments="", fmt="%.6g")
    model = tmp_path / "model.toml"
    model.write_text('axis = "Z"\n[[term]]\neffect = "temperature"\nsensor = "table"\nt_ref_C = 20.0\n'
                     'coeff_um_per_K = 3.0\n')
    fitted = tmp_path / "fitted.toml"
    assert main(["machine", "fit", str(recording), "--inputs", "spindle_rpm,coolant", "--out", str(fitted)]) == 0
    capsys.readouterr()
    assert main(["machine", "compare", str(recording), "--machine", str(fitted), "--model", str(model)]) == 0
    line = next(row for row in capsys.readouterr().out.splitlines() if row.startswith("err_Z_um"))
    recorded, twin = (float(part.split(" um")[0].split()[-1]) for part in line.split(", from the twin's"))
    assert recorded < 0.01 and twin < 0.3, line


@pytest.mark.slow
def test_fit_a_fleet_as_dask_tasks(tmp_path, capsys):
    """--fleet ROOT: each machine folder's fit as a task on a local cluster, the terms tabulated."""
    for folder, seed in (("mill1", 0), ("mill2", 1)):
        (tmp_path / folder).mkdir()
        _write(tmp_path / folder / "day1.csv", "coolant", seed)
    assert main(["machine", "fit", "--fleet", str(tmp_path), "--inputs", "spindle_rpm,coolant", "--workers", "1",
                 "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert [m["machine"] for m in document["machines"]] == ["mill1", "mill2"] and document["failed"] == {}
    rows = {(row["sensor"], row["term"]): row for row in document["table"]}
    assert rows[("table", "coolant")]["machines"] == 2 and rows[("table", "spindle")]["machines"] == 2
    assert rows[("table", "coolant")]["K"]["max"] < 0
    assert main(["machine", "fit", "--fleet", str(tmp_path), "--out", "x.toml"]) == 1
    assert "give no recordings, --out or --machine" in capsys.readouterr().err
