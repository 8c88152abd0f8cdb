"""`nckemu program run`: a program offline, its block table and the recording it would make (issue 41)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from nckemu.cli import main
from nckemu.thermal.recordings.recording import load_recording
from tests.conftest import FIXTURES

SHORT = FIXTURES / "programs" / "SHORT.MPF"


def test_run_writes_blocks_and_a_recording_discover_reads(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocks, sim = tmp_path / "blocks.csv", tmp_path / "sim.csv"
    assert main(["program", "run", str(SHORT), "--blocks", str(blocks), "--out", str(sim), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["outcome"] == "ended" and summary["blocks"] == 9 and summary["parts"] == 1.0
    assert summary["net_time_s"] == pytest.approx(37.585, abs=0.001)
    rows = list(csv.DictReader(blocks.open()))
    assert [row["N"] for row in rows] == ["N10", "N20", "N30", "N40", "N50", "N60", "N70", "N80", "N90"]
    assert rows[3]["X_mm"] == "400.0000" and rows[3]["feed"] == "2000" and rows[-1]["M"] == "M30"
    recording = load_recording(sim, need_errors=False)
    assert recording.t_s[-1] == pytest.approx(38.0) and max(recording.spindle_rpm) == 3000.0
    assert "temp_bed_C" in recording.temperatures_C and set(recording.positions_mm) == {"X", "Y", "Z"}


def test_the_block_table_on_stdout(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["program", "run", str(SHORT)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("t_s\tend_s\tprogram") and "N40 G1 X400 F2000" in out[4]
    assert out[-1].startswith("/_N_MPF_DIR/_N_SHORT_MPF: ended after 37.6 s simulated (9 blocks")


@pytest.mark.parametrize(("content", "name", "expected"), [
    (None, "MISSING.MPF", "no such program file"),
    ("G0 X10\n", "my-prog.txt", "not an NC program name"),
])
def test_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str | None, name: str,
                               expected: str) -> None:
    path = tmp_path / name
    if content is not None:
        path.write_text(content)
    assert main(["program", "run", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expected in err[0]


def test_a_program_alarm_exits_1_and_names_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "BAD.MPF"
    path.write_text("G0 X10\nGOTOF NOWHERE\nM30\n")
    assert main(["program", "run", str(path), "--json"]) == 1
    summary = json.loads(capsys.readouterr().out)
    assert summary["outcome"] == "alarm" and "14080" in summary["alarms"][0]


def test_an_endless_program_stops_at_max_time(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "LOOP.MPF"
    path.write_text("L1:\nG1 X10 F6000\nG1 X20\nGOTOB L1\n")
    assert main(["program", "run", str(path), "--max-time", "60", "--json"]) == 1
    summary = json.loads(capsys.readouterr().out)
    assert summary["outcome"] == "timeout" and summary["simulated_s"] == pytest.approx(60.0)
