"""docs/recordings.md: every command of its ``sh`` blocks runs as written (from the repository's root;
its /tmp/nckemu-* output directories become the test's own)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from nckemu.cli import main
from tests.conftest import SHARED

pytest.importorskip("openpyxl")

REPO = Path(__file__).resolve().parents[3]
DOC = REPO / "docs" / "recordings.md"


def _commands() -> list[str]:
    blocks = re.findall(r"```sh\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)
    return [line.strip() for block in blocks for line in block.splitlines() if line.strip().startswith("nckemu ")]


COMMANDS = _commands()


def test_the_page_has_three_worked_examples() -> None:
    assert len(re.findall(r"^### \d\. ", DOC.read_text(encoding="utf-8"), re.M)) == 3
    assert len(COMMANDS) >= 9


def _headline(output: str) -> str:
    """The held-out figures of discovery's first line (the runs' names differ between the sources)."""
    match = re.search(r"held-out \(each run left out, median over runs\) [0-9.]+ -> [0-9.]+ um", output)
    assert match is not None, output
    return match.group(0)


def test_every_command_runs_as_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(REPO)
    assert main(["discover", "fixtures/thermal/runs", "--axis", "Z"]) == 0
    project_headline = _headline(capsys.readouterr().out)
    ran = 0
    for command in COMMANDS:
        argv = [a.replace("/tmp/nckemu-", f"{tmp_path}/nckemu-") for a in shlex.split(command)[1:]]
        if any("../shared" in a for a in argv) and not SHARED.is_dir():
            continue
        if any(a.startswith("../shared") for a in argv):
            argv = [str(SHARED) + a[len("../shared"):] if a.startswith("../shared") else a for a in argv]
        if f"{tmp_path}/nckemu-fl" in " ".join(argv) and not (tmp_path / "nckemu-fl").exists():
            continue  # example 1 without ../shared
        code = main(argv)
        captured = capsys.readouterr()
        assert code == 0, f"{command}: {captured.err}"
        if argv[0] == "discover":  # the runs of example 2 are fixtures/thermal/runs: the same discovery
            assert _headline(captured.out) == project_headline
        ran += 1
    assert ran >= 7
    assert sorted(p.name for p in (tmp_path / "nckemu-days").iterdir()) == [
        "6-17-2017_TM16.parquet", "6-18-2017_TM16.parquet", "6-19-2017_TM16.parquet"]
    assert [p.name for p in (tmp_path / "nckemu-eu").iterdir()] == ["seed003_eu.csv"]
