"""The live page shows the part program: its name, the block and line running, and the time left (the
last complete run's net time less this run's), over HTTP as a browser fetches it and in headless chromium."""

from __future__ import annotations

import json
import time
import urllib.request
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from nckemu.clients.sync import NckClient
from tests.support.browser import Browser, needs_browser
from tests.support.live_tools import serve

# 10 dwells of 60 s: 600 s simulated, one wall second at 600x; each block on its own line
PROGRAM = "".join(f"N{10 * n} G4 F60 ; dwell {n}\n" for n in range(1, 11)) + "N200 M30\n"


def _status(http: int) -> dict[str, Any]:
    with urllib.request.urlopen(f"http://127.0.0.1:{http}/status.json", timeout=10) as answer:
        return json.loads(answer.read())["channel"]  # type: ignore[no-any-return]


def _wait(predicate: Callable[[], bool], timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


@contextmanager
def _served_program(tmp_path: Path) -> Iterator[tuple[int, NckClient]]:
    program = tmp_path / "WARM.MPF"
    program.write_text(PROGRAM)
    with serve("--program", str(program), "--speed", "600x", "--http", "0") as served:
        with NckClient("127.0.0.1", served.port, slot=2) as plc:
            yield int(served.ready["http"]), plc  # type: ignore[call-overload]


def _nc_start(plc: NckClient) -> None:
    plc.db_write(21, 7, b"\x00")
    plc.db_write(21, 7, b"\x02")                  # DB21.DBX7.1 rising edge: NC start


@pytest.mark.timeout(120)
def test_status_shows_program_line_and_time_left(tmp_path: Path) -> None:
    with _served_program(tmp_path) as (http, plc):
        channel = _status(http)
        assert channel["selected"] == "/_N_MPF_DIR/_N_WARM_MPF" and channel["status"] == "reset"
        assert channel["time_left_s"] is None
        _nc_start(plc)
        _wait(lambda: _status(http)["status"] == "active")
        first = _status(http)
        # the first run: nothing to count down from yet
        assert first["time_left_s"] is None and first["last_run_s"] is None
        assert first["block_program"] == "/_N_MPF_DIR/_N_WARM_MPF" and 1 <= first["line"] <= 11
        assert first["block"].startswith("N") and first["block_number"].startswith("N")
        _wait(lambda: _status(http)["status"] == "reset")
        _nc_start(plc)
        _wait(lambda: _status(http)["status"] == "active")
        second = _status(http)
        assert second["last_run_s"] == pytest.approx(600.0, abs=1.0)
        assert second["time_left_s"] == pytest.approx(600.0 - second["net_time_s"], abs=15.0)
        assert 0.0 <= second["time_left_s"] <= 600.0
        _wait(lambda: (_status(http)["time_left_s"] or 600.0) < 300.0)       # it counts down
        line = _status(http)["line"]
        assert line >= 5, "half the time gone: the run is in its second half of lines"


@needs_browser
@pytest.mark.timeout(240)
def test_page_shows_program_line_and_time_left_in_chromium(tmp_path: Path) -> None:
    with _served_program(tmp_path) as (http, plc):
        _nc_start(plc)
        _wait(lambda: _status(http)["actual_parts"] >= 1 and _status(http)["status"] == "reset")
        _nc_start(plc)
        _wait(lambda: _status(http)["status"] == "active")
        plc.db_write(21, 7, b"\x08")              # NC stop: the run holds, the page has time to look
        _wait(lambda: _status(http)["status"] == "interrupted")
        with Browser() as browser:
            browser.open(f"http://127.0.0.1:{http}/")
            assert browser.wait_for("document.getElementById('channel').innerText.includes('WARM.MPF')")
            assert browser.wait_for("/time left\\s+\\d\\d:\\d\\d:\\d\\d/.test("
                                    "document.getElementById('channel').innerText)")
            text = browser.script("return document.getElementById('channel').innerText")
            assert "part program" in text and "WARM.MPF line" in text and "G4 F60" in text
