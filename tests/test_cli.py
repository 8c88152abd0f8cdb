"""The command line as a new user meets it (issue 15): every --help example runs, and every bad input
is one clear line with exit code 1, before anything is written."""

from __future__ import annotations

import argparse
import functools
import os
import re
import shlex
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from nckemu.cli import COMMAND_HOMES, _walk, build_parser, main
from nckemu.clients import NckClient
from nckemu.emulator.runner import EmulatorThread
from nckemu.thermal.recordings.recording import write_recording
from nckemu.thermal.synthetic.scenarios import make_scenario

REPO = Path(__file__).resolve().parents[1]
FIXTURES = REPO / "fixtures"


def test_help_exits_cleanly(capsys):
    assert main([]) == 2
    assert "nckemu" in capsys.readouterr().out


# ---------------------------------------------------------------------------------------- helpers
def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture(scope="module")
def emulator() -> Iterator[EmulatorThread]:
    with EmulatorThread() as emu:
        yield emu


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small pcapng of a GET, a PUT and a PI job (nckemu serve --record)."""
    path = tmp_path_factory.mktemp("capture") / "capture.pcapng"
    with EmulatorThread(record_path=path) as emu, NckClient("127.0.0.1", emu.port) as client:
        client.get("SD43900[AX4]", "R5")
        client.put({"SD43900[AX4]": 0.25})
        client.login("EVENING")
    return path


@pytest.fixture(scope="module")
def silent_server() -> Iterator[int]:
    """Accepts connections and never answers (a controller that hangs)."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    held: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        listener.settimeout(0.2)
        while not stop.is_set():
            try:
                held.append(listener.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield listener.getsockname()[1]
    stop.set()
    thread.join()
    for connection in held:
        connection.close()
    listener.close()



def test_each_command_is_built_from_the_modules_that_register_it() -> None:
    """The parser built for one command (COMMAND_HOMES: only its modules imported) helps, defaults and
    runs exactly as the whole command line's, for every command and group; a word that is no command
    builds the whole line, so the error lists every command."""

    def named(value: object) -> str:  # a function, or a partial of functions, by its names
        if isinstance(value, functools.partial):
            return f"{named(value.func)}({', '.join(named(arg) for arg in value.args)})"
        return getattr(value, "__qualname__", repr(value))

    def described(parser: argparse.ArgumentParser) -> tuple[str, dict[str, str]]:
        return parser.format_help(), {key: named(value) for key, value in parser._defaults.items()}

    whole = {parser.prog: described(parser) for parser in _walk(build_parser())}
    assert {prog.split()[1] for prog in whole} == set(COMMAND_HOMES)
    for command in COMMAND_HOMES:
        alone = {parser.prog: described(parser) for parser in _walk(build_parser(["-v", command]))
                 if parser.prog.split()[1] == command}
        assert alone == {prog: text for prog, text in whole.items() if prog.split()[1] == command}, command
    assert build_parser(["--log-file", "serve", "get"]).parse_args(["get", "R1"]).command == "get"
    assert len(_walk(build_parser(["gett"]))) == len(whole)

# ------------------------------------------------------------------------------ --help examples
def _help_examples() -> list[tuple[str, list[str]]]:
    examples = []
    for parser in [build_parser(), *_walk(build_parser())]:
        for line in (parser.epilog or "").splitlines():
            match = re.match(r"^\s*(?:examples?:\s*)?nckemu (.+)$", line)
            if match:
                examples.append((parser.prog, shlex.split(match[1])))
    return examples


HELP_EXAMPLES = _help_examples()


def test_every_command_has_an_example_and_a_final_newline() -> None:
    parsers = _walk(build_parser())
    for parser in parsers:  # groups (trace, plc, machine) too: a newcomer types the group first
        assert any(prog == parser.prog for prog, _ in HELP_EXAMPLES), f"{parser.prog} --help has no example"
        assert parser.format_help().endswith("\n")


def _prepare(argv: list[str], workdir: Path, port: int, capture_path: Path) -> list[str]:
    """The example as written, in a directory holding the files it names; only the port is the test's."""
    if argv[0] == "serve":
        port = 0  # a server of its own on any free port (102 needs root)
        if "--port" not in argv:
            argv = [*argv, "--port", "1102"]
        argv = ["0" if a == "4840" else a for a in argv]  # the OPC UA face on any free port too
    argv = [str(port) if a == "1102" else a.replace("127.0.0.1:1102", f"127.0.0.1:{port}") for a in argv]
    return argv


@pytest.mark.parametrize(("prog", "argv"), HELP_EXAMPLES, ids=[" ".join(a)[:60] for _, a in HELP_EXAMPLES])
def test_help_example_runs(prog: str, argv: list[str], tmp_path: Path, capture: Path, capsys,
                           monkeypatch: pytest.MonkeyPatch, fixed_ports: Callable[[], Any]) -> None:
    # As written in a fresh clone: the repository's files (fixtures/) and nothing else; the only
    # change is the port of a server the test starts for examples that need one.
    os.symlink(FIXTURES, tmp_path / "fixtures")
    with EmulatorThread() as emu:
        argv = _prepare(argv, tmp_path, emu.port, capture)
        if argv[0] == "serve":  # servers: started, seen ready, stopped
            _run_serve_example(argv, tmp_path)
            return
        if argv[0] == "fleet":  # its ports are the example's own: one such server at a time
            with fixed_ports():
                _run_serve_example(argv, tmp_path)
            return
        monkeypatch.chdir(tmp_path)
        code = main(argv)
    err = capsys.readouterr().err
    assert code == 0, f"nckemu {' '.join(argv)} -> {code}: {err}"


def _run_serve_example(argv: list[str], cwd: Path) -> None:
    process = subprocess.Popen([sys.executable, "-m", "nckemu", *argv], cwd=cwd, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        ready = process.stdout.readline() if process.stdout else ""
        # serve's ready line; fleet's first line is its first machine's name and address
        expected = "nckemu: machine" if argv[0] == "serve" else ""
        assert ready.startswith(expected) and ("127.0.0.1:" in ready), \
            process.stderr.read() if process.stderr else ready
    finally:
        process.terminate()
        process.wait(timeout=20)


# ------------------------------------------------------------------------ bad input -> answer
BINARY = "capture.pcapng"   # a pcap where text is expected
# (argv, what the one line must say); {port}: the test emulator; {dead}: nothing listening;
# {tmp}: a scratch directory; {capture}: a capture file; {binary}: a binary file
BAD_INPUT = [
    # tracebacks before
    (["trace", "replay", "{capture}", "--emulator", "127.0.0.1:{dead}"], "cannot connect to 127.0.0.1:"),
    (["serve", "--machine", "{binary}", "--port", "0"], "not a text file"),
    (["discover", "{binary}"], "not a text file"),
    (["discover", "{recording}", "--model", "{binary}"], "not a text file"),
    (["simulate", "--model", "{model}", "--inputs", "{binary}"], "not a text file"),
    (["simulate", "--model", "{binary}", "--inputs", "{recording}"], "not a text file"),
    (["plc", "run", "fixtures/plc/tc_z.awl", "--machine", "{binary}"], "not a text file"),
    (["serve", "--lec", "{tmp}/missing.mpf", "--port", "0"], "missing.mpf: cannot read"),
    (["discover", "{recording}", "--json-out", "/nonexistent/x.json"], "/nonexistent does not exist"),
    (["discover", "{recording}", "--report", "/nonexistent/x.html"], "/nonexistent does not exist"),
    (["simulate", "--model", "{model}", "--inputs", "{recording}", "--out", "/nonexistent/x.csv"],
     "/nonexistent does not exist"),
    (["plc", "stubs", "{recording}"], "is not a directory"),
    (["plc", "stubs", "/proc/nope"], "cannot write the stub sources"),
    # messages that pointed the wrong way
    (["put", "--port", "{port}", "SD43900[AX4]=1e9"], "1e+09 mm is outside its limits -1000..1000 mm"),
    (["put", "--port", "{port}", "SD43900[AX4]=nan"], "not a finite number"),
    (["put", "--port", "{port}", "SD43900[AX4]=inf"], "not a finite number"),
    (["put", "--port", "{port}", "SD43910[AX4]=5"], "5 is outside its limits -0.1..0.1"),
    (["put", "--port", "{port}", "--password", "SUNRISE", "MD32750[AX4]=99"], "99 is outside its limits 0..7"),
    (["put", "--port", "{port}", "--password", "WRONG", "SD43900[AX4]=1"], "password refused"),
    (["lec", "--port", "{port}", "--password", "WRONG", "fixtures/lec/z_axis.mpf"], "password refused"),
    (["pi", "--port", "{port}", "_N_LOGIN_", "/NC", "WRONG"], "incorrect password entered (header error 0xD602)"),
    (["lec", "--port", "{port}", "fixtures/lec/z_axis.mpf"], "access level is too low"),
    (["serve", "--record", "/nonexistent/dir/x.pcapng", "--port", "0"], "/nonexistent/dir does not exist"),
    (["comp840c", "--port", "{port}", "--db", "999", "--axis", "4", "--k0", "0.3"], "user DB999 does not exist"),
    (["comp840c", "--port", "{port}", "--axis", "4", "--k0", "0.3", "--flags", "UA"], "needs --p0"),
    (["pi", "--port", "{port}", "_N_NO_SUCH_SERVICE"], "service not implemented on the module"),
    (["get", "--port", "{port}", "SD43900"], "SD43900 is an axis variable: say which axis"),
    # silent acceptance
    (["serve", "--port", "99999"], "99999 is outside 1..65535"),
    (["get", "--port", "70000", "R5"], "70000 is outside 1..65535"),
    (["lec", "--port", "{port}", "--password", "EVENING", "{tmp}/empty.mpf"], "no leadscrew table in it"),
    (["serve", "--lec", "{tmp}/empty.mpf", "--port", "0"], "no leadscrew table in it"),
    (["serve", "--machine", "{tmp}/unknown_key.toml", "--port", "0"], "field 'axis[0].colour': unknown key"),
    (["serve", "--machine", "{tmp}/piw.toml", "--port", "0"], "PIW99999: the input area has bytes"),
    (["trace", "show", "{capture}", "--connection", "99"], "--connection 99: the capture has no such connection"),
    (["trace", "replay", "{capture}", "--timeout", "0"], "--timeout 0.0: expected a positive number"),
    (["discover", "{recording}", "--json", "out.json"], "unrecognized arguments: out.json"),
    (["machine", "show", "--machine", "{tmp}/missing.toml"], "missing.toml: cannot read"),
    # and the ordinary ones, kept so
    (["trace", "show", "{recording}"], "not a pcap or pcapng file"),
    (["trace", "show", "{tmp}/missing.pcapng"], "cannot read"),
    (["get", "--port", "{port}", "FOO[AX1]"], "unknown NCK variable 'FOO'"),
    (["get", "--port", "{dead}", "R5"], "cannot connect to 127.0.0.1:"),
    (["get", "--port", "{port}", "--timeout", "0", "R5"], "expected a positive number of seconds"),
    (["put", "--port", "{port}", "SD43900[AX4]=abc"], "'abc' is not a REAL8 value"),
    (["comp840c", "--port", "{port}", "--axis", "4", "--flags", "Q"], "only U and A"),
    (["serve", "--state", "/nonexistent/s.json", "--port", "0"], "/nonexistent does not exist"),
    (["discover", "{tmp}/missing.csv"], "missing.csv: cannot read"),
    (["vars", "NO_SUCH_THING"], "no NCK variable name or number matches"),
    (["plc", "run", "{tmp}/empty.awl"], "the program is empty"),
    (["plc", "run", "{tmp}/no_ob1.awl"], "no ORGANIZATION_BLOCK OB 1"),
]


@pytest.fixture
def bad_input_files(tmp_path: Path, capture: Path) -> dict[str, str]:
    (tmp_path / "empty.mpf").write_text("")
    (tmp_path / "empty.awl").write_text("\n")
    (tmp_path / "no_ob1.awl").write_text("FUNCTION FC 1 : VOID\nBEGIN\nEND_FUNCTION\n")
    (tmp_path / "unknown_key.toml").write_text('name = "m"\n[[axis]]\nnumber = 1\nname = "X1"\ncolour = "red"\n')
    (tmp_path / "piw.toml").write_text('name = "m"\n[[sensor]]\nname = "bed"\nplc_input = "PIW99999"\n')
    recording = tmp_path / "rec.csv"
    write_recording(recording, make_scenario("thermal_gradient").recording)
    return {"tmp": str(tmp_path), "capture": str(capture), "binary": str(capture), "recording": str(recording),
            "model": str(FIXTURES / "thermal" / "baseline_spindle_bed.toml"), "dead": str(_free_port())}


@pytest.mark.parametrize(("argv", "answer"), BAD_INPUT, ids=[" ".join(a)[:70] for a, _ in BAD_INPUT])
def test_bad_input_is_one_clear_line(argv: list[str], answer: str, bad_input_files: dict[str, str],
                                     emulator: EmulatorThread, capfd, monkeypatch: pytest.MonkeyPatch) -> None:
    values = {**bad_input_files, "port": str(emulator.port)}
    argv = [a.format(**values) for a in argv]
    monkeypatch.chdir(REPO)
    code = main(argv)
    out, err = capfd.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 1, f"nckemu {' '.join(argv)}: exit {code}\n{err}"
    assert len(lines) == 1, f"nckemu {' '.join(argv)}: expected one line, got:\n{err}"
    assert answer in lines[0]
    assert "Traceback" not in err
    assert not out.strip() or argv[0] == "put"  # put may list the items that did land
    assert not Path("/nonexistent").exists()


def test_replay_against_a_silent_server_gives_up_per_job(capture: Path, silent_server: int, capsys) -> None:
    # Issue 26: a server that never answers the connection request is given up there, with one line
    # naming its address (it used to cost a job timeout per job and a report of missing answers).
    started = time.monotonic()
    code = main(["trace", "replay", str(capture), "--emulator", f"127.0.0.1:{silent_server}", "--timeout", "0.2"])
    elapsed = time.monotonic() - started
    assert code == 1
    out, err = capsys.readouterr()
    assert not out and len(err.splitlines()) == 1 and f"127.0.0.1:{silent_server}" in err
    assert "did not answer the connection request" in err
    assert elapsed < 10


def test_verbose_and_log_file_after_the_command(tmp_path: Path, emulator: EmulatorThread) -> None:
    log_file = tmp_path / "nckemu.log"
    assert main(["get", "--port", str(emulator.port), "R5", "-v", "--log-file", str(log_file)]) == 0
    assert log_file.exists()


def test_environment_sets_the_default_port(emulator: EmulatorThread, monkeypatch, capsys) -> None:
    monkeypatch.setenv("NCKEMU_PORT", str(emulator.port))
    monkeypatch.setenv("NCKEMU_HOST", "127.0.0.1")
    assert main(["get", "MD32700[1,AX4]"]) == 0
    assert capsys.readouterr().out.startswith("MD32700 ENC_COMP_ENABLE[1,AX4] = ")


def test_machine_show_documents_the_default_memory(capsys) -> None:
    assert main(["machine", "show"]) == 0
    out = capsys.readouterr().out
    assert "DB41: 64, DB100: 256, DB130: 256, DB131: 64" in out
