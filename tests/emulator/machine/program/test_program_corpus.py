"""The public programs of bench/corpus/manifest.toml, run as bench/bench_corpus.py runs them: none may
crash (a traceback of ours); every program that does not run to its end stops with an NCK alarm naming
program, line and feature, or is still running (a program waiting for its PLC). The programs are not in
the repository: set NCKEMU_CORPUS to the directory bench/corpus_fetch.py fetched them into."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from bench.bench_corpus import run_corpus
from bench.corpus_fetch import load_manifest

CORPUS = Path(os.environ.get("NCKEMU_CORPUS", "/nonexistent-nckemu-corpus"))


def test_the_manifest_names_40_programs_of_8_repositories_each_at_a_commit() -> None:
    manifest = load_manifest()
    repositories = {entry["repo"]: entry for entry in manifest["repository"]}
    assert len(manifest["program"]) >= 40 and len({entry["repo"] for entry in manifest["program"]}) >= 8
    for entry in manifest["program"]:
        assert len(entry["commit"]) == 40 and repositories[entry["repo"]]["commit"] == entry["commit"]
        assert (Path(__file__).parents[4] / repositories[entry["repo"]]["machine"]).is_file()


def test_every_machine_the_manifest_names_loads() -> None:
    from nckemu.emulator.machine.machine_file import load_machine

    manifest = load_manifest()
    root = Path(__file__).parents[4]
    machines = {entry["machine"] for entry in manifest["repository"]}
    machines |= {entry["machine"] for entry in manifest["program"] if "machine" in entry}
    for machine in sorted(machines):
        assert load_machine(root / machine).axes, machine


def test_the_manifests_own_budgets_say_why_and_its_gud_values_are_files_of_ours() -> None:
    manifest_dir = Path(__file__).parents[4] / "bench" / "corpus"
    for entry in load_manifest()["program"]:
        if "max_time_s" in entry or "wall_s" in entry:
            assert entry.get("why"), entry
        values = entry.get("values", [])
        for name in [values] if isinstance(values, str) else values:
            text = (manifest_dir / name).read_text()
            assert "of ours" in text and text.rstrip().endswith("M17"), name


@pytest.mark.slow
@pytest.mark.timeout(3600)  # 55 programs of up to 30 s of real time each
def test_no_program_of_the_corpus_crashes() -> None:
    if not CORPUS.is_dir():
        pytest.skip("NCKEMU_CORPUS is not a directory: fetch the corpus with bench/corpus_fetch.py (needs GitHub)")
    results = run_corpus(CORPUS, wall_s=30.0)
    if not results:
        pytest.skip(f"no program of the manifest under {CORPUS}")
    assert not [result["program"] for result in results if result["outcome"] == "crashed"]
    for result in results:
        if result["outcome"] == "alarm":
            assert result.get("number") and result.get("line"), result
