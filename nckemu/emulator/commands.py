"""``nckemu serve``: run the emulator on ISO-on-TCP."""

from __future__ import annotations

import argparse
import asyncio
import errno
import json
import logging
import signal
import sys
from collections.abc import Callable

from nckemu.errors import NckConfigError

from .core import Emulator
from .server import EmulatorServer, ServerLimits

log = logging.getLogger(__name__)

EXAMPLE = """\
examples:
  nckemu serve --port 1102
  nckemu serve --machine fixtures/machines/lathe.toml --state state.json --record session.pcapng
then, e.g. with python-snap7:
  import snap7; c = snap7.Client(); c.connect("127.0.0.1", 0, 4, 1102); print(c.get_cpu_info())
"""


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    parser = subparsers.add_parser(
        "serve", help="run the NCK/PLC emulator", epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Serve an emulated SINUMERIK NCU (NCK + PLC) on ISO-on-TCP (S7comm).")
    parser.add_argument("--machine", help="machine TOML (default: the built-in default machine)")
    parser.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=102, help="TCP port (default 102, needs root)")
    parser.add_argument("--state", help="retained-data file (SD/MD survive restarts)")
    parser.add_argument("--record", help="write every frame both ways to this pcapng file")
    parser.add_argument("--lec", action="append", default=[],
                        help="leadscrew compensation NC program to load at start (repeatable)")
    parser.add_argument("--max-connections", type=int, default=ServerLimits.max_connections)
    parser.add_argument("--idle-timeout", type=float, default=ServerLimits.idle_timeout_s,
                        help="seconds without a byte before a connection is closed")
    parser.add_argument("--partial-frame-timeout", type=float, default=ServerLimits.partial_frame_timeout_s,
                        help="seconds a begun frame may take to complete")
    parser.add_argument("--loop", choices=("auto", "uvloop", "asyncio"), default="auto",
                        help="event loop: uvloop (faster, libuv) when installed, else asyncio's own (auto)")
    parser.add_argument("--json", action="store_true", help="print the ready line as JSON")
    parser.set_defaults(func=run_serve)


def loop_factory(choice: str = "auto") -> Callable[[], asyncio.AbstractEventLoop]:
    """uvloop's loop when it is installed (and not refused), else asyncio's."""
    if choice != "asyncio":
        try:
            import uvloop
        except ImportError:
            if choice == "uvloop":
                raise NckConfigError("--loop uvloop: uvloop is not installed (pip install uvloop)") from None
        else:
            return uvloop.new_event_loop
    return asyncio.new_event_loop


def run_serve(args: argparse.Namespace) -> int:
    emulator = Emulator(args.machine, state_path=args.state)
    for path in args.lec:
        with open(path, encoding="utf-8") as handle:
            emulator.nck.load_leadscrew_program(handle.read(), source=path)
    if args.lec:
        emulator.power_on()
    limits = ServerLimits(max_connections=args.max_connections, idle_timeout_s=args.idle_timeout,
                          partial_frame_timeout_s=args.partial_frame_timeout)
    server = EmulatorServer(emulator, host=args.host, port=args.port, limits=limits,
                            record_path=args.record)
    try:
        with asyncio.Runner(loop_factory=loop_factory(args.loop)) as runner:
            return runner.run(_serve(server, args))
    except KeyboardInterrupt:
        return 0


async def _serve(server: EmulatorServer, args: argparse.Namespace) -> int:
    try:
        await server.start()
    except OSError as exc:
        if exc.errno in (errno.EACCES, errno.EPERM):
            print(f"nckemu serve: cannot bind {args.host}:{args.port} (permission denied: ports below "
                  f"1024 need root). Try: nckemu serve --port 1102", file=sys.stderr)
        elif exc.errno == errno.EADDRINUSE:
            other = args.port + 1 if args.port >= 1024 else 1102
            print(f"nckemu serve: {args.host}:{args.port} is already in use (another nckemu serve?). "
                  f"Stop it, or use another port, e.g. --port {other} (make serve PORT={other})", file=sys.stderr)
        else:
            print(f"nckemu serve: cannot bind {args.host}:{args.port}: {exc}", file=sys.stderr)
        return 1
    machine_name = getattr(server.emulator.machine, "name", "default")
    ready = {"host": args.host, "port": server.port, "machine": machine_name,
             "state": args.state, "record": args.record}
    if args.json:
        print(json.dumps(ready), flush=True)
    else:
        print(f"nckemu: machine '{machine_name}' on {args.host}:{server.port} "
              f"(NCK: rack 0 slot 4, PLC: rack 0 slot 2; any TSAP is accepted). Ctrl-C stops.\n"
              f"  python-snap7: c = snap7.Client(); c.connect('{args.host}', 0, 4, {server.port})\n"
              f"  nckemu get --port {server.port} SD43900[AX4]", flush=True)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            loop.add_signal_handler(sig, stop.set)
        except (NotImplementedError, RuntimeError):
            pass
    try:
        await stop.wait()
    finally:
        await server.stop()
        print("nckemu: stopped; retained state flushed" if args.state else "nckemu: stopped",
              flush=True)
    return 0
