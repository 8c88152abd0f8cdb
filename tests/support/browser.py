"""Debian's headless chromium driven through chromedriver's W3C WebDriver HTTP API with urllib (no
Python dependency). `make test` installs both when root; without them the browser tests skip."""

from __future__ import annotations

import base64
import json
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.error
import urllib.request
from typing import Any

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
needs_browser = pytest.mark.skipif(CHROMIUM is None or CHROMEDRIVER is None,
                                   reason="Debian's chromium and chromium-driver are not installed (make chromium)")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Browser:
    """``with Browser() as b: b.open(url); b.script("return document.title")``."""

    def __init__(self, width: int = 1300, height: int = 1000) -> None:
        self.width, self.height = width, height
        self.port = _free_port()
        self.profile = tempfile.TemporaryDirectory(prefix="nckemu-chromium-")
        self.driver: subprocess.Popen[bytes] | None = None
        self.session = ""

    def _call(self, method: str, path: str, body: Any = None, timeout_s: float = 60.0) -> Any:
        data = None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(f"http://127.0.0.1:{self.port}{path}", data=data, method=method,
                                         headers={"Content-Type": "application/json"})
        try:
            with urllib.request.urlopen(request, timeout=timeout_s) as answer:
                return json.loads(answer.read() or b"{}").get("value")
        except urllib.error.HTTPError as exc:
            raise AssertionError(f"chromedriver {method} {path}: {exc.read()[:500]!r}") from None

    def __enter__(self) -> Browser:
        assert CHROMEDRIVER is not None and CHROMIUM is not None
        self.driver = subprocess.Popen([CHROMEDRIVER, f"--port={self.port}"], stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 20
        while True:
            try:
                self._call("GET", "/status", timeout_s=2)
                break
            except (OSError, AssertionError):
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)
        args = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--disable-background-networking", "--disable-component-update", "--no-first-run",
                f"--user-data-dir={self.profile.name}", f"--window-size={self.width},{self.height}"]
        value = self._call("POST", "/session", {"capabilities": {"alwaysMatch": {
            "browserName": "chrome", "goog:chromeOptions": {"binary": CHROMIUM, "args": args}}}})
        self.session = value["sessionId"]
        return self

    def open(self, url: str) -> None:
        self._call("POST", f"/session/{self.session}/url", {"url": url})

    def script(self, source: str) -> Any:
        return self._call("POST", f"/session/{self.session}/execute/sync", {"script": source, "args": []})

    def wait_for(self, source: str, timeout_s: float = 30.0) -> Any:
        """Evaluate ``source`` (a JS expression) until it is truthy; its value."""
        deadline = time.monotonic() + timeout_s
        while True:
            value = self.script(f"return ({source});")
            if value or time.monotonic() > deadline:
                return value
            time.sleep(0.25)

    def screenshot(self) -> bytes:
        return base64.b64decode(self._call("GET", f"/session/{self.session}/screenshot"))

    def __exit__(self, *exc: object) -> None:
        try:
            if self.session:
                self._call("DELETE", f"/session/{self.session}", timeout_s=20)
        finally:
            if self.driver is not None:
                self.driver.terminate()
                try:
                    self.driver.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.driver.kill()
            self.profile.cleanup()
