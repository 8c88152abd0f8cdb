"""Hostile input on the OPC UA face while both faces serve others: mutated messages of every type the
face takes, wrong sizes and sequence numbers, half-open connections, oversized messages, session,
subscription, monitored-item and publish floods, bad passwords and certificates.

The server is ``nckemu serve --opcua`` in its own process. Valid messages are built with asyncua's own
encoders (bench/opcua_wire.py) and then mutated. Throughout, a python-snap7 client and an asyncua client
(each in a process of its own) poll the two faces; every poll must be served, none may wait long.

A case is one mutated message (plus a valid read behind it, to see the connection still works) or one
step of a named attack. Each ends answered (an OPC UA response or error), closed by the server, or
waiting (the server waits for the rest of a message it was promised): a waiting connection is left
open, and the server must close it by itself within its partial-message timeout (``stuck`` counts
those it did not, with what was sent on them; ``late_answers`` those answered after all, later than
the probe waited, with nothing left pending). Crashes: the server process died. Internal errors:
tracebacks in its log.

Usage: .venv/bin/python bench/fuzz_opcua.py [--size small|full] [--cases N] [--seed 1] [--json]
Loopback only; bounded by --cases and --seconds.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing as mp
import random
import re
import struct
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bench_server import percentile, process_figures  # noqa: E402
from bench.opcua_wire import Answer, Wire  # noqa: E402

SIZES = {"small": 1_500, "medium": 20_000, "full": 100_000}
HOST = "127.0.0.1"
PARTIAL_TIMEOUT_S = 10.0  # the face's: a begun message must complete (faces/opcua/transport.py)
ANSWER_S = 3.0
SESSION_KINDS = ("read", "write", "browse", "call", "subscribe", "monitor", "publish", "close")
OPENING_KINDS = ("hello", "open", "create_session", "activate")


# ------------------------------------------------------------------ the server and its watchers
def start_server(log: Path, extra: list[str] | None = None) -> tuple[subprocess.Popen[str], int, str]:
    command = [sys.executable, "-m", "nckemu", "serve", "--port", "0", "--opcua", "0", "--json",
               "--max-connections", "128", *(extra or [])]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=log.open("w"), text=True)
    assert process.stdout is not None
    line = process.stdout.readline()
    if not line:
        raise RuntimeError(f"the server did not start: {log.read_text()[-2000:]}")
    ready = json.loads(line)
    return process, int(ready["port"]), ready["opcua"]


def s7_watcher(port: int, stop: Any, out: Any) -> None:
    """python-snap7 reads a DB word and the CPU state in a loop: latencies and failures."""
    import snap7

    latencies: list[float] = []
    slow: list[tuple[float, float]] = []
    failures = 0
    client = snap7.client.Client()
    client.connect(HOST, 0, 2, port)
    while not stop.is_set():
        started = time.perf_counter()
        try:
            client.db_read(130, 0, 4)
            latencies.append(time.perf_counter() - started)
            if latencies[-1] > 0.5:
                slow.append((round(time.time(), 1), round(latencies[-1], 2)))
        except Exception:
            failures += 1
            time.sleep(0.1)
            try:
                client.disconnect()
                client.connect(HOST, 0, 2, port)
            except Exception:
                pass
        time.sleep(0.002)
    client.disconnect()
    out.put(("s7", latencies, failures, slow))


def ua_watcher(url: str, stop: Any, out: Any) -> None:
    """asyncua's client reads a node in a loop (one session throughout): latencies and failures."""
    from asyncua import Client, ua

    slow: list[tuple[float, float]] = []

    async def go() -> tuple[list[float], int]:
        latencies: list[float] = []
        failures = 0
        # asyncua 2.x's client takes its connection for lost when its server probe (each watchdog interval, 1 s by
        # default) is answered slower than the interval, as on loaded cores: probe within the timeout instead.
        async with Client(url, timeout=10, watchdog_intervall=10.0) as client:
            node = client.get_node(ua.NodeId("/Channel/State/progStatus", 2))
            while not stop.is_set():
                started = time.perf_counter()
                try:
                    await node.read_value()
                    latencies.append(time.perf_counter() - started)
                    if latencies[-1] > 0.5:
                        slow.append((round(time.time(), 1), round(latencies[-1], 2)))
                except Exception:
                    failures += 1
                await asyncio.sleep(0.005)
        return latencies, failures

    latencies, failures = asyncio.run(go())
    out.put(("opcua", latencies, failures, slow))


# ------------------------------------------------------------------ mutations
def mutate(rng: random.Random, data: bytes) -> tuple[bytes, str]:
    """A mutated copy of one message and what was done (framing kept or broken)."""
    message = bytearray(data)
    header = 12 if message[:3] in (b"OPN", b"MSG", b"CLO") else 8
    choice = rng.random()
    if choice < 0.55:  # inside the body, size fixed up: the decoders see it
        for _ in range(rng.randint(1, 4)):
            if len(message) <= header:
                break
            at = rng.randrange(header, len(message))
            way = rng.randrange(7)
            if way == 0:
                message[at] ^= 1 << rng.randrange(8)
            elif way == 1:
                message[at] = rng.choice([0x00, 0x01, 0x7F, 0x80, 0xFF, 0x15, 0x16, 0x0F, 0x8C])
            elif way == 2 and at + 4 <= len(message):  # a length or count field
                message[at:at + 4] = struct.pack("<i", rng.choice(
                    [-1, 0, 1, 0x7FFFFFFF, -0x80000000, 65535, 1 << 20, rng.randint(-5, 100000)]))
            elif way == 3:
                message[at:at] = rng.randbytes(rng.randint(1, 32))
            elif way == 4:
                del message[at:at + rng.randint(1, 16)]
            elif way == 5:
                del message[at:]
            else:
                message[at:at + 8] = rng.randbytes(8)
        message[4:8] = struct.pack("<I", len(message))
        return bytes(message), "body"
    if choice < 0.65:  # the size field lies
        size = rng.choice([0, 1, 7, 8, 11, 12, len(message) - 1, len(message) + 1, len(message) + 100,
                           65535, 65536, 1 << 20, 0x7FFFFFFF, 0xFFFFFFFF, rng.randint(0, 1 << 32)]) & 0xFFFFFFFF
        message[4:8] = struct.pack("<I", size)
        return bytes(message), "size"
    if choice < 0.72:  # truncated: the rest never comes
        return bytes(message[:rng.randrange(1, len(message))]), "truncated"
    if choice < 0.80 and header == 12:  # sequence number, request id, channel or token id
        field = rng.choice([8, 12, 16, 20])
        value = struct.unpack_from("<I", message, field)[0]
        message[field:field + 4] = struct.pack("<I", rng.choice(
            [0, value - 1, value + 2, value, 0xFFFFFFFF, rng.randint(0, 1 << 32) & 0xFFFFFFFF]) & 0xFFFFFFFF)
        return bytes(message), "ids"
    if choice < 0.88:  # chunk type or message type
        if rng.random() < 0.5:
            message[3:4] = rng.choice([b"C", b"A", b"X", b"\x00"])
        else:
            message[0:3] = rng.choice([b"HEL", b"ACK", b"ERR", b"OPN", b"CLO", b"MSG", b"RHE", rng.randbytes(3)])
        return bytes(message), "type"
    if choice < 0.94:  # garbage after a valid message, framed
        garbage = rng.randbytes(rng.randint(0, 200))
        return bytes(message) + b"MSGF" + struct.pack("<I", len(garbage) + 8) + garbage, "trailing"
    return rng.randbytes(rng.randint(1, 300)), "random"


# ------------------------------------------------------------------ the fuzzing clients
@dataclass
class Parked:
    """A connection that got no answer in ANSWER_S, and what was sent on it."""

    since: float
    wire: Wire
    kind: str
    how: str
    data: bytes
    received: int = 0  # bytes that came after all (an answer later than ANSWER_S)


class Fuzzer:
    def __init__(self, url: str, port: int, seed: int, cases: int, seconds: float) -> None:
        self.url, self.port, self.cases, self.deadline = url, port, cases, time.monotonic() + seconds
        self.rng = random.Random(seed)
        self.done = 0
        self.outcomes: Counter[str] = Counter()
        self.by_kind: Counter[str] = Counter()
        self.waiting: list[Parked] = []
        self.stuck = 0
        self.stuck_cases: list[dict[str, Any]] = []  # what was sent, to replay it as a regression test
        self.late = 0  # answered after ANSWER_S, then idle: no message is pending, nothing to close
        self.probe_taken_in = 0  # the probe completed a cut message exactly (answered, not waiting)
        self.closed_in: list[float] = []
        self.handshake_failures = 0

    def _more(self) -> bool:
        return self.done < self.cases and time.monotonic() < self.deadline

    async def _session(self, subscribe: bool) -> Wire | None:
        wire = Wire(self.url)
        user = self.rng.choice([None, ("nckemu", "SUNRISE")])
        got = await wire.handshake(HOST, self.port, *(user or (None, None)))
        if not got.good:
            self.handshake_failures += 1
            wire.close()
            return None
        if subscribe:
            await wire.subscribe()
        return wire

    def _park(self, wire: Wire, kind: str, how: str, data: bytes) -> Parked:
        """A connection the server waits on: it must close it by itself."""
        parked = Parked(time.monotonic(), wire, kind, how, data)
        self.waiting.append(parked)
        return parked

    def _parked(self, wire: Wire) -> bool:
        return any(parked.wire is wire for parked in self.waiting)

    async def janitor(self) -> None:
        """Watch parked connections: closed by the server within the partial timeout, or stuck."""
        while self._more() or self.waiting:
            now = time.monotonic()
            keep = []
            for parked in self.waiting:
                wire = parked.wire
                assert wire.reader is not None
                if wire.reader.at_eof() or wire.writer is None or wire.writer.transport.is_closing():
                    self.closed_in.append(now - parked.since)
                    wire.close()
                elif now - parked.since > PARTIAL_TIMEOUT_S + 5:
                    if parked.received:
                        self.late += 1
                    else:
                        self.stuck += 1
                        self.stuck_cases.append({"kind": parked.kind, "how": parked.how, "hex": parked.data[:512].hex()})
                    wire.close()
                else:
                    keep.append(parked)
            self.waiting = keep
            await asyncio.sleep(0.25)

    async def _watch_eof(self, parked: Parked) -> None:
        assert parked.wire.reader is not None
        try:
            while data := await parked.wire.reader.read(65536):
                parked.received += len(data)
        except (ConnectionError, OSError):
            pass

    def _count(self, kind: str, how: str, got: Answer) -> None:
        self.done += 1
        self.by_kind[kind] += 1
        outcome = {"MSG": "answered", "OPN": "answered", "ACK": "answered", "ERR": "error",
                   "closed": "closed", "silent": "waiting"}.get(got.kind, got.kind)
        self.outcomes[outcome] += 1
        self.outcomes[f"{how}:{outcome}"] += 1

    async def _settle(self, wire: Wire, kind: str, how: str, data: bytes, probe: bool) -> bool:
        """After a mutated message: its outcome; True if the connection is still good to use."""
        skipped = wire.skipped
        if probe:
            wire.send(wire.read())
        got = await wire.until(wire.request_id, ANSWER_S) if probe else await wire.answer(ANSWER_S)
        if got.kind == "silent" and wire.skipped > skipped:
            # A cut message whose missing bytes the probe happened to fill exactly: the server answered
            # that message (under its own request id) and waits for nothing; the probe is gone in it.
            self._count(kind, how, Answer("MSG"))
            self.probe_taken_in += 1
            wire.close()
            return False
        self._count(kind, how, got)
        if got.kind == "silent":
            asyncio.get_running_loop().create_task(self._watch_eof(self._park(wire, kind, how, data)))
            return False
        if got.kind in ("closed", "ERR", "garbled", "aborted"):
            wire.close()
            return False
        return probe and got.kind == "MSG"

    async def opening_case(self) -> None:
        kind = self.rng.choice(OPENING_KINDS)
        wire = Wire(self.url)
        try:
            await wire.connect(HOST, self.port)
        except OSError:
            self.handshake_failures += 1
            return
        steps = OPENING_KINDS.index(kind)
        if steps >= 1:
            wire.send(wire.hello())
            await wire.answer(ANSWER_S)
        if steps >= 2:
            await wire.ask(wire.open(), ANSWER_S)
        if steps >= 3:
            got = await wire.ask(wire.create_session(), ANSWER_S)
            if got.good:
                wire.token = got.decode(__import__("asyncua").ua.CreateSessionResponse).Parameters.AuthenticationToken
        build = {"hello": wire.hello, "open": wire.open, "create_session": wire.create_session,
                 "activate": lambda: wire.activate(*self.rng.choice([(None, None), ("nckemu", "SUNRISE"),
                                                                      ("nckemu", "x"), ("x", "y")]))}[kind]
        data, how = mutate(self.rng, build())
        wire.send(data)
        if data[:4] == b"MSGA":
            # An abort chunk: the server discards that message and answers nothing (Part 6, 6.7.3);
            # a valid one behind it shows the connection is still served.
            how = "abort"
            wire.send(build())
        if await self._settle(wire, kind, how, data, probe=False) or not self._parked(wire):
            wire.close()

    def _build(self, wire: Wire, kind: str) -> bytes:
        """A valid message of ``kind`` on a session's connection."""
        if kind == "write":
            return wire.write(self.rng.uniform(-1, 1))
        if kind == "call":
            return wire.call(self.rng.random() < 0.3)
        if kind == "monitor":
            return wire.monitor(self.rng.randint(1, 3))
        return {"read": wire.read, "browse": wire.browse, "subscribe": wire.create_subscription,
                "publish": wire.publish, "close": wire.close_channel}[kind]()

    async def session_worker(self) -> None:
        wire: Wire | None = None
        while self._more():
            if self.rng.random() < 0.3:
                await self.opening_case()
                continue
            if wire is None:
                wire = await self._session(subscribe=True)
                if wire is None:
                    await asyncio.sleep(0.2)
                    continue
            kind = self.rng.choice(SESSION_KINDS)
            data, how = mutate(self.rng, self._build(wire, kind))
            wire.send(data)
            if not await self._settle(wire, kind, how, data, probe=True):
                if not self._parked(wire):
                    wire.close()
                wire = None
        if wire is not None:
            wire.close()

    async def run(self, workers: int) -> None:
        janitor = asyncio.get_running_loop().create_task(self.janitor())
        await asyncio.gather(*(self.session_worker() for _ in range(workers)))
        await janitor


# ------------------------------------------------------------------ named attacks
async def attacks(url: str, port: int, rng: random.Random, scale: float) -> dict[str, Any]:
    """Each attack: what was sent and what came back (counts of answer kinds and status codes)."""
    from asyncua import ua

    results: dict[str, Any] = {}
    phases: dict[str, float] = {}

    def tally(name: str, got: Answer) -> None:
        phases.setdefault(name, time.time())
        entry = results.setdefault(name, Counter())
        entry[got.kind if got.kind != "MSG" else ua.StatusCode(got.status).name] += 1

    # wrong sequence numbers on a good session: a repeated, a smaller, a skipped one
    for step in range(max(3, int(30 * scale))):
        wire = Wire(url)
        await wire.handshake(HOST, port)
        data = bytearray(wire.read())
        sequence = struct.unpack_from("<I", data, 16)[0]
        data[16:20] = struct.pack("<I", [sequence - 1, sequence - 2, sequence + 5][step % 3])
        wire.send(bytes(data))
        tally("wrong sequence number", await wire.answer(ANSWER_S))
        wire.close()

    # oversized: a chunk larger than the receive buffer; a size that promises gigabytes, then data
    for _ in range(max(2, int(10 * scale))):
        wire = Wire(url)
        await wire.handshake(HOST, port)
        big = bytearray(wire.read())
        big += bytes(70_000)
        big[4:8] = struct.pack("<I", len(big))
        wire.send(bytes(big))
        tally("chunk over the receive buffer", await wire.answer(ANSWER_S))
        wire.close()
        wire = Wire(url)
        await wire.handshake(HOST, port)
        wire.send(b"MSGF" + struct.pack("<I", 0xFFFFFFF0) + bytes(4))
        got = Answer("silent")
        for _ in range(64):  # up to 4 MiB
            try:
                wire.send(bytes(65536))
                assert wire.writer is not None
                await asyncio.wait_for(wire.writer.drain(), 2)
            except (ConnectionError, TimeoutError, AssertionError):
                got = Answer("closed")
                break
        if got.kind != "closed":
            got = await wire.answer(ANSWER_S)
        tally("size field of 4 GiB, then 4 MiB", got)
        wire.close()
        wire = Wire(url)  # intermediate chunks without end
        await wire.handshake(HOST, port)
        got = Answer("silent")
        for _ in range(2000):
            chunk = bytearray(wire.read())
            chunk[3:4] = b"C"
            chunk += bytes(60_000)
            chunk[4:8] = struct.pack("<I", len(chunk))
            try:
                wire.send(bytes(chunk))
                assert wire.writer is not None
                await asyncio.wait_for(wire.writer.drain(), 2)
            except (ConnectionError, TimeoutError, AssertionError):
                got = Answer("closed")
                break
            wire.request_id -= 1  # every chunk belongs to one request
        if got.kind != "closed":
            got = await wire.answer(ANSWER_S)
        tally("intermediate chunks, never a final one (120 MB)", got)
        wire.close()

    # half-open: part of a Hello, then silence; a connection that never says Hello
    started = time.monotonic()
    half = []
    for count in range(max(4, int(40 * scale))):
        wire = Wire(url)
        await wire.connect(HOST, port)
        wire.send(wire.hello()[: 1 + count % 20] if count % 2 else b"")
        half.append(wire)
    closed_after = []
    deadline = time.monotonic() + PARTIAL_TIMEOUT_S + 10
    for wire in half:
        got = await wire.answer(max(0.1, deadline - time.monotonic()))
        closed_after.append(time.monotonic() - started)
        tally("half-open (part of a Hello or nothing, then silence)", got)
        wire.close()
    results["half-open closed after s (max)"] = round(max(closed_after), 1)

    # session flood: CreateSession over and over on one channel, never activated
    wire = Wire(url)
    await wire.connect(HOST, port)
    wire.send(wire.hello())
    await wire.answer(ANSWER_S)
    await wire.ask(wire.open())
    for _ in range(max(20, int(500 * scale))):
        tally("CreateSession flood on one channel", await wire.ask(wire.create_session()))
    wire.close()
    # sessions past the limit: each on its own connection
    held = []
    for _ in range(15):
        wire = Wire(url)
        got = await wire.handshake(HOST, port)
        tally("sessions past max_sessions", got)
        held.append(wire)
    for wire in held:
        wire.close()
    await asyncio.sleep(0.5)

    # subscription, monitored-item and publish floods on one session
    wire = Wire(url)
    await wire.handshake(HOST, port, "nckemu", "SUNRISE")
    for _ in range(25):
        tally("subscription flood", await wire.subscribe())
    wire.close()
    await asyncio.sleep(1.0)  # its subscriptions go with it (the limit is the server's)
    wire = Wire(url)
    await wire.handshake(HOST, port, "nckemu", "SUNRISE")
    await wire.subscribe()
    for _ in range(max(1, int(5 * scale))):
        got = await wire.ask(wire.monitor(5000, ua.NodeId("/Plc/DB130.DBW0", 2)), 30)
        if got.good:
            for result in got.decode(ua.CreateMonitoredItemsResponse).Results:
                results.setdefault("monitored items, 5000 per request", Counter())[result.StatusCode.name] += 1
        else:
            tally("monitored items, 5000 per request", got)
    publishes = max(100, int(3000 * scale))
    wire.send(b"".join(wire.publish() for _ in range(publishes)))
    answers: Counter[str] = Counter()
    for _ in range(publishes):
        got = await wire.answer(5)
        if got.kind == "silent":
            break
        answers[ua.StatusCode(got.status).name if got.kind == "MSG" else got.kind] += 1
    results[f"{publishes} Publish requests at once (answered within 5 s)"] = answers
    wire.close()

    # bad passwords: the same refusal whether the user or the password was wrong
    for step in range(max(10, int(300 * scale))):
        user, password = [("nckemu", rng.randbytes(8).hex()), (rng.randbytes(6).hex(), "SUNRISE"),
                          ("nckemu", ""), ("", "SUNRISE"), ("nckemu", b"\xff\xfe\x00")][step % 5]
        wire = Wire(url)
        tally("bad passwords and users", await wire.handshake(HOST, port, user, password))  # type: ignore[arg-type]
        wire.close()

    # bad certificates: OpenSecureChannel under Basic256Sha256 with garbage or no certificate
    for step in range(max(4, int(40 * scale))):
        wire = Wire(url)
        await wire.connect(HOST, port)
        wire.send(wire.hello())
        await wire.answer(ANSWER_S)
        certificate = [rng.randbytes(rng.randint(1, 2000)), None, b"0\x82\x01\x00" + rng.randbytes(256)][step % 3]
        wire.send(wire.open("http://opcfoundation.org/UA/SecurityPolicy#Basic256Sha256", certificate,
                            ua.MessageSecurityMode.SignAndEncrypt))
        tally("OpenSecureChannel with a bad certificate", await wire.answer(ANSWER_S))
        wire.close()
    out = {name: dict(value) if isinstance(value, Counter) else value for name, value in results.items()}
    out["_phases"] = phases
    return out


# ------------------------------------------------------------------ the run
def run(cases: int, seconds: float, seed: int, workers: int = 6, attack_scale: float = 1.0) -> dict[str, Any]:
    ctx = mp.get_context("spawn")
    with tempfile.TemporaryDirectory() as scratch:
        log = Path(scratch) / "server.log"
        server, s7_port, url = start_server(log)
        port = int(url.rsplit(":", 1)[1].strip("/"))
        stop, out = ctx.Event(), ctx.Queue()
        watchers = [ctx.Process(target=s7_watcher, args=(s7_port, stop, out)),
                    ctx.Process(target=ua_watcher, args=(url, stop, out))]
        try:
            for watcher in watchers:
                watcher.start()
            time.sleep(2.0)
            rss_before, fds_before = process_figures(server.pid)
            started = time.monotonic()
            fuzz_started = time.time()
            fuzzer = Fuzzer(url, port, seed, cases, seconds)
            asyncio.run(fuzzer.run(workers))
            fuzz_s = time.monotonic() - started
            named = asyncio.run(attacks(url, port, random.Random(seed), attack_scale))
            elapsed_s = time.monotonic() - started
            time.sleep(1.0)
            alive = server.poll() is None
            rss_after, fds_after = process_figures(server.pid) if alive else (0, 0)
            stop.set()
            seen = {}
            for _ in watchers:
                try:
                    name, latencies, failures, slow = out.get(timeout=60)
                    seen[name] = {"polls": len(latencies), "failures": failures,
                                  "p50_ms": round(1000 * percentile(latencies, 0.5), 2),
                                  "p99_ms": round(1000 * percentile(latencies, 0.99), 2),
                                  "max_ms": round(1000 * max(latencies, default=float("nan")), 1),
                                  "slow_polls": slow[:20]}
                except Exception:
                    pass
            for watcher in watchers:
                watcher.join(timeout=10)
        finally:
            stop.set()
            server.terminate()
            try:
                server.wait(timeout=20)
            except subprocess.TimeoutExpired:
                server.kill()
            for watcher in watchers:
                if watcher.is_alive():
                    watcher.kill()
        text = log.read_text(errors="replace")
    tracebacks = text.count("Traceback (most recent call last)") + text.count("internal error serving a request")
    first = re.findall(r"^.*(?:ERROR|CRITICAL).*$", text, re.MULTILINE)[:5]
    at = text.find("Traceback (most recent call last)")
    first_traceback = text[max(0, text.rfind("\n", 0, max(0, at - 1)) + 1):][:4000] if at >= 0 else ""
    return {"cases": fuzzer.done, "seconds": round(elapsed_s, 1), "cases_per_s": round(fuzzer.done / fuzz_s, 1),
            "outcomes": dict(fuzzer.outcomes.most_common()), "by_message": dict(fuzzer.by_kind),
            "stuck": fuzzer.stuck, "stuck_cases": fuzzer.stuck_cases[:5], "late_answers": fuzzer.late,
            "probe_taken_into_a_cut_message": fuzzer.probe_taken_in,
            "waiting_closed_by_server_max_s": round(max(fuzzer.closed_in, default=0), 1),
            "handshake_failures": fuzzer.handshake_failures, "attacks": named, "fuzz_started": fuzz_started,
            "crashed": not alive, "internal_errors": tracebacks, "first_errors": first,
            "first_traceback": first_traceback,
            "watchers": seen, "rss_kib": [rss_before, rss_after], "fds": [fds_before, fds_after]}


def verdict(result: dict[str, Any]) -> list[str]:
    """What went wrong (empty: the face held)."""
    wrong = []
    if result["crashed"]:
        wrong.append("the server died")
    if result["internal_errors"]:
        wrong.append(f"{result['internal_errors']} tracebacks in the server log")
    if result["stuck"]:
        wrong.append(f"{result['stuck']} waiting connections never closed by the server")
    for name in ("s7", "opcua"):
        watch = result["watchers"].get(name)
        if watch is None or watch["failures"] or not watch["polls"]:
            wrong.append(f"the {name} watcher was not served throughout: {watch}")
    if result["fds"][1] > result["fds"][0] + 8:
        wrong.append(f"descriptors grew {result['fds']}")
    return wrong


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", choices=sorted(SIZES), default="small")
    parser.add_argument("--cases", type=int, help="mutated messages (default: by --size)")
    parser.add_argument("--seconds", type=float, default=3600.0, help="stop the mutated messages after this")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=6)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    cases = args.cases or SIZES[args.size]
    result = run(cases, args.seconds, args.seed, args.workers, attack_scale=1.0 if args.size != "small" else 0.2)
    wrong = verdict(result)
    if args.json:
        print(json.dumps({**result, "wrong": wrong}, indent=1))
    else:
        print(json.dumps(result, indent=1))
        print("OPC UA fuzz:", "held" if not wrong else "; ".join(wrong))
    return 1 if wrong else 0


if __name__ == "__main__":
    sys.exit(main())
