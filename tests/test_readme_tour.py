"""The README tour as written, in a fresh copy of the repository where `make serve` is the only set-up
(issue 15): its own .venv (pip's cache makes the install quick), the emulator it starts, and the tour's
shell block run with bash -e. Only the ports are the test's."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def tour_block(readme: str) -> str:
    block = readme.split("<!-- tour -->", 1)[1].split("<!-- end tour -->", 1)[0]
    return block.split("```sh\n", 1)[1].split("```", 1)[0]


def test_tour_block_is_in_the_readme() -> None:
    block = tour_block((REPO / "README.md").read_text(encoding="utf-8"))
    assert "nckemu plc run" in block and "nckemu discover" in block


def _fresh_copy(target: Path) -> None:
    files = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, check=True, stdout=subprocess.PIPE).stdout
    for name in filter(None, files.decode().split("\0")):
        source = REPO / name
        if source.is_file():
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / name)


def test_readme_tour_after_make_serve(tmp_path: Path) -> None:
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    clone = tmp_path / "nckemu"
    _fresh_copy(clone)
    serve_port, record_port, opcua_port = _free_port(), _free_port(), _free_port()
    env = {key: value for key, value in os.environ.items() if key not in ("VIRTUAL_ENV", "PYTHONPATH")}
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if ".venv" not in p)
    serve = subprocess.Popen(["make", "serve", f"PORT={serve_port}", f"OPCUA_PORT={opcua_port}"], cwd=clone, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        seen = []
        deadline = time.monotonic() + 1500
        assert serve.stdout is not None
        while time.monotonic() < deadline:
            line = serve.stdout.readline()
            if not line:
                pytest.fail("make serve ended before the emulator was ready:\n" + "".join(seen[-30:]))
            seen.append(line)
            if line.startswith("nckemu: machine"):
                break
        block = tour_block((clone / "README.md").read_text(encoding="utf-8"))
        script = block.replace("1102", str(serve_port)).replace("1103", str(record_port)).replace(
            "4840", str(opcua_port))
        tour = subprocess.run(["bash", "-e", "-c", script], cwd=clone, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=600)
        assert tour.returncode == 0, tour.stdout[-4000:]
        out = tour.stdout
        assert "CPU 317-2 PN/DP (NCU PLC)" in out                       # python-snap7's get_cpu_info
        assert "SD43900 TEMP_COMP_ABS_VALUE[AX4] = 0.300000 mm" in out   # get after put
        assert "\n0.3\n" in out                                           # uaread: the same value over OPC UA
        assert "SD43900 TEMP_COMP_ABS_VALUE[AX4] := 0.300000 mm" in out  # trace show of the recording
        assert "0 values differ" in out                                  # trace replay
        assert "FB3 PUT jobs" in out and "TC of axis 4" in out           # plc run (awlsim after make serve)
        assert '"gain": 1.29' in out and (clone / "out.json").is_file() and (clone / "out.html").is_file()
    finally:
        os.killpg(serve.pid, signal.SIGTERM)
        serve.wait(timeout=30)
