"""Every command example in README.md and docs/*.md runs as written (issue 37), against what `make serve`
starts (`nckemu serve --host 127.0.0.1 --port 1102 --opcua 4840`, here on free ports).

What counts as an example, so that none is skipped unseen:
* a fenced block tagged ``sh`` is run, line by line in order (a ``\\`` continues a line), in one
  working directory that has the repository's ``fixtures/`` and ``../shared`` beside it; a block with
  a line starting ``nckemu`` must be tagged ``sh`` (an example) or ``text`` (a synopsis with
  placeholders), never left untagged;
* an inline ``nckemu ...`` span is run unless it is a synopsis (it names a placeholder: ``M.toml``,
  ``REC.csv``, ``FILE``, ``[--option]``, ``...``), a command's bare name in a sentence (``nckemu
  serve``, ``nckemu get/put/vars``) or a command named with one of its options (``nckemu serve
  --record``, ``nckemu discover --fleet``, an option that needs a value and is given none);
* ``make serve`` and ``make test`` are the set-up this runner stands for, not run again.

As written means: the ports are the test's (1102 and 4840 are the running server's, every other port
a free one; the client commands reach the server through NCKEMU_HOST/NCKEMU_PORT, as README
"Connecting" says), nothing else is changed. A server an example starts (``nckemu serve``, ``nckemu
fleet`` not sent to the background) is started, seen ready and stopped. Each must end with exit code
0 and no line saying "does not exist"; a documented refusal must give its documented message. An
example that fails only because of the address grammar issue 37's other part settles is listed in
PENDING with its reason (expected to fail until then, strict: it must be taken off once it runs).
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path

import pytest

from nckemu.cli import _walk, build_parser
from tests.conftest import SHARED

REPO = Path(__file__).resolve().parents[1]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]

# Refusals the docs describe as such: the command, then the words its one line must say.
REFUSALS = {
    "nckemu get SD43900": "is an axis variable: say which axis",
    "nckemu pi _N_SELECT 201 /_N_MPF_DIR/_N_NOPE_MPF": "no such program or file (header error 0xD201)",
}
# Examples that wait on issue 37's address grammar (the other engineer's part): command -> reason.
PENDING: dict[str, str] = {}
# Examples that take minutes, run with -m slow (make slow; CI runs it): the words that mark each.
SLOW_MARKERS = (
    "nckemu loop fixtures/plc/fl_one_sensor.awl",  # the loop over FL_THERMAL's 46 h: seven PLC runs
    # The README's tour (a PLC run, a discovery and a loop, 45-70 s on two cores): test_readme_tour.py runs
    # the same block as written in a fresh clone after `make serve`, in the slow suite.
    "nckemu loop fixtures/plc/bed_only_z.awl --machine fixtures/machines/loop_mill.toml --inputs",
    "nckemu discover ../shared/data/fl_thermal/recording.csv --split-runs",  # 46 h of 16 sensors, 6 runs
    "nckemu recording check ../shared/data/fl_thermal/data.xlsx",  # reading a 46 h workbook twice
    # the heat fit of FL_THERMAL's 16 sensors and the twin replayed over its 46 h
    "nckemu machine fit ../shared/data/fl_thermal/recording.csv --inputs spindle_rpm --out fl.toml",
)
# Setting-up lines the runner stands for.
SETUP = ("make serve", "make test")
PLACEHOLDER = re.compile(r"(?:^|\s|=)(?:[A-Z][A-Z0-9_]*\.(?:toml|csv|awl|json|html|parquet|pcapng|mpf)|FILE|DIR|"
                         r"PATTERN|ROOT/|HOST:PORT|N|P|PORT)(?=\s|$|/)")


@dataclass(frozen=True)
class Example:
    source: str     # file:line
    kind: str       # "block" or "span"
    lines: tuple[str, ...]

    @property
    def text(self) -> str:
        return "\n".join(self.lines)


# ------------------------------------------------------------------------------------ extraction
def _logical_lines(block: list[str]) -> list[str]:
    lines, pending = [], ""
    for line in block:
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1].rstrip() + " "
            continue
        lines.append((pending + line.strip()) if pending else line.rstrip())
        pending = ""
    return [line for line in lines if line.strip()]


def fenced_blocks(path: Path) -> list[tuple[int, str, list[str]]]:
    """(first line number, info string, lines) of each fenced block."""
    blocks, inside, info, start, body = [], False, "", 0, []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if line.startswith("```"):
            if inside:
                blocks.append((start, info, body))
                inside = False
            else:
                inside, info, start, body = True, line[3:].strip(), number, []
            continue
        if inside:
            body.append(line)
    return blocks


def _command_names() -> set[str]:
    return {parser.prog.split(" ", 1)[1] for parser in _walk(build_parser())}


def _strip_quoted(text: str) -> str:
    return re.sub(r"'[^']*'|\"[^\"]*\"", "''", text)


def span_kind(span: str) -> str:
    """``run``, ``synopsis``, ``name`` (a command named in a sentence) or ``option`` (one of its
    options named)."""
    bare = _strip_quoted(span)
    if "[" in bare or "..." in bare or " | " in bare or PLACEHOLDER.search(bare):
        return "synopsis"
    words = span.split()[1:]
    commands = _command_names()
    if words and "/" in words[0] and all(part in commands for part in words[0].split("/")):
        words = words[1:]  # nckemu get/put/vars
    else:
        for length in (2, 1):
            if " ".join(words[:length]) in commands:
                words = words[length:]
                break
    if not words:
        return "name"
    if len(words) == 1 and words[0].startswith("-"):
        parser = _parser_of(span)
        action = parser._option_string_actions.get(words[0]) if parser is not None else None
        if action is not None and action.nargs != 0:
            return "option"  # an option that needs a value, named without one
    return "run"


def _parser_of(span: str) -> argparse.ArgumentParser | None:
    words = span.split()[1:]
    found = None
    for parser in _walk(build_parser()):
        command = parser.prog.split(" ", 1)[1].split()
        if words[:len(command)] == command and (found is None or len(command) >= len(found.prog.split())):
            found = parser
    return found


def examples() -> list[Example]:
    found = []
    for path in DOCS:
        name = path.relative_to(REPO).as_posix()
        for start, info, body in fenced_blocks(path):
            commands = [line for line in _logical_lines(body) if line.lstrip().startswith("nckemu ")]
            if info == "sh":
                found.append(Example(f"{name}:{start}", "block", tuple(_logical_lines(body))))
            else:
                assert not commands or info == "text", \
                    f"{name}:{start}: a block with nckemu commands is tagged sh (an example) or text (a synopsis)"
        text = path.read_text(encoding="utf-8")
        for match in re.finditer(r"(?<!`)`(nckemu [^`]+)`(?!`)", text):
            span = match.group(1).strip()
            if span_kind(span) == "run":
                line = text.count("\n", 0, match.start()) + 1
                found.append(Example(f"{name}:{line}", "span", (span,)))
    return found


EXAMPLES = examples()


def test_the_runner_finds_the_examples() -> None:
    texts = "\n".join(e.text for e in EXAMPLES)
    for expected in ("nckemu get 'SD43900[AX4]'", "nckemu trace replay s.pcapng", "nckemu vars /Channel/State",
                     "nckemu comp840c --port 1102 --axis 4", "nckemu loop fixtures/plc/seed003_elongation.awl",
                     "nckemu fleet fixtures/fleets/lab.toml", "nckemu serve --port 1102 --machine fixtures"):
        assert expected in texts, expected
    assert span_kind("nckemu serve") == "name" and span_kind("nckemu get/put/vars") == "name"
    assert span_kind("nckemu serve --record") == "option" and span_kind("nckemu plc run --inputs") == "option"
    assert span_kind("nckemu vars [--json] [PATTERN] [--machine M.toml]") == "synopsis"
    assert span_kind("nckemu lec --port 1102 --password EVENING FILE") == "synopsis"
    assert span_kind("nckemu vars --json") == "run" and span_kind("nckemu get SD43900") == "run"


def test_the_examples_that_need_shared_are_known() -> None:
    """Without ../shared beside the clone (a new user's first `make test`), every example that reads from it,
    or reads what such an example wrote, skips with the reason instead of failing."""
    reasons = {example.source: reason for example, reason in NEEDS_SHARED.items()}
    runs_syil = next(e.source for e in EXAMPLES if "syil_828d_warmup/routines/DAILY.MPF" in e.text)
    reads_syil = next(e.source for e in EXAMPLES if "--inputs syil.csv" in e.text)
    assert runs_syil in reasons and reasons[reads_syil].endswith(f"{runs_syil} writes from ../shared")
    assert not any("fixtures/" in e.text and "../shared" not in e.text and "syil" not in e.text
                   for e in NEEDS_SHARED), "an example on fixtures alone is marked as needing ../shared"


# ------------------------------------------------------------------------------------ running
def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@dataclass
class Site:
    workdir: Path
    env: dict[str, str]
    ports: dict[str, str]


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Site]:
    """`make serve` (S7 and OPC UA), and a working directory laid out as a clone: fixtures/, .venv/,
    and ../shared beside it."""
    root = tmp_path_factory.mktemp("docs")
    workdir = root / "nckemu"
    workdir.mkdir()
    (workdir / "fixtures").symlink_to(REPO / "fixtures")
    if SHARED.is_dir():
        (root / "shared").symlink_to(SHARED)
    bin_dir = Path(sys.executable).parent
    if (Path(sys.prefix) / "bin" / "activate").is_file():
        (workdir / ".venv").symlink_to(Path(sys.prefix))
    else:
        (workdir / ".venv" / "bin").mkdir(parents=True)
        (workdir / ".venv" / "bin" / "activate").write_text(f'export PATH="{bin_dir}:$PATH"\n')
    s7_port, opcua_port = _free_port(), _free_port()
    ports = {"1102": str(s7_port), "4840": str(opcua_port), "1103": str(_free_port()), "8080": str(_free_port())}
    env = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH",)}
    env.update(PATH=f"{bin_dir}{os.pathsep}{env.get('PATH', '')}", NCKEMU_HOST="127.0.0.1",
               NCKEMU_PORT=str(s7_port), PYTHONUNBUFFERED="1", MPLBACKEND="Agg")
    server = subprocess.Popen([str(bin_dir / "nckemu"), "serve", "--host", "127.0.0.1", "--port", str(s7_port),
                               "--opcua", str(opcua_port)], cwd=workdir, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        _wait_ready(server, "nckemu: machine", 120)
        yield Site(workdir, env, ports)
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=30)


def _wait_ready(process: subprocess.Popen[str], expected: str, timeout_s: float) -> str:
    assert process.stdout is not None
    deadline, seen = time.monotonic() + timeout_s, []
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        seen.append(line)
        if line.startswith(expected) and "127.0.0.1:" in line:
            return line
    raise AssertionError("the server did not get ready:\n" + "".join(seen[-20:]))


def with_ports(line: str, ports: dict[str, str]) -> str:
    for written, used in ports.items():
        line = re.sub(rf"(?<![\d.]){written}(?!\d)", used, line)
    return line


def _is_server(line: str) -> bool:
    words = line.split()
    return len(words) > 1 and words[0] == "nckemu" and words[1] in ("serve", "fleet") \
        and not line.rstrip().endswith("&") and "--help" not in words


def _run_server(line: str, site: Site) -> str:
    """A server example: on free ports of its own, seen ready, stopped."""
    argv = shlex.split(line)
    for option in ("--port", "--opcua", "--http"):
        if option in argv:
            argv[argv.index(option) + 1] = "0"
    expected = "nckemu: machine" if argv[1] == "serve" else ""
    process = subprocess.Popen(argv, cwd=site.workdir, env=site.env, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        return _wait_ready(process, expected, 120)
    finally:
        os.killpg(process.pid, signal.SIGTERM)
        process.wait(timeout=30)


def run_example(example: Example, site: Site, fixed_ports: Callable[[], AbstractContextManager[None]]) -> str:
    """Runs the example; its output, or an AssertionError naming the command that failed."""
    output = []
    script: list[str] = []

    def flush() -> None:
        if not script:
            return
        text = "\n".join(script)
        done = subprocess.run(["bash", "-e", "-c", text], cwd=site.workdir, env=site.env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=900)
        output.append(done.stdout)
        assert done.returncode == 0, f"{example.source}: exit {done.returncode}:\n{text}\n---\n{done.stdout[-3000:]}"
        script.clear()

    for written in example.lines:
        line = written.split("  #", 1)[0].rstrip() if not written.lstrip().startswith("#") else ""
        if not line or line.startswith(SETUP):
            continue
        line = with_ports(line, site.ports)
        if _is_server(line):
            flush()
            if line.split()[1] == "fleet":  # a fleet file's ports are its own: one such server at a time
                with fixed_ports():
                    output.append(_run_server(line, site))
            else:
                output.append(_run_server(line, site))
        else:
            script.append(line)
    flush()
    return "".join(output)


def _marks(example: Example) -> list[pytest.MarkDecorator]:
    marks = []
    if any(marker in example.text for marker in SLOW_MARKERS):
        marks.append(pytest.mark.slow)
    if example.text in PENDING:
        marks.append(pytest.mark.xfail(reason=PENDING[example.text], strict=True))
    if not SHARED.is_dir() and example in NEEDS_SHARED:
        marks.append(pytest.mark.skip(reason=NEEDS_SHARED[example]))
    return marks


# Options and redirections whose next word is a file the command writes.
_WRITES = ("--out", "--json-out", "--report", "--record", "-o", ">")


def _written_files(line: str) -> set[str]:
    words = line.replace(">", " > ").split()
    return {words[i + 1] for i, word in enumerate(words[:-1]) if word in _WRITES}


def needs_shared(found: list[Example]) -> dict[Example, str]:
    """The examples that cannot run without ../shared, with the reason: those naming a path in it, and those
    reading a file that such an example writes (docs/programs.md's `plc run --inputs syil.csv` reads what the
    SYIL warm-up run wrote), in the order the examples stand in their page."""
    needing: dict[Example, str] = {}
    written_by: dict[tuple[str, str], str] = {}  # (page, file) -> the example that writes it from ../shared
    for example in found:
        page = example.source.split(":", 1)[0]
        reads = [written_by[(page, word)] for word in example.text.split() if (page, word) in written_by]
        if "../shared" in example.text:
            needing[example] = f"{SHARED} is absent: the example runs files from ../shared"
        elif reads:
            needing[example] = f"{SHARED} is absent: the example reads what {reads[0]} writes from ../shared"
        if example in needing:
            for line in example.lines:
                for name in _written_files(line):
                    written_by[(page, name)] = example.source
    return needing


NEEDS_SHARED = needs_shared(EXAMPLES)


@pytest.mark.timeout(1800)
@pytest.mark.parametrize("example", [pytest.param(e, marks=_marks(e), id=f"{e.source} {e.lines[0][:50]}")
                                     for e in EXAMPLES])
def test_example_runs_as_written(example: Example, site: Site,
                                 fixed_ports: Callable[[], AbstractContextManager[None]]) -> None:
    if example.text in REFUSALS:
        done = subprocess.run(["bash", "-c", with_ports(example.text, site.ports)], cwd=site.workdir, env=site.env,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=120)
        assert done.returncode == 1 and REFUSALS[example.text] in done.stdout, done.stdout
        return
    out = run_example(example, site, fixed_ports)
    bad = [line for line in out.splitlines() if "does not exist" in line]
    assert not bad, f"{example.source}: {bad[:3]}"


def test_make_serve_is_what_the_runner_starts() -> None:
    """The runner's server is `make serve`'s command line; if the Makefile changes, so must the runner."""
    makefile = (REPO / "Makefile").read_text(encoding="utf-8")
    assert "nckemu serve --host $(HOST) --port $(PORT) --opcua $(OPCUA_PORT)" in makefile
    assert shutil.which("bash") is not None


# ------------------------------------------------------------------ names the README promises
def _spans_after(text: str, start: str, end: str) -> list[str]:
    part = text.split(start, 1)[1].split(end, 1)[0]
    return re.findall(r"`([^`]+)`", part)


def documented_names() -> list[str]:
    """The README's "Readable names" (read with `nckemu get`)."""
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    return _spans_after(readme, "Readable names:", "\n\n")


def documented_node_ids() -> list[str]:
    """The node ids of README "Two faces" (read over OPC UA): whole ids, not the patterns."""
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    spans = _spans_after(readme, "* Namespace `SinumerikVarProvider`", "\n* ")
    return [span for span in spans if span.startswith("/") and "<" not in span]


def test_the_readme_names_read_on_the_default_machine(site: Site) -> None:
    """`cuttEdgeParam[2,T1,col7]` answered 0x0A (the default machine has tools 1 and 2): every name the
    README gives as readable reads."""
    names = documented_names()
    assert "SD43900[AX4]" in names and any(name.startswith("cuttEdgeParam") for name in names)
    for first in range(0, len(names), 8):  # GET takes 1..8 variables
        chunk = names[first:first + 8]
        done = subprocess.run(["nckemu", "get", *chunk], cwd=site.workdir, env=site.env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=120)
        assert done.returncode == 0, done.stdout
        assert len(done.stdout.splitlines()) == len(chunk) and "does not exist" not in done.stdout


def test_the_readme_node_ids_read_over_opcua(site: Site) -> None:
    """`/Nck/Spindle/driveLoad[u1, 3]` was no variable of the catalogue, `/Plc/DB2.DBD0:REAL[10]` and
    `/Plc/DB8.DBB2:STRING` BadAttributeIdInvalid (no DB2, DB8 on the default machine)."""
    import asyncio

    from asyncua import Client, ua

    ids = documented_node_ids()
    assert "/Plc/DB2.DBD0:REAL[10]" in ids and "/Plc/DB8.DBB2:STRING" in ids and len(ids) >= 8

    async def read_all() -> dict[str, str]:
        async with Client(f"opc.tcp://127.0.0.1:{site.ports['4840']}/", timeout=20) as client:
            ns = (await client.get_namespace_array()).index("SinumerikVarProvider")
            found = {}
            for node_id in ids:
                value = await client.get_node(ua.NodeId(node_id, ns)).read_data_value(raise_on_bad_status=False)
                found[node_id] = value.StatusCode.name
            return found

    statuses = asyncio.run(read_all())
    assert all(status == "Good" for status in statuses.values()), statuses
