"""Retained data across restarts of the real server process, including kill -9 in a write burst."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from nckemu.clients import NckClient
from nckemu.errors import NckError

REPO = Path(__file__).resolve().parents[3]


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _serve(port: int, state: Path) -> subprocess.Popen[str]:
    process = subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", str(port), "--state",
                                str(state), "--json"], cwd=REPO, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    assert process.stdout is not None
    line = process.stdout.readline()
    if not line:
        raise AssertionError(f"server did not start: {process.stderr.read() if process.stderr else ''}")
    assert json.loads(line)["port"] == port
    return process


def test_restart_keeps_setting_data(tmp_path: Path) -> None:
    state, port = tmp_path / "state.json", _free_port()
    server = _serve(port, state)
    try:
        with NckClient("127.0.0.1", port) as client:
            client.put({"SD43900[AX4]": 0.3, "SD43920[AX4]": -1000.0, "R7": 7.5})
    finally:
        server.send_signal(signal.SIGINT)
        assert server.wait(timeout=20) == 0
    server = _serve(port, state)
    try:
        with NckClient("127.0.0.1", port) as client:
            assert client.get("SD43900[AX4]", "SD43920[AX4]", "R7") == [0.3, -1000.0, 7.5]
    finally:
        server.send_signal(signal.SIGINT)
        server.wait(timeout=20)


def test_kill9_in_a_write_burst_loses_no_acknowledged_write(tmp_path: Path) -> None:
    state, port = tmp_path / "state.json", _free_port()
    server = _serve(port, state)
    acknowledged = 0
    try:
        with NckClient("127.0.0.1", port, timeout_s=2.0) as client:
            deadline = time.monotonic() + 0.6
            while time.monotonic() < deadline:
                client.put({"R1": float(acknowledged + 1)})
                acknowledged += 1
            os.kill(server.pid, signal.SIGKILL)
            with pytest.raises(NckError):
                for _ in range(1000):
                    client.put({"R1": -1.0})
    finally:
        server.wait(timeout=20)
    assert acknowledged > 10
    server = _serve(port, state)  # the state file must load
    try:
        with NckClient("127.0.0.1", port) as client:
            (value,) = client.get("R1")
        assert value >= acknowledged  # what was acknowledged is on disk (a later unacknowledged one may be too)
    finally:
        server.send_signal(signal.SIGINT)
        server.wait(timeout=20)


def test_damaged_state_file_is_refused_not_replaced(tmp_path: Path) -> None:
    state = tmp_path / "state.json"
    state.write_text("{not json")
    result = subprocess.run([sys.executable, "-m", "nckemu", "serve", "--port", str(_free_port()), "--state",
                             str(state)], cwd=REPO, capture_output=True, text=True, timeout=30)
    assert result.returncode != 0
    assert "state.json" in result.stderr and "damaged" in result.stderr
    assert state.read_text() == "{not json"
