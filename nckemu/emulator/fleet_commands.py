"""``nckemu fleet``: many emulated machines in one process."""

from __future__ import annotations

import argparse
import asyncio
import gc
import json

from nckemu.cliutil import port_number, until_signalled
from nckemu.emulator.commands import loop_factory
from nckemu.emulator.faces.s7.server import ServerLimits
from nckemu.emulator.fleet import Fleet, LivingHook, load_fleet, quick_fleet
from nckemu.errors import NckConfigError

EXAMPLE = """\
examples:
  nckemu fleet fixtures/fleets/lab.toml
  nckemu fleet --count 100 --base-port 21001 --machine fixtures/machines/bed_ramp.toml --state states/
  nckemu fleet --count 5 --base-port 21001 --opcua-base-port 24841
a fleet file:
  [fleet]                       # defaults for every machine (optional)
  machine = "../machines/bed_ramp.toml"
  [[machine]]
  name = "mill-01"
  port = 21001                  # or host = "127.0.0.12" and port = 102 (as root)
  opcua = 24841                 # optional: its OPC UA face (about 6 MB and well under a second each)
  [[machine]]
  name = "lathe-02"
  port = 21002
  machine = "../machines/warm_z.toml"
  [[machine]]                   # a living machine: a recording and a PLC program on its own clock
  name = "mill-03"
  port = 21003
  inputs = "../thermal/loop_bed_program_spindle_lag.csv"
  plc = "../plc/bed_only_z.awl"
  speed = "600x"                # also: cycle = "1s", loop = true (the recording starts over)
measured by bench/bench_fleet.py (2026-11-27): an extra machine takes about 0.06 MB, 5.5 MB with an
  OPC UA face (--opcua-only: 20 machines with OPC UA 199 MB RSS, one 95 MB); after SIGTERM a fleet of
  20 with OPC UA exits in about 1 s (the faces stop at once)
"""


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    parser = subparsers.add_parser(
        "fleet", help="serve many machines from one process", epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Serve the machines of a fleet file (or N copies of one machine) on one event loop; "
                    "each machine has its own address and state.")
    parser.add_argument("fleet", nargs="?", help="fleet TOML ([[machine]] tables: name, port, host, machine)")
    parser.add_argument("--count", type=int, help="instead of a fleet file: this many machines")
    parser.add_argument("--base-port", type=port_number, help="with --count: the first machine's port")
    parser.add_argument("--opcua-base-port", type=port_number,
                        help="with --count: an OPC UA face for each machine, the first on this port")
    parser.add_argument("--machine", help="with --count: machine TOML (default: the built-in default machine)")
    parser.add_argument("--host", default="127.0.0.1", help="with --count: address to bind (default 127.0.0.1)")
    parser.add_argument("--state", metavar="DIR", help="keep each machine's retained data in DIR/<name>.json")
    parser.add_argument("--max-connections", type=int, default=ServerLimits.max_connections,
                        help=f"per machine (default {ServerLimits.max_connections})")
    parser.add_argument("--event-loop", choices=("auto", "uvloop", "asyncio"), default="auto",
                        help="event loop: uvloop when installed, else asyncio's own (auto)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON ready line (every machine's name and address) on stdout")
    parser.set_defaults(func=run_fleet)


def run_fleet(args: argparse.Namespace, *, living: LivingHook | None = None) -> int:
    """``living`` builds the living machines (nckemu.plcsim wraps this command with it)."""
    if args.fleet is not None and args.count is not None:
        raise NckConfigError("give a fleet file or --count, not both")
    if args.fleet is None:
        if args.count is None or args.base_port is None:
            raise NckConfigError("give a fleet file, or --count N --base-port P")
        spec = quick_fleet(args.count, args.base_port, args.machine, args.host, args.opcua_base_port)
    else:
        if args.machine is not None or args.base_port is not None or args.opcua_base_port is not None:
            raise NckConfigError("--machine, --base-port and --opcua-base-port go with --count; a fleet file "
                                 "names its own")
        spec = load_fleet(args.fleet)
    if args.max_connections < 1:
        raise NckConfigError(f"--max-connections {args.max_connections}: at least 1")
    fleet = Fleet(spec, state_dir=args.state, limits=ServerLimits(max_connections=args.max_connections),
                  living=living)
    try:
        with asyncio.Runner(loop_factory=loop_factory(args.event_loop)) as runner:
            return runner.run(_serve(fleet, args))
    except KeyboardInterrupt:
        return 0
    finally:
        # Every machine has stopped and flushed its state. The interpreter's collections at exit would
        # walk each face's objects (4 s of the 5 s after SIGTERM for 20 OPC UA faces, bench_fleet.py):
        # keep them out of it; the process is about to end and frees its memory whole.
        gc.freeze()


async def _serve(fleet: Fleet, args: argparse.Namespace) -> int:
    await fleet.start()
    ready = [machine.ready() for machine in fleet.machines]
    if args.json:
        print(json.dumps({"fleet": fleet.spec.source, "machines": ready}), flush=True)
    else:
        for machine in ready:
            alive = ", living" if machine["living"] else ""
            opcua = f", OPC UA {machine['opcua']}" if "opcua" in machine else ""
            print(f"{machine['name']} {machine['host']}:{machine['port']} ({machine['machine']}{alive}{opcua})")
        print(f"nckemu fleet: {len(ready)} machine(s) serving (NCK: rack 0 slot 4, PLC: rack 0 slot 2). "
              f"Ctrl-C stops.", flush=True)
    try:
        await until_signalled()
    finally:
        await fleet.stop()
        if not args.json:
            print("nckemu fleet: stopped" + ("; retained state flushed" if args.state else ""), flush=True)
    return 0
