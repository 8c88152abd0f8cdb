"""Start time and memory of the OPC UA face with the umati and CNC models, beside the face without them.

Each case runs in a fresh Python process (so that memory and caches are the process's own):
- ``first``: an empty cache directory: the standard shelf and the models' shelf are built (the NodeSets
  imported), then the face starts;
- ``cached``: the same directory again: the face starts from the models' shelf;
- ``cached, 2nd face``: a second face in that process (what each machine of a fleet pays);
- ``without models``: ``[opcua] models = []`` from the same cache.

Prints one line per case: wall seconds to ``start()``, the process's peak RSS after it, nodes the models
added.

Then, in the same run, one face (default machine, both models) and one client process monitoring 1000
items at 100 ms twice: on umati/CNC variables (the overrides: Monitoring/<channel>/FeedOverride and
RapidOverride, Monitoring/MachineTool/FeedOverride, Monitoring/<spindle>/Override, the CNC channel's and
spindle's Act/CmdOverride; each node 125 times) and on the SINUMERIK variables they show
(feedRateIpoOvr, rapFeedRateOvr, speedOvr), while the server writes the three overrides into the model
every 100 ms (as an S7 put would). Server CPU per update delivered, for each.

Fleet (``--fleet N``, 0 skips): ``nckemu fleet --count N --opcua-base-port`` with both models and with
``models = []``, same run: RSS of the fleet process and seconds until every face listens.

``python bench/bench_umati.py [--seconds 5] [--fleet 100]`` (needs the NodeSets: ``make nodesets``).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve()
ITEMS = 1000
CYCLE_S = 0.1
# (umati/CNC node id in the instance namespace, the SINUMERIK node id it shows)
PAIRS = (
    ("MachineTool/Monitoring/Channel1/FeedOverride", "/Channel/State/feedRateIpoOvr[u1]"),
    ("MachineTool/Monitoring/MachineTool/FeedOverride", "/Channel/State/feedRateIpoOvr[u1]"),
    ("CncInterface/CncChannelList/Channel1/ActOverride", "/Channel/State/feedRateIpoOvr[u1]"),
    ("CncInterface/CncChannelList/Channel1/CmdOverride", "/Channel/State/feedRateIpoOvr[u1]"),
    ("MachineTool/Monitoring/Channel1/RapidOverride", "/Channel/State/rapFeedRateOvr[u1]"),
    ("MachineTool/Monitoring/Spindle1/Override", "/Channel/Spindle/speedOvr[u1,1]"),
    ("CncInterface/CncSpindleList/SP1/ActOverride", "/Channel/Spindle/speedOvr[u1,1]"),
    ("CncInterface/CncSpindleList/SP1/CmdOverride", "/Channel/Spindle/speedOvr[u1,1]"),
)

CHILD = r"""
import asyncio, dataclasses, json, resource, sys, time
from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.faces.opcua.settings import OpcUaSettings
from nckemu.emulator.machine.core import Emulator

async def main(models, faces):
    out = []
    for _ in range(faces):
        emulator = Emulator()
        settings = OpcUaSettings.from_machine(emulator.machine.opcua, emulator.machine.source)
        if not models:
            settings = dataclasses.replace(settings, models=())
        rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        started = time.perf_counter()
        face = await OpcUaFace(emulator, "127.0.0.1", 0, settings=settings).start()
        took = time.perf_counter() - started
        out.append({"start_s": took, "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                    "rss_before_mb": rss0, "nodes": face.models.nodes_made})
    print(json.dumps(out))

asyncio.run(main(sys.argv[1] == "models", int(sys.argv[2])))
"""


def run(cache: str, models: bool, faces: int) -> list[dict[str, float]]:
    env = dict(os.environ, NCKEMU_CACHE=cache)
    done = subprocess.run([sys.executable, "-c", CHILD, "models" if models else "none", str(faces)], env=env,
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


async def serve_overrides() -> None:
    """A face whose overrides change every cycle (the cycle number modulo 200, in percent)."""
    import dataclasses

    from nckemu.catalogue.node_ids import parse_node_id
    from nckemu.emulator.faces.opcua import OpcUaFace
    from nckemu.emulator.faces.opcua.settings import OpcUaSettings
    from nckemu.emulator.machine.core import Emulator
    from nckemu.emulator.machine.nck.access import HIGHEST_LEVEL, AccessContext

    emulator = Emulator()
    settings = dataclasses.replace(OpcUaSettings.from_machine(emulator.machine.opcua, emulator.machine.source),
                                   max_samples_per_s=100_000)  # 1000 items at 100 ms: ten times the 840D sl cap
    face = await OpcUaFace(emulator, "127.0.0.1", 0, settings=settings).start()
    print(json.dumps({"port": face.port, "ns": face.models.instance_namespace}), flush=True)
    specs = emulator.nck.store.specs
    addresses = [parse_node_id(node_id, specs).address for node_id in sorted({btss for _u, btss in PAIRS})]
    ctx = AccessContext(level=HIGHEST_LEVEL, client="bench")
    loop = asyncio.get_running_loop()
    due, cycle = loop.time(), 0
    while True:
        cycle += 1
        for address in addresses:
            emulator.nck.write(address, [float(cycle % 200)], ctx)
        due += CYCLE_S
        await asyncio.sleep(max(0.0, due - loop.time()))


async def subscribe(url: str, ns: int, kind: str, seconds: float) -> None:
    from asyncua import Client, ua

    counted = {"on": False, "n": 0}

    class Handler:
        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            if counted["on"]:
                counted["n"] += 1

    ids = [(ua.NodeId(umati, ns) if kind == "umati" else ua.NodeId(btss, 2)) for umati, btss in PAIRS]
    async with Client(url, timeout=30) as client:
        subscription = await client.create_subscription(100, Handler())
        nodes = [client.get_node(ids[i % len(ids)]) for i in range(ITEMS)]
        await subscription.subscribe_data_change(nodes, queuesize=10, sampling_interval=100)
        await asyncio.sleep(1.0)
        counted["on"] = True
        start = time.monotonic()
        await asyncio.sleep(seconds)
        counted["on"] = False
        elapsed = time.monotonic() - start
    print(json.dumps({"updates_per_s": counted["n"] / elapsed}), flush=True)


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def monitoring(seconds: float, order: tuple[str, ...] = ("sinumerik", "umati", "umati", "sinumerik")
               ) -> dict[str, dict[str, float]]:
    """Each kind twice, in ABBA order (the host's load drifts); CPU and updates summed per kind."""
    server = subprocess.Popen([sys.executable, str(HERE), "--serve"], stdout=subprocess.PIPE, text=True)
    results: dict[str, dict[str, float]] = {}
    try:
        assert server.stdout is not None
        ready = json.loads(server.stdout.readline())
        url = f"opc.tcp://127.0.0.1:{ready['port']}/"
        for kind in order:
            subscriber = subprocess.Popen([sys.executable, str(HERE), "--subscribe", url, "--ns", str(ready["ns"]),
                                           "--kind", kind, "--seconds", str(seconds)], stdout=subprocess.PIPE,
                                          text=True)
            time.sleep(2.0)
            cpu0, t0 = _cpu_s(server.pid), time.monotonic()
            out, _ = subscriber.communicate(timeout=180)
            cpu = (_cpu_s(server.pid) - cpu0) / (time.monotonic() - t0)
            updates = json.loads(out.strip().splitlines()[-1])["updates_per_s"]
            row = results.setdefault(kind, {"server_cpu": 0.0, "updates_per_s": 0.0, "runs": 0})
            row["server_cpu"] += cpu
            row["updates_per_s"] += updates
            row["runs"] += 1
    finally:
        server.terminate()
        server.wait(timeout=30)
    for row in results.values():
        row["server_cpu"] /= row["runs"]
        row["updates_per_s"] /= row["runs"]
        row["us_per_update"] = row["server_cpu"] / row["updates_per_s"] * 1e6 if row["updates_per_s"] else float("nan")
    return results


def fleet(count: int) -> dict[str, dict[str, float]]:
    """A fleet of ``count`` machines with an OPC UA face each, with and without the models."""
    sys.path.insert(0, str(HERE.parent.parent))
    from bench.bench_fleet import free_range, rss_mb, start_fleet

    default = (HERE.parent.parent / "nckemu/emulator/machine/machines/default.toml").read_text("utf-8")
    results: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as folder:
        plain = Path(folder) / "plain.toml"
        plain.write_text(default.replace('models = ["MachineTool", "CNC"]', "models = []"), encoding="utf-8")
        for label, extra in (("without models", ("--machine", str(plain))), ("with both models", ())):
            base = free_range(2 * count)
            started = time.monotonic()
            process, _ports = start_fleet(count, base, "--opcua-base-port", str(base + count), *extra)
            try:
                results[label] = {"ready_s": time.monotonic() - started, "rss_mb": rss_mb(process.pid)}
            finally:
                process.terminate()
                process.wait()
    return results


def main() -> int:
    from nckemu.emulator.faces.opcua import nodesets

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--serve", action="store_true")
    parser.add_argument("--subscribe")
    parser.add_argument("--ns", type=int, default=0)
    parser.add_argument("--kind", default="umati")
    parser.add_argument("--fleet", type=int, default=0, help="machines of the OPC UA fleet (0: skip)")
    args = parser.parse_args()
    if args.serve:
        asyncio.run(serve_overrides())
        return 0
    if args.subscribe:
        asyncio.run(subscribe(args.subscribe, args.ns, args.kind, args.seconds))
        return 0
    if nodesets.find() is None:
        print(nodesets.how_to_get())
        return 0
    with tempfile.TemporaryDirectory() as cache:
        first = run(cache, True, 1)[0]
        cached = run(cache, True, 2)
        plain = run(cache, False, 2)
    rows = [("first (models imported)", first), ("cached", cached[0]), ("cached, 2nd face", cached[1]),
            ("without models", plain[0]), ("without models, 2nd face", plain[1])]
    for label, row in rows:
        print(f"{label:28s} start {row['start_s']:6.2f} s   peak RSS {row['rss_mb']:6.1f} MB "
              f"(+{row['rss_mb'] - row['rss_before_mb']:5.1f})   model nodes {row['nodes']:.0f}")
    measured = monitoring(args.seconds)
    print(f"{ITEMS} monitored items at 100 ms, the overrides written every {CYCLE_S * 1000:.0f} ms, "
          f"{args.seconds:g} s each, each kind twice (ABBA), means")
    for kind, label in (("sinumerik", "SINUMERIK nodes"), ("umati", "umati/CNC nodes")):
        row = measured[kind]
        print(f"{label:18s} updates delivered/s {row['updates_per_s']:8.0f} (of {ITEMS / CYCLE_S:.0f})   "
              f"server CPU {row['server_cpu']:.2f} cores   {row['us_per_update']:6.1f} us per update")
    if args.fleet > 0:
        for label, row in fleet(args.fleet).items():
            print(f"fleet of {args.fleet} with OPC UA faces, {label:17s} RSS {row['rss_mb']:6.0f} MB   "
                  f"every face listening after {row['ready_s']:6.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
