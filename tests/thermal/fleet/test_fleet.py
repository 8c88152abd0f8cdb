"""Fleet discovery's parts without a cluster: the machine folders, the task, the fleet table."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from nckemu.cli import main
from nckemu.errors import NckConfigError
from nckemu.thermal.fleet.discover import (
    MachineFolder,
    discover_machine,
    fleet_document,
    fleet_table,
    scan_root,
    write_fleet_report,
)
from nckemu.thermal.model.terms import render_model
from nckemu.thermal.recordings.recording import load_recording, write_recording
from nckemu.thermal.synthetic.scenarios import make_scenario


def _machine(root: Path, name: str, scenario: str, seed: int, days: int = 1, model: bool = True) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    made = make_scenario(scenario, seed=seed, duration_h=24.0 * days)
    t_s = made.recording.t_s
    for day in range(days):
        inside = (t_s >= day * 86400.0) & (t_s < (day + 1) * 86400.0)
        write_recording(folder / f"day{day + 1:03d}.csv", made.recording.slice(inside))
    if model:
        (folder / "model.toml").write_text(render_model(made.baseline), encoding="utf-8")
    return folder


def test_scan_root_finds_runs_and_model(tmp_path: Path) -> None:
    _machine(tmp_path, "b", "gain_error", 2, days=2)
    _machine(tmp_path, "a", "thermal_lag", 1, model=False)
    (tmp_path / "notes.txt").write_text("not a machine", encoding="utf-8")
    machines = scan_root(tmp_path)
    assert [m.name for m in machines] == ["a", "b"]
    assert [Path(r).name for r in machines[1].runs] == ["day001.csv", "day002.csv"]
    assert machines[0].model is None and Path(machines[1].model or "").name == "model.toml"
    assert all(Path(r).is_absolute() for m in machines for r in m.runs)


def test_a_machine_folder_without_recordings_is_refused(tmp_path: Path) -> None:
    _machine(tmp_path, "a", "thermal_lag", 1)
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "model.toml").write_text("", encoding="utf-8")
    with pytest.raises(NckConfigError, match=r"empty: no recordings in this machine folder"):
        scan_root(tmp_path)
    with pytest.raises(NckConfigError, match="not a directory"):
        scan_root(tmp_path / "nowhere")
    with pytest.raises(NckConfigError, match="no machine folders"):
        scan_root(tmp_path / "a")


def test_the_task_finds_the_machines_physics_over_its_runs(tmp_path: Path) -> None:
    folder = _machine(tmp_path, "m", "gain_error", 2, days=2)
    result = discover_machine(scan_root(tmp_path)[0])
    assert result["machine"] == "m" and result["runs"] == ["day001.csv", "day002.csv"] and "error" not in result
    assert [e["effect"] for e in result["findings"]["missing_physics"]] == ["gain_error"]
    days = [discover_machine(MachineFolder("m", (str(run),))) for run in sorted(folder.glob("*.csv"))]
    assert result["findings"]["samples"] == sum(day["findings"]["samples"] for day in days)


def test_bad_data_is_that_machines_error_not_the_fleets(tmp_path: Path) -> None:
    folder = tmp_path / "bad"
    folder.mkdir()
    (folder / "run.csv").write_text("t_s,temp_bed_C\n0,20\n", encoding="utf-8")
    result = discover_machine(scan_root(tmp_path)[0])
    assert "no err_<axis>_um column" in result["error"] and "run.csv" in result["error"]
    missing = MachineFolder("p", (str(tmp_path / "gone.parquet"),))
    assert "gone.parquet" in discover_machine(missing)["error"]


def test_parquet_and_csv_runs_give_the_same_findings(tmp_path: Path) -> None:
    folder = _machine(tmp_path / "csv", "m", "thermal_lag", 4, days=2)
    as_parquet = tmp_path / "parquet" / "m"
    as_parquet.mkdir(parents=True)
    for run in folder.glob("*.csv"):
        write_recording(as_parquet / f"{run.stem}.parquet", load_recording(run))
    (as_parquet / "model.toml").write_text((folder / "model.toml").read_text())
    from_csv = discover_machine(scan_root(tmp_path / "csv")[0])
    from_parquet = discover_machine(scan_root(tmp_path / "parquet")[0])
    assert from_parquet["runs"] == ["day001.parquet", "day002.parquet"]
    assert from_parquet["findings"] == from_csv["findings"]


def test_fleet_table_counts_machines_and_spreads_parameters() -> None:
    def machine(name: str, *effects: tuple[str, dict[str, object]]) -> dict[str, object]:
        return {"machine": name, "runs": ["r.csv"], "findings": {
            "missing_physics": [{"effect": e, "parameters": p} for e, p in effects]}}
    machines = [
        machine("a", ("thermal_lag", {"tau_s": 100.0, "sensor": "bed"}), ("offset", {"value_um": 1.0})),
        machine("b", ("thermal_lag", {"tau_s": 300.0, "sensor": "bed"})),
        machine("c", ("thermal_lag", {"tau_s": 200.0, "sensor": "spindle"})),
        machine("d"),
        {"machine": "e", "runs": [], "error": "broken"},
    ]
    table = fleet_table(machines)
    assert [(r["effect"], r["machines"], r["of"]) for r in table] == [("thermal_lag", 3, 4), ("offset", 1, 4)]
    assert table[0]["parameters"]["tau_s"] == {"min": 100.0, "median": 200.0, "max": 300.0, "std": 100.0}
    assert "sensor" not in table[0]["parameters"]
    document = fleet_document(machines, "root", None, "test")
    assert document["nothing_missing"] == ["d"] and document["failed"] == {"e": "broken"}


def test_fleet_report_is_a_page_naming_every_machine(tmp_path: Path) -> None:
    machines = [{"machine": "a<b", "runs": ["r.csv"], "worker_losses": 1, "findings": {
        "samples": 10, "heldout_rms_before_um": 2.0, "heldout_rms_after_um": 1.0,
        "missing_physics": [{"effect": "offset", "parameters": {"value_um": 1.5}}]}},
        {"machine": "c", "runs": ["r.csv"], "error": "no err_Z_um column"}]
    document = fleet_document(machines, "root", "Z", "local cluster, 2 worker(s)")
    write_fleet_report(tmp_path / "fleet.html", document, "fleet")
    page = (tmp_path / "fleet.html").read_text(encoding="utf-8")
    assert "a&lt;b" in page and "no err_Z_um column" in page and "1 of 1" in page and "retried" in page


def test_cli_refuses_bad_combinations_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _machine(tmp_path, "a", "thermal_lag", 1)
    for argv, expected in (
        (["discover", "--scheduler", "tcp://127.0.0.1:1"], "--scheduler and --workers go with --fleet ROOT"),
        (["discover", "--fleet", str(tmp_path), "--model", "m.toml"], "--model does not go with --fleet"),
        (["discover", "--fleet", str(tmp_path), "--workers", "0"], "--workers 0: at least 1"),
        (["discover", "--fleet", str(tmp_path / "a")], "no machine folders"),
        (["discover"], "give a recording CSV, or --fleet ROOT"),
        (["discover", "--fleet", str(tmp_path), "--json-out", str(tmp_path / "no" / "x.json")], "does not exist"),
    ):
        assert main(argv) == 1, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and expected in err, (argv, err)
    assert json.dumps  # (json is used by the interop tests' helpers as well)
