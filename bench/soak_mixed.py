"""A mixed soak on a living machine: the recording and the PLC program run in the server while many
S7 clients (reads, writes, PI, SZL) and OPC UA sessions (subscriptions with monitored items, reads,
writes, method calls, user changes, copied-in programs) work at once, with ``--state``.

Two runs: one server life (every change an OPC UA session writes must reach its monitored item, RSS
and descriptors flat after warm-up), then the same load while the server is killed with -9 at random
moments and restarted: every acknowledged write (S7 and OPC UA: R parameters, setting data, users,
programs) is there after each restart, and no value read is torn (each is one that was written).

Values written: client w writes R[w] = w * 1e6 + i + 0.123456789 (i counts up), so a torn double is
almost surely no written value and the last acknowledged one is a lower bound after a restart.

Usage: .venv/bin/python bench/soak_mixed.py [--size small|medium|full] [--kills N] [--json]
Loopback only; every loop is bounded by its count and by --seconds.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing as mp
import os
import queue
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

REPO = Path(__file__).resolve().parent.parent
MACHINE = REPO / "fixtures/machines/loop_mill.toml"
RECORDING = REPO / "fixtures/thermal/loop_bed_program_spindle_lag.csv"
PLC = REPO / "fixtures/plc/bed_only_z.awl"
FRACTION = 0.123456789
UA_FIRST_R = 64  # OPC UA session k writes R[64 + k]; S7 client w writes R[w]
SD = "SD43900[AX1]"  # written by S7 client 0 only (the PLC program writes AX4's)
SIZES = {  # S7 clients, jobs each, OPC UA sessions, operations each, kill cycles, seconds at most
    "tiny": (4, 400, 2, 40, 1, 120),  # the run inside `make test`
    "small": (8, 4000, 4, 400, 3, 300),
    "medium": (32, 8000, 10, 2500, 8, 1800),
    "full": (64, 16000, 10, 10_000, 20, 5400),
}


def value_of(writer: int, index: int) -> float:
    return writer * 1e6 + index + FRACTION


def is_a_write(value: float, writer: int | None = None) -> bool:
    if value == 0.0:
        return True
    who, rest = divmod(value - FRACTION, 1e6)
    return abs(rest - round(rest)) < 1e-6 and (writer is None or who == writer)


# ------------------------------------------------------------------ the server
OPCUA_USERS = """
[opcua]
anonymous = ["SinuReadAll"]
max_sessions = 11  # the soak's 10 sessions at the 840D's limit, and one for the checks after a restart

[opcua.users.nckemu]
password = "SUNRISE"
rights = ["SinuReadAll", "SinuWriteAll"]
"""


def machine_file(folder: Path) -> Path:
    """loop_mill with the default machine's OPC UA users (its own file has none)."""
    path = folder / "loop_mill_users.toml"
    path.write_text(MACHINE.read_text(encoding="utf-8") + OPCUA_USERS, encoding="utf-8")
    return path


def serve(port: int, opcua: int, state: Path, log: Path, clients: int) -> subprocess.Popen[str]:
    command = [sys.executable, "-m", "nckemu", "serve", "--machine", str(machine_file(state.parent)), "--inputs", str(RECORDING),
               "--loop", "--plc", str(PLC), "--speed", "60x", "--port", str(port), "--opcua", str(opcua),
               "--state", str(state), "--json", "--max-connections", str(clients + 16)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=log.open("a"), text=True)
    assert process.stdout is not None
    if not process.stdout.readline():
        raise RuntimeError(f"the server did not start: {log.read_text()[-3000:]}")
    return process


# ------------------------------------------------------------------ S7 clients
def s7_client(port: int, number: int, jobs: int, deadline: float, acked: Any, progress: Any, out: Any) -> None:
    """Reads, writes (R[number], DB100 word, SD for client 0), PI and live values, reconnecting when
    the server goes away. Counts jobs, errors, torn values; keeps its last acknowledged R value and
    shows its job count in ``progress[number]`` (the kills are timed by it)."""
    import logging
    import struct

    from nckemu.clients import NckClient
    from nckemu.errors import NckError

    logging.disable(logging.CRITICAL)
    rng = random.Random(number)
    latencies: list[float] = []
    done = torn = errors = reconnects = index = 0
    client: NckClient | None = None
    while done < jobs and time.time() < deadline:
        try:
            if client is None:
                client = NckClient("127.0.0.1", port, timeout_s=5).connect()
            pick = rng.random()
            started = time.perf_counter()
            if pick < 0.12:  # a retained write: acknowledged after the state file is on disk
                index += 1
                value = value_of(number, index)
                client.put({f"R{number}": value})
                acked[number] = value
            elif pick < 0.6:
                own, other = client.get(f"R{number}", f"R{rng.randrange(UA_FIRST_R + 10)}")
                if not is_a_write(own, number) or not is_a_write(other):
                    torn += 1
            elif pick < 0.72:
                client.db_write(100, 2 * number, struct.pack(">H", index & 0xFFFF))
                if struct.unpack(">H", client.db_read(100, 2 * number, 2))[0] != index & 0xFFFF:
                    torn += 1
                done += 1
            elif pick < 0.75 and number == 0:
                index += 1
                client.put({SD: float(index % 1000) / 1000.0})
                acked[len(acked) - 1] = float(index % 1000) / 1000.0
            elif pick < 0.85:
                client.pi_service("_N_SETUDT", "/NC")
            else:
                client.get("actToolBasePos[3,C1]", SD)
            latencies.append(time.perf_counter() - started)
            done += 1
            progress[number] = done
        except (NckError, OSError, TimeoutError):
            errors += 1
            if client is not None:
                try:
                    client.close()
                except Exception:
                    pass
            client = None
            reconnects += 1
            time.sleep(0.2)
    if client is not None:
        client.close()
    out.put(("s7", number, done, errors, torn, latencies[::max(1, len(latencies) // 20000)]))


def szl_client(port: int, deadline: float, stop: Any, out: Any) -> None:
    """python-snap7: SZL lists, CPU info and DB reads in a loop."""
    import snap7

    done = errors = 0
    latencies: list[float] = []
    client = snap7.client.Client()
    while time.time() < deadline and not stop.is_set():
        try:
            if not client.get_connected():
                client.connect("127.0.0.1", 0, 2, port)
            started = time.perf_counter()
            client.read_szl(0x0011, 0) if done % 3 == 0 else client.get_cpu_info() if done % 3 == 1 \
                else client.db_read(100, 0, 16)
            latencies.append(time.perf_counter() - started)
            done += 1
            time.sleep(0.002)
        except Exception:
            errors += 1
            try:
                client.disconnect()
            except Exception:
                pass
            time.sleep(0.2)
    out.put(("szl", 0, done, errors, 0, latencies))


# ------------------------------------------------------------------ OPC UA sessions
def ua_client(url: str, number: int, operations: int, items: int, deadline: float, acked: Any, users: Any,
              programs: Any, watch: bool, progress: Any, out: Any) -> None:
    """One session (reconnecting): a subscription on ``items`` nodes incl. its own PLC word; writes of
    that word and of R[64 + number]; reads; method calls; user changes (sessions 0..3), programs."""
    import logging

    from asyncua import Client, ua

    logging.disable(logging.CRITICAL)
    r_index = UA_FIRST_R + number
    word = f"/Plc/DB100.DBW{128 + 2 * number}"
    result = {"done": 0, "errors": 0, "lost": 0, "written": 0, "seen": 0}
    latencies: list[float] = []

    async def life(state: dict[str, int]) -> None:
        seen: list[int] = []

        class Handler:
            def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
                if node.nodeid.Identifier == word:
                    seen.append(int(value))

        # asyncua 2.x's client takes its connection for lost when its server probe (each watchdog interval, 1 s by
        # default) is answered slower than the interval, as on loaded cores: probe within the timeout instead.
        client = Client(url, timeout=10, watchdog_intervall=10.0)
        client.set_user("nckemu")
        client.set_password("SUNRISE")
        async with client:
            ns = 2
            methods = await client.nodes.objects.get_child([f"{ns}:Sinumerik", f"{ns}:Methods"])
            subscription = await client.create_subscription(1000, Handler())
            nodes = [client.get_node(ua.NodeId(word, ns))] + [
                client.get_node(ua.NodeId(f"/Plc/DB100.DBB{i % 128}", ns)) for i in range(items - 1)]
            await subscription.subscribe_data_change(nodes, queuesize=1000, sampling_interval=1000)
            await asyncio.sleep(1.5)
            seen.clear()
            own = client.get_node(ua.NodeId(word, ns))
            r_node = client.get_node(ua.NodeId(f"/Channel/Parameter/R[u1,{r_index + 1}]", ns))  # R[u1,n]: R(n-1)
            live = client.get_node(ua.NodeId("/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]", ns))  # the PLC writes it
            written: list[int] = []
            rng = random.Random(number * 7919 + state["life"])
            while result["done"] < operations and time.time() < deadline:
                pick = rng.random()
                started = time.perf_counter()
                if pick < 0.4:
                    state["word"] = (state["word"] + 1) & 0x7FFF
                    await own.write_value(ua.Variant(state["word"], ua.VariantType.UInt16))
                    written.append(state["word"])
                elif pick < 0.5:  # a retained write
                    state["r"] += 1
                    value = value_of(r_index, state["r"])
                    await r_node.write_value(ua.Variant(value, ua.VariantType.Double))
                    acked[r_index] = value
                elif pick < 0.75:
                    value = await r_node.read_value()
                    await live.read_value()
                    if not is_a_write(value, r_index):
                        result["errors"] += 1
                elif pick < 0.85:
                    await methods.call_method(f"{ns}:GetMyAccessRights")
                elif pick < 0.95 or number >= 4:
                    state["program"] += 1
                    text = f"; soak {number} {state['program']}\nM30\n".encode()
                    await methods.call_method(f"{ns}:CopyFileToServer",
                                              ua.Variant(f"Sinumerik/FileSystem/Part Program/SOAK{number}.MPF"),
                                              ua.Variant(text, ua.VariantType.ByteString), ua.Variant(True))
                    programs[number] = state["program"]
                else:
                    state["user"] += 1
                    name = f"s{number}u{state['user']}"
                    await methods.call_method(f"{ns}:AddUser", ua.Variant(name), ua.Variant("pw"))
                    users[number] = state["user"]
                    if state["user"] > 1:
                        await methods.call_method(f"{ns}:DeleteUser", ua.Variant(f"s{number}u{state['user'] - 1}"))
                latencies.append(time.perf_counter() - started)
                result["done"] += 1
                progress[number] = result["done"]
            if watch:
                await asyncio.sleep(2.5)  # the last publishing interval and one more
                result["written"] += len(written)
                result["seen"] += len(seen)
                missing = set(written) - set(seen)
                result["lost"] += len(missing)

    async def main() -> None:
        state = {"word": 0, "r": 0, "program": 0, "user": 0, "life": 0}
        while result["done"] < operations and time.time() < deadline:
            state["life"] += 1
            try:
                await life(state)
            except Exception:
                result["errors"] += 1
                await asyncio.sleep(0.5)

    asyncio.run(main())
    out.put(("opcua", number, result, latencies[::max(1, len(latencies) // 20000)]))


# ------------------------------------------------------------------ checks after a restart
def check_durable(port: int, url: str, acked: list[float], users: list[int], programs: list[int]) -> dict[str, int]:
    """Every acknowledged value is there (or a later one of the same writer); none is torn."""
    from asyncua import Client, ua

    from nckemu.clients import NckClient

    lost = torn = 0
    with NckClient("127.0.0.1", port, timeout_s=10) as client:
        for writer, value in enumerate(acked[:-1]):
            if value == 0.0:
                continue
            (now,) = client.get(f"R{writer}")
            if not is_a_write(now, writer):
                torn += 1
            elif now < value:
                lost += 1
        if acked[-1]:
            (sd,) = client.get(SD)
            if abs(sd * 1000 - round(sd * 1000)) > 1e-6:
                torn += 1

    async def opcua_side() -> int:
        missing = 0
        # asyncua 2.x's client takes its connection for lost when its server probe (each watchdog interval, 1 s by
        # default) is answered slower than the interval, as on loaded cores: probe within the timeout instead.
        client = Client(url, timeout=10, watchdog_intervall=10.0)
        client.set_user("nckemu")
        client.set_password("SUNRISE")
        async with client:
            methods = await client.nodes.objects.get_child(["2:Sinumerik", "2:Methods"])
            names = set(await methods.call_method("2:GetUserList"))
            for number, last in enumerate(users):
                if last and not any(n.startswith(f"s{number}u") and int(n.split("u")[1]) >= last for n in names):
                    missing += 1
            for number, last in enumerate(programs):
                if not last:
                    continue
                text = await methods.call_method("2:CopyFileFromServer", ua.Variant(
                    f"Sinumerik/FileSystem/Part Program/SOAK{number}.MPF"))
                if int(text.split(b"\n")[0].split()[-1]) < last:
                    missing += 1
        return missing

    return {"lost": lost, "torn": torn, "lost_opcua": asyncio.run(opcua_side())}


def percentiles(values: list[float]) -> dict[str, float]:
    if not values:
        return {}
    ordered = sorted(values)
    pick = lambda q: round(1000 * ordered[min(len(ordered) - 1, int(q * len(ordered)))], 2)  # noqa: E731
    return {"p50_ms": pick(0.5), "p99_ms": pick(0.99), "p999_ms": pick(0.999), "max_ms": round(1000 * ordered[-1], 1)}


# ------------------------------------------------------------------ one run
def run(s7_clients: int, s7_jobs: int, ua_sessions: int, ua_operations: int, kills: int, seconds: float,
        seed: int = 1) -> dict[str, Any]:
    from bench.bench_server import free_port, process_figures

    ctx = mp.get_context("spawn")
    rng = random.Random(seed)
    port, opcua = free_port(), free_port()
    url = f"opc.tcp://127.0.0.1:{opcua}/"
    acked = ctx.Array("d", UA_FIRST_R + 10 + 1)
    users, programs = ctx.Array("i", ua_sessions), ctx.Array("i", ua_sessions)
    out, stop = ctx.Queue(), ctx.Event()
    progress = ctx.Array("q", s7_clients, lock=False)
    progress_ua = ctx.Array("q", max(1, ua_sessions), lock=False)
    items = max(1, min(1000 // max(1, ua_sessions), 25 * s7_jobs // 1000))
    with tempfile.TemporaryDirectory() as scratch:
        state, log = Path(scratch) / "state.json", Path(scratch) / "server.log"
        server = serve(port, opcua, state, log, s7_clients + 1)
        started = time.time()
        deadline = started + seconds
        workers = [ctx.Process(target=s7_client, args=(port, w, s7_jobs, deadline, acked, progress, out))
                   for w in range(s7_clients)]
        workers += [ctx.Process(target=ua_client, args=(url, k, ua_operations, items, deadline, acked, users,
                                                        programs, kills == 0, progress_ua, out))
                    for k in range(ua_sessions)]
        szl = ctx.Process(target=szl_client, args=(port, deadline, stop, out))
        for worker in [*workers, szl]:
            worker.start()
        samples: list[tuple[float, int, int]] = []
        restarts: list[dict[str, int]] = []
        died = 0
        # Kill moments are fractions of the S7 jobs (or of the time, whichever comes first): on a fast
        # machine the jobs end long before the time does, and a kill planned by the clock alone never came.
        kill_at = sorted(rng.uniform(0.1, 0.9) for _ in range(kills))
        planned_jobs = max(1, s7_clients * s7_jobs)

        def kill_and_restart() -> None:
            nonlocal server
            kill_at.pop(0)
            time.sleep(rng.uniform(0, 0.5))
            os.kill(server.pid, signal.SIGKILL)
            server.wait(timeout=10)
            snapshot = list(acked), list(users), list(programs)
            server = serve(port, opcua, state, log, s7_clients + 1)
            restarts.append(check_durable(port, url, *snapshot))

        # A worker's result is read as soon as it is sent: a process that sent a result larger than the
        # pipe holds cannot exit until it is read (the first full-size run waited on exactly that).
        results: list[Any] = []

        def collect() -> None:
            try:
                while True:
                    results.append(out.get_nowait())
            except queue.Empty:
                pass

        try:
            while (len(results) < len(workers) and any(worker.is_alive() for worker in workers)
                   and time.time() < deadline + 60):
                time.sleep(0.25)
                collect()
                if server.poll() is not None:
                    died += 1
                    server = serve(port, opcua, state, log, s7_clients + 1)
                samples.append((time.time() - started, *process_figures(server.pid)))
                if sys.stderr.isatty() or len(samples) % 240 == 0:  # every minute in a log, live on a terminal
                    print(f"\rsoak: {sum(progress):,} of {planned_jobs:,} S7 jobs, {sum(progress_ua):,} of "
                          f"{ua_sessions * ua_operations:,} OPC UA operations, {len(restarts)} kills, "
                          f"{time.time() - started:.0f} s", end="" if sys.stderr.isatty() else "\n",
                          file=sys.stderr, flush=True)
                done = max((time.time() - started) / seconds, sum(progress) / planned_jobs)
                if kill_at and done >= kill_at[0]:
                    kill_and_restart()
            while kill_at:  # the clients finished first: the kills still test what they acknowledged
                kill_and_restart()
            if sys.stderr.isatty():
                print(file=sys.stderr)
            results += [out.get(timeout=120) for _ in range(len(workers) - len(results))]
            stop.set()
            results.append(out.get(timeout=60))
            for worker in [*workers, szl]:
                worker.join(timeout=30)
            final = check_durable(port, url, list(acked), list(users), list(programs))
        finally:
            stop.set()
            server.send_signal(signal.SIGINT)
            try:
                server.wait(timeout=20)
            except subprocess.TimeoutExpired:
                server.kill()
            for worker in [*workers, szl]:
                if worker.is_alive():
                    worker.kill()
        text = log.read_text(errors="replace")
    elapsed = time.time() - started
    s7 = [r for r in results if r[0] in ("s7", "szl")]
    ua_results = [r for r in results if r[0] == "opcua"]
    s7_latencies = [x for r in s7 for x in r[5]]
    ua_latencies = [x for r in ua_results for x in r[3]]
    warm = [s for s in samples if s[0] > 0.2 * elapsed] if not kills else []
    return {
        "seconds": round(elapsed, 1), "kills": len(restarts), "unexpected_deaths": died,
        "s7": {"clients": len(s7), "jobs": sum(r[2] for r in s7), "errors": sum(r[3] for r in s7),
               "torn": sum(r[4] for r in s7), **percentiles(s7_latencies)},
        "opcua": {"sessions": len(ua_results), "items_each": items,
                  "operations": sum(r[2]["done"] for r in ua_results),
                  "errors": sum(r[2]["errors"] for r in ua_results),
                  "changes_written": sum(r[2]["written"] for r in ua_results),
                  "changes_seen": sum(r[2]["seen"] for r in ua_results),
                  "changes_lost": sum(r[2]["lost"] for r in ua_results), **percentiles(ua_latencies)},
        "restarts": {"lost": sum(r["lost"] for r in restarts), "torn": sum(r["torn"] for r in restarts),
                     "lost_opcua": sum(r["lost_opcua"] for r in restarts)},
        "final": final,
        "rss_kib": {"after_warm_up": warm[0][1] if warm else None, "end": warm[-1][1] if warm else None,
                    "max": max((s[1] for s in samples), default=0)},
        "fds": {"after_warm_up": warm[0][2] if warm else None, "end": warm[-1][2] if warm else None},
        "tracebacks": text.count("Traceback (most recent call last)"),
    }


def verdict(result: dict[str, Any], kills: int) -> list[str]:
    wrong = []
    if result["unexpected_deaths"]:
        wrong.append(f"the server died {result['unexpected_deaths']} times by itself")
    for key in ("lost", "torn", "lost_opcua"):
        if result["restarts"][key] or result["final"][key]:
            wrong.append(f"{key}: {result['restarts'][key]} after restarts, {result['final'][key]} at the end")
    if result["s7"]["torn"]:
        wrong.append(f"{result['s7']['torn']} torn S7 values")
    if result["opcua"]["changes_lost"]:
        wrong.append(f"{result['opcua']['changes_lost']} monitored changes lost")
    if result["tracebacks"]:
        wrong.append(f"{result['tracebacks']} tracebacks in the server log")
    if not kills:
        rss, fds = result["rss_kib"], result["fds"]
        if rss["end"] and rss["after_warm_up"] and rss["end"] > rss["after_warm_up"] * 1.25 + 10_240:
            wrong.append(f"RSS grew after warm-up: {rss}")
        if fds["end"] and fds["after_warm_up"] and fds["end"] > fds["after_warm_up"] + 8:
            wrong.append(f"descriptors grew after warm-up: {fds}")
        if result["s7"]["errors"]:
            wrong.append(f"{result['s7']['errors']} S7 errors while the server lived")
    return wrong


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", choices=sorted(SIZES), default="small")
    parser.add_argument("--kills", type=int, help="kill -9 cycles of the second run (default: by --size)")
    parser.add_argument("--seconds", type=float, help="each run stops after this (default: by --size)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    clients, jobs, sessions, operations, kills, seconds = SIZES[args.size]
    kills = kills if args.kills is None else args.kills
    seconds = args.seconds or seconds
    wrong = []
    for name, count in (("one life", 0), (f"kill -9 x {kills}", kills)):
        result = run(clients, jobs, sessions, operations, count, seconds)
        problems = verdict(result, count)
        wrong += [f"{name}: {p}" for p in problems]
        print(json.dumps({"run": name, **result, "wrong": problems}, indent=None if args.json else 1), flush=True)
    print("soak:", "held" if not wrong else "; ".join(wrong))
    return 1 if wrong else 0


if __name__ == "__main__":
    sys.exit(main())
