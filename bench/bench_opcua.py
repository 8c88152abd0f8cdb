"""OPC UA face against asyncua's own server (the anchor), in the same run.

Each server runs in its own process with 1000 variables whose values change every 100 ms: on ours PLC
words /Plc/DB200.DBW0..1998 written into the model (as a PLC program or an S7 client would), on the
anchor plain asyncua variables written with ``write_attribute_value``. Then
  1. one client process monitors all 1000 at 100 ms: updates delivered/s, lost updates, server CPU;
  2. 8 client processes read 10 values per request: values read/s.
usage: python bench/bench_opcua.py [--seconds 5]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ITEMS = 1000
CYCLE_S = 0.1
READERS = 8
HERE = Path(__file__).resolve()
# asyncua 2.x's client probes the server every watchdog interval (1 s by default) and, when the answer
# takes longer than that, takes the connection for lost and ends its subscriptions in silence: on two
# loaded cores that is a client of the bench giving up, not a server failing. Probe within the timeout.
CLIENT = {"timeout": 30, "watchdog_intervall": 30.0}


def _ids(kind: str) -> list[str]:
    if kind == "ours":
        return [f"/Plc/DB200.DBW{2 * i}" for i in range(ITEMS)]
    return [f"plain{i}" for i in range(ITEMS)]


async def serve(kind: str, port: int) -> None:
    from asyncua import Server, ua

    if kind == "ours":
        from nckemu.emulator.faces.opcua import OpcUaFace
        from nckemu.emulator.machine.core import Emulator
        from nckemu.emulator.machine.machine_file import parse_machine

        # 1000 items at 100 ms are 10 000 samples/s, ten times an 840D sl's cap: raised for the bench.
        emulator = Emulator(parse_machine('name = "bench"\n[plc]\ndata_blocks = { 200 = 4096 }\n'
                                          '[opcua]\nmax_samples_per_s = 10000\n'))
        face = await OpcUaFace(emulator, "127.0.0.1", port).start()
        print(json.dumps({"port": face.port}), flush=True)
        cycle = 0
        async for cycle in _cycles():  # every cycle every word changes: a PLC program writing 1000 words
            emulator.plc.write(0x84, 200, 0, (cycle & 0xFFFF).to_bytes(2, "big") * ITEMS)
    server = Server()
    await server.init()
    server.set_endpoint(f"opc.tcp://127.0.0.1:{port}/")
    ns = await server.register_namespace("anchor")
    folder = await server.nodes.objects.add_folder(ua.NodeId("plain", ns), "plain")
    nodes = [await folder.add_variable(ua.NodeId(name, ns), name, ua.Variant(0, ua.VariantType.UInt16))
             for name in _ids("anchor")]
    await server.start()
    print(json.dumps({"port": port}), flush=True)
    async for cycle in _cycles():  # asyncua's documented way: Node.write_value (a DataValue each)
        variant = ua.Variant(cycle & 0xFFFF, ua.VariantType.UInt16)
        for node in nodes:
            await node.write_value(variant)


async def _cycles() -> Any:
    """Cycle numbers at a fixed rate (every CYCLE_S from the start, not CYCLE_S after the last write): a
    server slower than that makes fewer changes, which the subscriber counts."""
    loop = asyncio.get_running_loop()
    due = loop.time()
    cycle = 0
    while True:
        cycle += 1
        yield cycle
        due += CYCLE_S
        await asyncio.sleep(max(0.0, due - loop.time()))


async def subscribe(url: str, kind: str, seconds: float) -> None:
    from asyncua import Client, ua

    # Every value is the writer's cycle number, so per item (last - first seen) is how many changes the
    # server made in the window and the notification count how many reached us: their gap is loss.
    seen: dict[Any, list[int]] = {}
    measuring = {"on": False}

    class Handler:
        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            if not measuring["on"]:
                return
            entry = seen.get(node)
            if entry is None:
                seen[node] = [int(value), int(value), 0]
            else:
                entry[1] = int(value)
                entry[2] += 1

    async with Client(url, **CLIENT) as client:
        ns = 2
        subscription = await client.create_subscription(100, Handler())
        nodes = [client.get_node(ua.NodeId(i, ns)) for i in _ids(kind)]
        await subscription.subscribe_data_change(nodes, queuesize=10, sampling_interval=100)
        await asyncio.sleep(1.0)
        measuring["on"] = True
        start = time.monotonic()
        await asyncio.sleep(seconds)
        measuring["on"] = False
        elapsed = time.monotonic() - start
    made = sum((last - first) & 0xFFFF for first, last, _ in seen.values())
    delivered = sum(count for _, _, count in seen.values())
    print(json.dumps({"updates_per_s": delivered / elapsed, "changes_per_s": made / elapsed}), flush=True)


async def read(url: str, kind: str, seconds: float) -> None:
    from asyncua import Client, ua

    async with Client(url, **CLIENT) as client:
        ids = [ua.NodeId(i, 2) for i in _ids(kind)[:10]]
        params = ua.ReadParameters()
        params.NodesToRead = [ua.ReadValueId(i, ua.AttributeIds.Value) for i in ids]
        values = 0
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            results = await client.uaclient.read(params)
            values += len(results)
    print(json.dumps({"values_per_s": values / seconds}), flush=True)


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def measure(kind: str, seconds: float) -> dict[str, float]:
    port = _free_port()
    server = subprocess.Popen([sys.executable, str(HERE), "--serve", kind, "--port", str(port)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert server.stdout is not None
        port = json.loads(server.stdout.readline())["port"]
        url = f"opc.tcp://127.0.0.1:{port}/"
        subscriber = subprocess.Popen([sys.executable, str(HERE), "--subscribe", url, "--kind", kind,
                                       "--seconds", str(seconds)], stdout=subprocess.PIPE, text=True)
        time.sleep(1.5)  # connected, monitored, first values through
        cpu0, t0 = _cpu_s(server.pid), time.monotonic()
        out, _ = subscriber.communicate(timeout=120)
        cpu_share = (_cpu_s(server.pid) - cpu0) / (time.monotonic() - t0)
        counted = json.loads(out.strip().splitlines()[-1])
        updates, changes = counted["updates_per_s"], counted["changes_per_s"]
        readers = [subprocess.Popen([sys.executable, str(HERE), "--read", url, "--kind", kind,
                                     "--seconds", str(seconds)], stdout=subprocess.PIPE, text=True)
                   for _ in range(READERS)]
        reads = sum(json.loads(r.communicate(timeout=120)[0].strip().splitlines()[-1])["values_per_s"]
                    for r in readers)
    finally:
        server.terminate()
        server.wait(timeout=30)
    return {"server_cpu": cpu_share, "updates_per_s": updates, "expected_per_s": ITEMS / CYCLE_S,
            "changes_per_s": changes,
            "reads_per_s": reads}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--serve", choices=("ours", "anchor"))
    parser.add_argument("--subscribe")
    parser.add_argument("--read")
    parser.add_argument("--kind", default="ours")
    parser.add_argument("--port", type=int, default=0)
    args = parser.parse_args()
    if args.serve:
        asyncio.run(serve(args.serve, args.port))
        return 0
    if args.subscribe:
        asyncio.run(subscribe(args.subscribe, args.kind, args.seconds))
        return 0
    if args.read:
        asyncio.run(read(args.read, args.kind, args.seconds))
        return 0
    results = {kind: measure(kind, args.seconds) for kind in ("anchor", "ours")}
    anchor, ours = results["anchor"], results["ours"]
    print(f"{ITEMS} monitored items, values changing every {CYCLE_S * 1000:.0f} ms, publishing 100 ms; "
          f"{READERS} reader processes x 10 values per request; {args.seconds:g} s each")
    print(f"{'':28}{'anchor (asyncua plain)':>24}{'nckemu OPC UA face':>22}{'ratio':>8}")
    for key, label in (("server_cpu", "server CPU (cores)"), ("updates_per_s", "updates delivered/s"),
                       ("reads_per_s", "values read/s (8 procs)")):
        ratio = ours[key] / anchor[key] if anchor[key] else float("nan")
        print(f"{label:28}{anchor[key]:>24.2f}{ours[key]:>22.2f}{ratio:>8.2f}")
    per_update = [r["server_cpu"] / r["updates_per_s"] * 1e6 if r["updates_per_s"] else float("nan")
                  for r in (anchor, ours)]
    print(f"{'server CPU us per update':28}{per_update[0]:>24.1f}{per_update[1]:>22.1f}"
          f"{per_update[1] / per_update[0]:>8.2f}")
    print(f"{'updates expected/s':28}{anchor['expected_per_s']:>24.0f}{ours['expected_per_s']:>22.0f}")
    print(f"{'value changes made/s':28}{anchor['changes_per_s']:>24.0f}{ours['changes_per_s']:>22.0f}")
    lost = [1 - r["updates_per_s"] / r["changes_per_s"] if r["changes_per_s"] else float("nan")
            for r in (anchor, ours)]
    print(f"{'changes not delivered':28}{lost[0]:>24.1%}{lost[1]:>22.1%}")
    print(f"load average: {os.getloadavg()[0]:.2f} (2 cores)")
    print(f"target: CPU ratio <= 1.2 ({'met' if ours['server_cpu'] <= 1.2 * anchor['server_cpu'] else 'NOT met'}), "
          f"no lost updates ({'met' if lost[1] <= 0.001 else 'NOT met'})")
    made = [r["changes_per_s"] / r["expected_per_s"] for r in (anchor, ours)]
    print(f"changes made against the 100 ms cycle's: anchor {made[0]:.0%}, face {made[1]:.0%} (a server process "
          "too busy to keep its writer's time makes fewer changes; those are not lost updates)")
    print("(a change the server made but no notification carried is lost)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
