"""Issue 31, the reporting half: honest words (per-family detectable sizes, runs the model still
fails, mismatch windows where the residual is large, a structured residual never "nothing missing"),
a baseline that explains nothing, --split-runs on a recording that stays one run, the per-run report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from nckemu.cli import main
from nckemu.thermal.discovery import explain
from nckemu.thermal.discovery.discover import discover, discover_runs
from nckemu.thermal.discovery.report import write_report
from nckemu.thermal.discovery.wording import finding_lines, program_findings, runs_table
from nckemu.thermal.model.terms import Term, ThermalModel
from nckemu.thermal.recordings.recording import Recording, load_recording, write_recording

FIXTURES = Path(__file__).resolve().parents[3] / "fixtures" / "thermal"
RUNS = FIXTURES / "runs"
SHARED = Path(__file__).resolve().parents[3].parent / "shared" / "data"


def _with_sim(recording: Recording, axis: str, values: np.ndarray) -> Recording:
    return Recording(recording.source, recording.t_s, recording.temperatures_C, recording.spindle_rpm,
                     recording.positions_mm, recording.errors_um, {**recording.simulated_um, axis: values})


def _wander(hours: float = 48.0, step_s: float = 120.0, seed: int = 5) -> Recording:
    """An error that wanders slowly (a sine over the record) with a sensor that does not follow it:
    what it leaves is structure that no candidate of the vocabulary names."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, hours * 3600, step_s)
    temperature = 20.0 + rng.normal(0, 0.05, len(t))
    error = 5.0 * np.sin(2 * np.pi * t / (20 * 3600)) + rng.normal(0, 0.1, len(t))
    return Recording("wander.csv", t, {"temp_a_C": temperature}, None, {}, {"Z": error}, {})


# ---------------------------------------------------------------------- mismatch windows
def test_mismatch_windows_are_where_the_residual_is_large() -> None:
    """seed003: the first window listed was 0-0.5 h, mean residual +0.17 um against +10.05 um
    elsewhere, and the report shaded it."""
    result = discover(load_recording(FIXTURES / "seed003_spindle_elongation.csv"), axis="Z")
    assert result.mismatch
    t, residual = result.series["t_s"], result.series["residual_before_um"]
    for window in result.mismatch:
        inside = (t >= window["t_start_s"]) & (t <= window["t_end_s"])
        assert np.mean(np.abs(residual[inside])) > 1.5 * np.mean(np.abs(residual[~inside])), window
        assert window["t_start_s"] > 0
    assert "+0.17 um" not in json.dumps(result.mismatch)


# ---------------------------------------------------------------------- a baseline that explains nothing
def test_a_program_whose_output_stays_zero_is_judged_as_a_constant(tmp_path: Path, capsys) -> None:
    """tc_z compensates only above 30 degC: its sim_Z_um column is all zeros. Candidates must be tried
    against it plus an offset, exactly as without the sim column."""
    plain = load_recording(FIXTURES / "loop_bed_program_spindle_lag.csv")
    zeros = tmp_path / "sim.csv"
    write_recording(zeros, _with_sim(plain, "Z", np.zeros(len(plain.t_s))))
    out = tmp_path / "o.json"
    assert main(["discover", str(zeros), "--axis", "Z", "--json-out", str(out)]) == 0
    text = capsys.readouterr().out
    document = json.loads(out.read_text())
    effects = [m["effect"] for m in document["missing_physics"]]
    assert "thermal_lag" in effects and document["baseline_constant_um"] == 0.0
    assert document["heldout_rms_after_um"] < 0.2 * document["heldout_rms_before_um"]
    assert "no physics" not in text and "compensates nothing" in text
    without = discover(plain, "Z", ThermalModel("Z", [Term("offset", {"value_um": 0.0})]))
    assert document["missing_physics"] == json.loads(json.dumps(without.to_json()["missing_physics"]))
    assert document["heldout_rms_after_um"] == pytest.approx(without.heldout_rms_after_um, abs=1e-4)


# ---------------------------------------------------------------------- structure is never "nothing missing"
def test_a_residual_that_is_structure_is_never_nothing_missing() -> None:
    recording = _wander()
    result = discover(_with_sim(recording, "Z", np.zeros(len(recording.t_s))), axis="Z")
    assert result.missing_physics == []
    assert result.residual_structure["beyond_white_noise"] and result.residual_structure["r1"] > 0.9
    lines = finding_lines(result)
    assert not any(line.startswith("nothing missing") for line in lines)
    assert any(line.startswith("nothing named, but the residual is structure") for line in lines)
    physics = dict(program_findings(result))["What physics it leaves out"]
    assert "no physics" not in physics and "structure, not noise" in physics


def test_the_detectable_size_is_per_family() -> None:
    result = discover(_wander(), axis="Z", model=ThermalModel("Z", [Term("offset", {"value_um": 0.0})]))
    sizes = result.smallest_detectable_um
    assert len(sizes) >= 4
    assert len({round(v, 3) for v in sizes.values()}) > 1, sizes
    # never below the held-out bar's share of the baseline's mean square
    assert min(sizes.values()) >= 0.43 * result.heldout_rms_before_um


# ---------------------------------------------------------------------- --split-runs, one run
def _one_run_csv(tmp_path: Path) -> Path:
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 30 * 3600, 120.0)
    temperature = 20 + 6 * (1 - np.exp(-t / 20000.0)) + rng.normal(0, 0.03, len(t))
    error = 3.0 * (temperature - 20) + rng.normal(0, 0.3, len(t))
    path = tmp_path / "one.csv"
    write_recording(path, Recording("one.csv", t, {"temp_a_C": temperature}, None, {}, {"Z": error}, {}))
    return path


def test_split_runs_on_a_recording_that_stays_one_run_is_as_without_it(tmp_path: Path, capsys) -> None:
    path = _one_run_csv(tmp_path)
    plain, split = tmp_path / "plain.json", tmp_path / "split.json"
    assert main(["discover", str(path), "--json-out", str(plain)]) == 0
    assert main(["discover", str(path), "--split-runs", "--json-out", str(split)]) == 0
    assert "stays one run" in capsys.readouterr().err
    assert json.loads(split.read_text()) == json.loads(plain.read_text())
    assert json.loads(plain.read_text())["missing_physics"][0]["effect"] == "temperature"


@pytest.mark.skipif(not (SHARED / "sjtu_spindle" / "recording.csv").exists(), reason="../shared absent")
@pytest.mark.slow  # discovery over sjtu's 78 h of 16 sensors: 20-40 s on two cores (make slow)
def test_split_runs_on_sjtu_stays_one_run(tmp_path: Path, capsys) -> None:
    out = tmp_path / "o.json"
    assert main(["discover", str(SHARED / "sjtu_spindle" / "recording.csv"), "--split-runs",
                 "--json-out", str(out)]) == 0
    document = json.loads(out.read_text())
    assert document["missing_physics"] and "runs" not in document
    assert document["heldout_rms_after_um"] < 0.5 * document["heldout_rms_before_um"]


# ---------------------------------------------------------------------- several runs: figures, words, report
def test_run_figures_name_the_runs_the_model_still_fails() -> None:
    names = [f"run{i}" for i in range(7)]
    before = [7.0, 6.9, 6.5, 10.9, 7.2, 6.0, 6.8]
    figures = explain.run_figures(names, before, before, found=False)
    assert figures["median_after_um"] == pytest.approx(6.9)
    assert figures["fails"] == ["run3"] and figures["worst_run"] == "run3" and figures["runs_improved"] == 0
    after = [3.0, 3.1, 2.9, 7.5, 2.0, 6.5, 3.2]
    figures = explain.run_figures(names, before, after, found=True)
    assert figures["runs_improved"] == 6 and figures["fails"] == ["run3", "run5"]
    words = explain.runs_words(figures)
    assert "6 of 7 runs improve" in words and "worst run run3" in words and "still fails run3, run5" in words


def test_follows_names_the_signal_the_residual_tracks() -> None:
    t = np.arange(0.0, 10 * 3600, 60.0)
    rising = 20 + 5 * np.sin(t / 10000.0)  # heats, then cools: its rate is not its level
    flat = 20 + 0.1 * np.sin(t / 5000.0)
    recording = Recording("r.csv", t, {"temp_hot_C": rising, "temp_flat_C": flat}, None, {}, {}, {})
    residual = np.gradient(rising, t) * 3600 * 2.0
    assert explain.follows(recording, t, residual).startswith("the residual there follows the rate of temp_hot_C")
    assert explain.follows(recording, t[:3], residual[:3]) == ""


def test_runs_report_has_a_plot_per_run_and_marks_the_failing(tmp_path: Path) -> None:
    days = [load_recording(path) for path in sorted(RUNS.glob("*.csv"))]
    days[2].errors_um["Z"] = days[2].errors_um["Z"] + 4.0 * np.sin(days[2].t_s / 5000.0)  # a day it cannot follow
    result = discover_runs(days, axis="Z")
    assert result.run_figures["runs"] == 3 and result.run_figures["worst_run"] == "day3"
    assert [r["name"] for r in result.runs if r["fails"]] == result.run_figures["fails"]
    for name in result.run_figures["fails"]:
        (window,) = [w for w in result.mismatch if w["run"] == name]
        assert "follows" in window["why"]
    assert any("runs improve" in line and "worst run day3" in line for line in runs_table(result))
    report = tmp_path / "r.html"
    write_report(report, result, "runs")
    page = report.read_text()
    assert "Each run held out" in page and "Per run." in page
    assert len(result.series["heldout_improved_um"]) == len(result.series["measured_um"])


def test_detectable_sizes_follow_each_familys_held_out_figure() -> None:
    """Many samples (the t-test part small): before issue 31 every family got 0.44 x the baseline's
    RMS. Now each its own: a family no better held out than the baseline needs 0.48 x, one that
    costs held-out accuracy more."""
    from types import SimpleNamespace

    from nckemu.thermal.stats import CrossValidation

    def candidate(effect: str, heldout_um: float) -> SimpleNamespace:
        return SimpleNamespace(t_value=2.0, coefficient=0.01, own_rms=1.0, cv=CrossValidation(heldout_um, ()),
                               candidate=SimpleNamespace(term=SimpleNamespace(effect=effect)))

    base_um = 7.0
    sizes = explain.detectable_um([candidate("temperature", 7.0), candidate("thermal_lag", 7.3),
                                   candidate("thermal_gradient", 6.5), candidate("thermal_gradient", 6.9)],
                                  base_um, 4.0, 0.10)
    assert sizes["temperature"] == pytest.approx(base_um * (1 / 0.81 - 1) ** 0.5, rel=1e-6)
    assert sizes["thermal_lag"] == pytest.approx((7.3 ** 2 / 0.81 - 7.0 ** 2) ** 0.5, rel=1e-6)
    # what the better gradient already explains counts towards its size: 0.48 x its own held-out RMS
    assert sizes["thermal_gradient"] == pytest.approx(6.5 * (1 / 0.81 - 1) ** 0.5, rel=1e-6)
    assert min(sizes.values()) >= base_um * 0.19 ** 0.5  # never below the held-out bar
    assert len(set(sizes.values())) == 3
