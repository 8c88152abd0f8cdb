"""`serve --http`: the live page over plain HTTP (urllib) and in a real headless chromium, while a
recording plays at 600x with the PLC program running and a python-snap7 client polls."""

from __future__ import annotations

import json
import struct
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import snap7

from tests.support.browser import Browser, needs_browser
from tests.support.live_tools import MACHINE, PROGRAM, poll, serve, write_recording


def _get(port: int, path: str) -> tuple[int, str, bytes]:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=10) as answer:
            return answer.status, answer.headers["Content-Type"], answer.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.headers["Content-Type"], exc.read()


class Poller(threading.Thread):
    """A python-snap7 client polling the machine until stopped (it shows on the page with its rate)."""

    def __init__(self, port: int) -> None:
        super().__init__(daemon=True)
        self.port = port
        self.polls = 0
        self.done = threading.Event()

    def run(self) -> None:
        client = snap7.Client()
        client.connect("127.0.0.1", 0, 4, self.port)
        try:
            while not self.done.is_set():
                poll(client, ref=self.polls % 60000 + 1)
                self.polls += 1
                time.sleep(0.02)
        finally:
            client.disconnect()


@contextmanager
def live_page(tmp_path: Path) -> Iterator[int]:
    """A machine living at 600x with the PLC program and a polling client; the page's port."""
    recording = write_recording(tmp_path / "rec.csv", hours=4.0)
    with serve("--machine", str(MACHINE), "--inputs", str(recording), "--plc", str(PROGRAM), "--speed", "600x",
               "--http", "0") as served:
        poller = Poller(served.port)
        poller.start()
        try:
            yield int(served.ready["http"])  # type: ignore[call-overload]
        finally:
            poller.done.set()
            poller.join(timeout=10)


def test_page_status_and_events(tmp_path: Path) -> None:
    with live_page(tmp_path) as http:
        time.sleep(2.5)
        status, kind, page = _get(http, "/")
        assert status == 200 and kind.startswith("text/html") and b'<canvas id="tc-plot"' in page
        assert b'<script src="plot.js">' in page
        assert b"http://" not in page and b"https://" not in page, "no CDN: the machines have no internet"
        status, kind, script = _get(http, "/plot.js")
        assert status == 200 and b"function drawPlot" in script
        status, kind, body = _get(http, "/status.json")
        document = json.loads(body)
        assert status == 200 and kind == "application/json"
        assert [a["name"] for a in document["axes"]] == ["X1", "Y1", "SP1", "Z1"]
        assert {s["name"] for s in document["sensors"]} == {"bed", "spindle"}
        assert document["live"]["plc"] == "RUN" and document["live"]["jobs"]["PUT"] > 10
        assert document["speed"] == 600.0 and document["t_s"] > 600.0
        bed = next(s for s in document["sensors"] if s["name"] == "bed")
        assert bed["raw"] == round(276.48 * bed["temperature_C"])
        rates = [c["jobs_per_s"] for c in document["clients"]]
        assert len(rates) == 2 and max(rates) > 5.0, document["clients"]  # the PLC and the poller
        assert _get(http, "/nothing")[0] == 404
        with urllib.request.urlopen(f"http://127.0.0.1:{http}/events", timeout=10) as events:
            assert events.headers["Content-Type"] == "text/event-stream"
            lines = [events.readline() for _ in range(4)]
            assert lines[2] == b"event: history\n" and lines[3].startswith(b"data: {")
            history = json.loads(lines[3][6:])
            assert len(history["points"]) >= 4 and history["status"]["machine"] == "loop mill"
            while events.readline() != b"event: status\n":
                pass
            assert json.loads(events.readline()[6:])["live"]["cycles"] > 0


@needs_browser
@pytest.mark.timeout(240)
def test_page_in_headless_chromium(tmp_path: Path) -> None:
    with live_page(tmp_path) as http:
        with Browser() as browser:
            browser.open(f"http://127.0.0.1:{http}/")
            assert browser.wait_for("Number(document.getElementById('temp-plot').dataset.points) > 20")
            time.sleep(1.0)
            state = browser.script("""return {
                machine: document.getElementById('machine').textContent,
                head: document.getElementById('head').textContent,
                axes: document.getElementById('axes').innerText,
                sensors: document.getElementById('sensors').innerText,
                plc: document.getElementById('plc').innerText,
                clients: document.getElementById('clients').innerText,
                tcPoints: Number(document.getElementById('tc-plot').dataset.points),
                tempPoints: Number(document.getElementById('temp-plot').dataset.points),
                axesHead: [...document.querySelectorAll('#axes th')].map(th => th.innerText.replace(/\\s+/g, ' ')),
                channel: document.getElementById('channel').innerText,
                xticks: document.getElementById('tc-plot').dataset.xticks,
                steps: [niceTimeStep(20000, 6), niceTimeStep(36 * 3600, 6), niceTimeStep(700, 6), niceTimeStep(90, 6)],
                colors: (() => {  // the TC plot's pixels: the pale band (TC applied) and the full colour (SD43900)
                    const canvas = document.getElementById('tc-plot');
                    const data = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
                    let full = 0, pale = 0;  // the canvas is transparent: the band is the colour at low alpha
                    for (let i = 0; i < data.length; i += 4) {
                        const [r, g, b, a] = [data[i], data[i + 1], data[i + 2], data[i + 3]];
                        if (Math.abs(r - 31) > 12 || Math.abs(g - 119) > 12 || Math.abs(b - 180) > 12) continue;
                        if (a >= 120) full++;  // a 1.5 px line covers a pixel row by half or more
                        else if (a > 50 && a < 110) pale++;
                    }
                    return {full, pale};
                })(),
            };""")
            shot = browser.screenshot()
    assert state["machine"] == "loop mill"
    assert "simulated time" in state["head"] and "600x" in state["head"] and "recording time" in state["head"]
    assert "Z1" in state["axes"] and "SD43900" in state["axes"]
    assert "bed" in state["sensors"] and "PIW420" in state["sensors"]
    assert "RUN" in state["plc"] and "tc_z.awl" in state["plc"]
    assert state["clients"].count("127.0.0.1:") == 2   # the PLC's own connection and the poller
    assert state["clients"].count("(the PLC program)") == 1
    assert state["tcPoints"] > 20 and state["tempPoints"] > 20
    # issue 37: one unit per quantity, labelled: positions in mm, the compensation (SD43900 as written and
    # as applied) in µm side by side, the slope in µm/m
    head = state["axesHead"]
    assert head[:3] == ["axis", "position mm", "actual mm"] and "SD43900 µm" in head and "TC applied µm" in head
    assert head.index("TC applied µm") == head.index("SD43900 µm") + 1 and "SD43910 µm/m" in head
    assert not any(h.endswith(" um") or h == "SD43900 mm" for h in head)
    # ticks on round clock times (05:33:20 before): 5 min .. 6 h steps
    ticks = state["xticks"].split()
    assert ticks and all(t.endswith(":00") and int(t.split(":")[1]) % 5 == 0 for t in ticks), ticks
    assert state["steps"] == [3600, 21600, 120, 15]
    # the SD43900 line shows over the applied value that follows it (it hid under it)
    assert state["colors"]["full"] > 10 and state["colors"]["pale"] > 10, state["colors"]  # before: no pale pixel
    # the machine's recording turns the spindle: AUTOMATIC, a program runs or has run, parts count
    assert "AUTOMATIC" in state["channel"] and "part time (net)" in state["channel"]
    assert shot[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", shot[16:24])
    assert (width, height) == (1300, 1000) or width > 800
