"""``serve --http PORT``: one page for people, showing the served machine live.

A small HTTP/1.1 server on asyncio (standard library only): ``/`` the page, ``/plot.js`` its own
canvas plotting code (shipped here: the machines have no internet), ``/status.json`` the machine now
(``status.machine_status`` plus each client's job rate), ``/events`` server-sent events: first the
history kept so far (event ``history``), then the status twice a second (event ``status``). The
history is sampled on the wall clock whether or not a page is open, so a page opened late still
plots what went before (the last ``HISTORY_POINTS`` samples).
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from collections import deque
from importlib import resources
from typing import Any

from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.status import ClientList, machine_status

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.web")

SAMPLE_PERIOD_S = 0.5
HISTORY_POINTS = 1200
MAX_REQUEST_BYTES = 8192
MAX_SUBSCRIBERS = 32
_FILES = {"/": ("page.html", "text/html; charset=utf-8"),
          "/index.html": ("page.html", "text/html; charset=utf-8"),
          "/plot.js": ("plot.js", "text/javascript; charset=utf-8")}


def history_point(status: dict[str, Any]) -> dict[str, Any]:
    """What the plots need of one status: time, compensation and temperatures."""
    return {"t_s": status["t_s"],
            "tc_um": {a["name"]: None if a.get("tc_mm") is None else a["tc_mm"] * 1000.0
                      for a in status["axes"] if not a["spindle"]},
            "sd43900_um": {a["name"]: None if a.get("sd43900_mm") is None else a["sd43900_mm"] * 1000.0
                           for a in status["axes"] if not a["spindle"]},
            "temperature_C": {s["name"]: s["temperature_C"] for s in status["sensors"]}}


class WebFace:
    """The live page of one served machine; ``await start()`` / ``await stop()`` on the running loop."""

    what = "--http"

    def __init__(self, emulator: Emulator, server: ClientList | None = None, *, host: str = "127.0.0.1",
                 port: int = 0, sample_period_s: float = SAMPLE_PERIOD_S) -> None:
        self.emulator = emulator
        self.server = server
        self.host = host
        self.requested_port = port
        self.sample_period_s = sample_period_s
        self.history: deque[dict[str, Any]] = deque(maxlen=HISTORY_POINTS)
        self._subscribers: set[asyncio.StreamWriter] = set()
        self._rates: dict[str, tuple[int, float, float]] = {}   # peer -> jobs, wall time, rate
        self._latest: dict[str, Any] | None = None
        self._http: asyncio.AbstractServer | None = None
        self._sampler: asyncio.Task[None] | None = None
        self._files = {path: (resources.files(__package__).joinpath(name).read_bytes(), kind)
                       for path, (name, kind) in _FILES.items()}

    @property
    def port(self) -> int:
        if self._http is None or not self._http.sockets:
            return self.requested_port
        return int(self._http.sockets[0].getsockname()[1])

    @property
    def ready(self) -> dict[str, Any]:
        return {"http": self.port}

    @property
    def ready_line(self) -> str:
        return f"live page: http://{self.host}:{self.port}/"

    async def start(self) -> WebFace:
        self._http = await asyncio.start_server(self._handle, self.host, self.requested_port, reuse_address=True)
        self._sample()
        self._sampler = asyncio.create_task(self._sample_forever(), name="nckemu-web")
        log.info("live page on http://%s:%d/", self.host, self.port)
        return self

    async def stop(self) -> None:
        if self._sampler is not None:
            self._sampler.cancel()
            self._sampler = None
        for writer in list(self._subscribers):
            writer.close()
        self._subscribers.clear()
        if self._http is not None:
            self._http.close()
            await self._http.wait_closed()
            self._http = None

    # ------------------------------------------------------------------ sampling
    def status(self) -> dict[str, Any]:
        """The machine now, each client with its job rate (jobs per wall second since the last sample)."""
        document = machine_status(self.emulator, self.server)
        now = time.monotonic()
        rates: dict[str, tuple[int, float, float]] = {}
        for client in document["clients"]:
            peer = client["peer"]
            jobs, then, rate = self._rates.get(peer, (client["jobs"], now, 0.0))
            if now - then >= 0.2:
                rate = (client["jobs"] - jobs) / (now - then)
                jobs, then = client["jobs"], now
            rates[peer] = (jobs, then, rate)
            client["jobs_per_s"] = rate
        self._rates = rates
        return document

    def _sample(self) -> dict[str, Any]:
        status = self.status()
        self._latest = status
        self.history.append(history_point(status))
        return status

    async def _sample_forever(self) -> None:
        while True:
            await asyncio.sleep(self.sample_period_s)
            try:
                status = self._sample()
            except Exception:  # noqa: BLE001 - the page must not take the machine down
                log.exception("live page: status failed")
                continue
            if self._subscribers:
                self._publish(b"status", status)

    def _publish(self, event: bytes, document: Any) -> None:
        message = b"event: " + event + b"\ndata: " + json.dumps(document).encode() + b"\n\n"
        for writer in list(self._subscribers):
            if writer.is_closing() or writer.transport.get_write_buffer_size() > 1 << 20:
                self._subscribers.discard(writer)  # gone, or not reading: let it go
                writer.close()
                continue
            writer.write(message)

    # ------------------------------------------------------------------ HTTP
    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), 10.0)
        except (asyncio.IncompleteReadError, asyncio.LimitOverrunError, TimeoutError, ConnectionError):
            writer.close()
            return
        request_line = head.split(b"\r\n", 1)[0].decode("latin-1")
        parts = request_line.split()
        if len(parts) != 3 or len(head) > MAX_REQUEST_BYTES:
            await self._reply(writer, 400, b"text/plain", b"bad request\n")
            return
        method, target = parts[0], parts[1].split("?", 1)[0]
        if method not in ("GET", "HEAD"):
            await self._reply(writer, 405, b"text/plain", b"only GET\n")
            return
        if target == "/events":
            await self._events(writer)
            return
        if target == "/status.json":
            body = json.dumps(self._latest if self._latest is not None else self._sample()).encode()
            await self._reply(writer, 200, b"application/json", body, head_only=method == "HEAD")
            return
        found = self._files.get(target)
        if found is None:
            await self._reply(writer, 404, b"text/plain", b"not found\n")
            return
        await self._reply(writer, 200, found[1].encode(), found[0], head_only=method == "HEAD")

    @staticmethod
    async def _reply(writer: asyncio.StreamWriter, code: int, kind: bytes, body: bytes, head_only: bool = False) -> None:
        reason = {200: b"OK", 400: b"Bad Request", 404: b"Not Found", 405: b"Method Not Allowed",
                  503: b"Service Unavailable"}[code]
        writer.write(b"HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %d\r\nCache-Control: no-store\r\n"
                     b"Connection: close\r\n\r\n" % (code, reason, kind, len(body)))
        if not head_only:
            writer.write(body)
        try:
            await writer.drain()
        except ConnectionError:
            pass
        writer.close()

    async def _events(self, writer: asyncio.StreamWriter) -> None:
        if len(self._subscribers) >= MAX_SUBSCRIBERS:
            await self._reply(writer, 503, b"text/plain", b"too many pages open\n")
            return
        writer.write(b"HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\n"
                     b"Connection: keep-alive\r\n\r\nretry: 2000\n\n")
        history = {"points": list(self.history), "status": self._latest}
        writer.write(b"event: history\ndata: " + json.dumps(history).encode() + b"\n\n")
        self._subscribers.add(writer)
        try:
            await writer.drain()
        except ConnectionError:
            self._subscribers.discard(writer)
            writer.close()
