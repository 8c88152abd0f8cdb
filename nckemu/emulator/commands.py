"""``nckemu serve``: run the emulator on ISO-on-TCP."""

from __future__ import annotations

import argparse
import asyncio
import errno
import json
import logging
import sys
from collections.abc import Callable, Sequence

from nckemu.cliutil import check_output, listen_port, until_signalled
from nckemu.emulator.faces import Face
from nckemu.emulator.faces.s7.server import EmulatorServer, ServerLimits
from nckemu.emulator.machine.clock import Clock
from nckemu.emulator.machine.core import Emulator
from nckemu.errors import NckConfigError, NckError
from nckemu.textfile import read_text

log = logging.getLogger(__name__)

EXAMPLE = """\
examples:
  nckemu serve --port 1102
  nckemu serve --machine fixtures/machines/warm_z.toml --state state.json --record session.pcapng
  nckemu serve --port 1102 --opcua 4840
  nckemu serve --port 1102 --program fixtures/programs/SHORT.MPF
then, e.g. with python-snap7 (and asyncua's uaread -u opc.tcp://127.0.0.1:4840/ -n 'ns=2;s=/Bag/State/opMode'):
  import snap7; c = snap7.Client(); c.connect("127.0.0.1", 0, 4, 1102); print(c.get_cpu_info())
"""


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    parser = subparsers.add_parser(
        "serve", help="run the NCK/PLC emulator", epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Serve an emulated SINUMERIK NCU (NCK + PLC) on ISO-on-TCP (S7comm).")
    parser.add_argument("--machine", help="machine TOML (default: the built-in default machine)")
    parser.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    parser.add_argument("--port", type=listen_port, default=102,
                        help="TCP port 1..65535, 0 for any free one (default 102, needs root; make serve uses 1102)")
    parser.add_argument("--state", help="retained-data file (SD/MD survive restarts)")
    parser.add_argument("--record", help="write every frame both ways to this pcapng file")
    parser.add_argument("--lec", action="append", default=[],
                        help="leadscrew compensation NC program to load at start (repeatable)")
    parser.add_argument("--max-connections", type=int, default=ServerLimits.max_connections,
                        help=f"connections served at once; one more is refused at connect "
                             f"(default {ServerLimits.max_connections})")
    parser.add_argument("--idle-timeout", type=float, default=ServerLimits.idle_timeout_s,
                        help="seconds without a byte before a connection is closed")
    parser.add_argument("--partial-frame-timeout", type=float, default=ServerLimits.partial_frame_timeout_s,
                        help="seconds a begun frame may take to complete")
    parser.add_argument("--event-loop", choices=("auto", "uvloop", "asyncio"), default="auto",
                        help="event loop: uvloop (faster, libuv) when installed, else asyncio's own (auto)")
    parser.add_argument("--http", type=listen_port, metavar="PORT",
                        help="also serve a live page of the machine on http://HOST:PORT/ (axes, sensors, "
                             "compensation over time, PLC, clients)")
    parser.add_argument("--opcua", type=listen_port, default=None, metavar="PORT",
                        help="also serve OPC UA (SINUMERIK node ids, same model) on PORT, e.g. 4840 (default off)")
    parser.add_argument("--program", action="append", default=[], metavar="FILE",
                        help="store this part program (and the .MPF/.SPF files beside it) and select the first "
                             "one in channel 1; NC start is DB21.DBX7.1 (docs/programs.md); repeatable")
    parser.add_argument("--json", action="store_true", help="print the ready line as JSON on stdout")
    parser.set_defaults(func=run_serve)

    machine = subparsers.add_parser(
        "machine", help="show a machine: axes, drives, tools, sensors, PLC memory, access, OPC UA",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  nckemu machine show\n  nckemu machine show --machine fixtures/machines/bed_ramp.toml\n")
    machine_commands = machine.add_subparsers(dest="machine_command", metavar="COMMAND")
    show = machine_commands.add_parser(
        "show", help="what a machine TOML (or the built-in default machine) serves",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  nckemu machine show\n  nckemu machine show --machine fixtures/machines/bed_ramp.toml --json\n")
    show.add_argument("--machine", help="machine TOML (default: the built-in default machine)")
    show.add_argument("--json", action="store_true", help="print the machine as JSON on stdout")
    show.set_defaults(func=run_machine_show)
    machine.set_defaults(func=lambda args: machine.print_help() or 2)


def run_machine_show(args: argparse.Namespace) -> int:
    from nckemu.emulator.machine_check import checked_machine
    from nckemu.emulator.machine_show import machine_document, print_machine

    # Built as serve builds it: what serve refuses, show refuses (file, line, field).
    emulator, opcua = checked_machine(args.machine)
    document = machine_document(emulator.machine, opcua)
    if args.json:
        print(json.dumps(document))
        return 0
    print_machine(document)
    return 0


def loop_factory(choice: str = "auto") -> Callable[[], asyncio.AbstractEventLoop]:
    """uvloop's loop when it is installed (and not refused), else asyncio's."""
    if choice != "asyncio":
        try:
            import uvloop
        except ImportError:
            if choice == "uvloop":
                raise NckConfigError("--event-loop uvloop: uvloop is not installed (pip install uvloop)") from None
        else:
            return uvloop.new_event_loop
    return asyncio.new_event_loop


def _read_program(path: str) -> str:
    return read_text(path, "an NC program is text")


# Builds a further face of a served machine (a living machine, an OPC UA face) from the emulator and
# its S7 server, before anything listens: bad input is refused then, in one line.
FaceFactory = Callable[[Emulator, EmulatorServer], Face]


def run_serve(args: argparse.Namespace, *, clock: Clock | None = None, faces: Sequence[FaceFactory] = ()) -> int:
    check_output(args.record, "--record")
    check_output(args.state, "--state")
    programs = [(path, _read_program(path)) for path in args.lec]
    emulator = Emulator(args.machine, state_path=args.state, clock=clock)
    for path, text in programs:
        if not emulator.nck.load_leadscrew_program(text, source=path):
            raise NckConfigError("no leadscrew table in it (expected $AA_ENC_COMP[...] lines)", path=path)
    if args.lec:
        emulator.power_on()
    if getattr(args, "program", None):
        from nckemu.emulator.program_commands import store_programs

        emulator.nck.channels[1].select(store_programs(emulator, args.program))
    limits = ServerLimits(max_connections=args.max_connections, idle_timeout_s=args.idle_timeout,
                          partial_frame_timeout_s=args.partial_frame_timeout)
    server = EmulatorServer(emulator, host=args.host, port=args.port, limits=limits,
                            record_path=args.record)
    built = [make(emulator, server) for make in faces]
    if getattr(args, "http", None) is not None:
        from nckemu.emulator.faces.web import WebFace

        built.append(WebFace(emulator, server, host=args.host, port=args.http))
    if getattr(args, "opcua", None) is not None:
        from nckemu.emulator.faces.opcua import OpcUaFace
        from nckemu.emulator.machine_check import opcua_settings

        # the [opcua] table refused with its line, as machine show refuses it (one path for both)
        built.append(OpcUaFace(emulator, args.host, args.opcua, opcua_settings(emulator.machine)))
    try:
        with asyncio.Runner(loop_factory=loop_factory(args.event_loop)) as runner:
            return runner.run(_serve(server, args, built))
    except KeyboardInterrupt:
        return 0


async def _start_faces(faces: Sequence[Face], args: argparse.Namespace) -> list[Face]:
    """Start each face after the S7 face; one that cannot (a port in use) is one line, exit 1."""
    started: list[Face] = []
    for face in faces:
        try:
            await face.start()
        except OSError as exc:
            port = getattr(face, "port", "?")
            what = getattr(face, "what", type(face).__name__)
            reason = "is already in use" if exc.errno == errno.EADDRINUSE else f"cannot be bound ({exc.strerror})"
            print(f"nckemu serve: {what}: {args.host}:{port} {reason}; use another port", file=sys.stderr)
            break
        except NckError as exc:
            print(f"nckemu serve: {exc}", file=sys.stderr)
            break
        started.append(face)
    else:
        return started
    for face in reversed(started):
        await face.stop()
    return []


async def _serve(server: EmulatorServer, args: argparse.Namespace, faces: Sequence[Face] = ()) -> int:
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
    started = await _start_faces(faces, args)
    if len(started) < len(faces):
        await server.stop()
        return 1
    machine_name = getattr(server.emulator.machine, "name", "default")
    ready = {"host": args.host, "port": server.port, "machine": machine_name,
             "state": args.state, "record": args.record}
    for face in started:
        ready.update(getattr(face, "ready", {}))
    if args.json:
        print(json.dumps(ready), flush=True)
    else:
        print(f"nckemu: machine '{machine_name}' on {args.host}:{server.port} "
              f"(NCK: rack 0 slot 4, PLC: rack 0 slot 2; any TSAP is accepted). Ctrl-C stops.\n"
              f"  python-snap7: c = snap7.Client(); c.connect('{args.host}', 0, 4, {server.port})\n"
              f"  nckemu get --port {server.port} SD43900[AX4]", flush=True)
        for face in started:
            if getattr(face, "ready_line", None):
                print(f"  {face.ready_line}", flush=True)
    try:
        await until_signalled()
    finally:
        for face in reversed(started):
            await face.stop()
        await server.stop()
        print("nckemu: stopped; retained state flushed" if args.state else "nckemu: stopped",
              flush=True)
    return 0
