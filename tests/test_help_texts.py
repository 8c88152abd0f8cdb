"""Every option says what it does and every command shows an example (issue 37): argparse walked, not
a list kept by hand; the version is the package's; figures a help text quotes are the measured ones."""

from __future__ import annotations

import argparse
import re
import tomllib
from importlib.metadata import version
from pathlib import Path

import pytest

from nckemu import __version__
from nckemu.cli import _walk, build_parser, main

REPO = Path(__file__).resolve().parents[0].parent


def _parsers() -> list[argparse.ArgumentParser]:
    top = build_parser()
    return [top, *_walk(top)]


def _arguments() -> list[tuple[str, argparse.Action]]:
    return [(parser.prog, action) for parser in _parsers() for action in parser._actions
            if not isinstance(action, argparse._HelpAction | argparse._SubParsersAction)]


@pytest.mark.parametrize(("prog", "action"), _arguments(),
                         ids=[f"{prog} {'/'.join(a.option_strings) or a.dest}" for prog, a in _arguments()])
def test_every_option_and_argument_has_a_help_text(prog: str, action: argparse.Action) -> None:
    """Before: serve --max-connections, --rack, pi's service and arguments, comp840c --axis, trace's
    capture had none."""
    assert action.help and action.help != argparse.SUPPRESS and len(action.help) > 8, \
        f"{prog} {'/'.join(action.option_strings) or action.dest}: no help text"


@pytest.mark.parametrize("parser", _parsers(), ids=[p.prog for p in _parsers()])
def test_every_command_help_shows_an_example(parser: argparse.ArgumentParser) -> None:
    """Groups too (machine, trace, plc had none): `nckemu trace --help` is what a newcomer types first."""
    help_text = parser.format_help()
    assert re.search(r"(?im)^\s*(?:examples?:\s*)?nckemu \S+", parser.epilog or ""), f"{parser.prog}: no example"
    assert help_text.endswith("\n")
    if parser.prog != "nckemu":
        command = parser.prog.split(" ", 1)[1]
        assert f"nckemu {command}" in parser.epilog, f"{parser.prog}: the example is of another command"


def test_version_is_the_packages(capsys: pytest.CaptureFixture[str]) -> None:
    """0.1.0 was printed after the layout change of 0.2.0; now pyproject.toml's version, read from the
    installed package's metadata."""
    declared = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]["version"]
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"nckemu {declared}"
    assert __version__ == version("nckemu") == declared
    assert tuple(int(part) for part in declared.split(".")[:2]) >= (0, 2)


def test_fleet_help_quotes_the_opcua_faces_measured_cost() -> None:
    """It said 55 MB and 1.5 s per OPC UA face; the README and bench_fleet.py say about 4 MB (the
    standard address space is shared from disk)."""
    fleet = next(p for p in _parsers() if p.prog == "nckemu fleet")
    text = fleet.format_help()
    assert "55 MB" not in text and "1.5 s" not in text
    (figure,) = re.findall(r"OPC UA face \(about (\d+) MB", text)
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert f"takes about {figure} MB" in readme and f"~{figure} MB with OPC UA" in readme
