"""``nckemu program put | get | list | select | start | stop | reset``: part programs on a control.

The same telegrams drive the emulator and a real SINUMERIK: NC program transfer (userdata "NC
programming", as libnodave sends it), PI ``_N_F_XFER`` / ``_N_SELECT``, and rising edges on the
channel's DB21.DBX7.1 (NC start), 7.3 (NC stop), 7.7 (reset).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TypeVar

from nckemu.catalogue.program_names import program_path, user_name
from nckemu.cliutil import command_group
from nckemu.errors import NckConfigError

from . import programs
from .async_client import AsyncNckClient
from .commands import _client, _connection_options

T = TypeVar("T")


def _on_client(args: argparse.Namespace, call: Callable[[AsyncNckClient], Awaitable[T]]) -> T:
    """One call on a connection opened from the command's options, closed after it."""
    async def go() -> T:
        async with _client(args) as client:
            return await call(client)
    return asyncio.run(go())

GROUP_HELP = "part programs: send, fetch, list, select, start, stop, reset"
NAMES = ("Names as users write them (DAILY.MPF, WARMUP_CYCLE.SPF; a bare name is a main program) or as "
         "the control does (_N_DAILY_MPF, /_N_MPF_DIR/_N_DAILY_MPF).")


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    group = command_group(subparsers, "program", GROUP_HELP)
    parent = subparsers.choices["program"]
    examples = "examples:\n  nckemu program list --port 1102\n  nckemu program get --port 1102 TEST.MPF\n"
    parent.formatter_class = argparse.RawDescriptionHelpFormatter
    parent.epilog = (parent.epilog or "") + examples
    raw = argparse.RawDescriptionHelpFormatter

    put = group.add_parser(
        "put", help="send a program to the control (NC program download)", formatter_class=raw,
        description=f"Send a file as a part program; it replaces a program of that name whole, once the "
                    f"transfer has ended.\n\n{NAMES}",
        epilog="examples:\n  nckemu program put --port 1102 fixtures/lec/z_axis.mpf\n"
               "  nckemu program put --port 1102 fixtures/lec/z_axis.mpf --name WARMUP_CYCLE.SPF\n")
    put.add_argument("file", help="the program's text, e.g. DAILY.MPF (sent as it is, line ends included)")
    put.add_argument("--name", help="the program's name on the control (default: the file's name, "
                                    "e.g. DAILY.MPF)")
    _connection_options(put)
    put.set_defaults(func=run_put)

    get = group.add_parser(
        "get", help="fetch a program from the control (PI _N_F_XFER, NC program upload)", formatter_class=raw,
        description=f"Fetch a part program's text.\n\n{NAMES}",
        epilog="examples:\n  nckemu program get --port 1102 TEST.MPF\n"
               "  nckemu program get --port 1102 /_N_MPF_DIR/_N_TEST_MPF --out TEST.MPF\n")
    get.add_argument("name", help="the program, e.g. DAILY.MPF or /_N_MPF_DIR/_N_DAILY_MPF")
    get.add_argument("--out", help="write the text to this file instead of printing it")
    _connection_options(get)
    get.set_defaults(func=run_get)

    listing = group.add_parser(
        "list", help="list a directory of programs (upload of the directory)", formatter_class=raw,
        epilog="examples:\n  nckemu program list --port 1102\n  nckemu program list --port 1102 SPF_DIR\n")
    listing.add_argument("directory", nargs="?", default="_N_MPF_DIR",
                         help="MPF_DIR (main programs, the default), SPF_DIR (subprograms), WKS_DIR, or a "
                              "path such as /_N_WKS_DIR/_N_PART_WPD")
    _connection_options(listing)
    listing.set_defaults(func=run_list)

    select = group.add_parser(
        "select", help="select a program for the channel (PI _N_SELECT)", formatter_class=raw,
        epilog="example: nckemu program select --port 1102 TEST.MPF\n")
    select.add_argument("name", help="the program, e.g. DAILY.MPF")
    _connection_options(select)
    select.set_defaults(func=run_select)

    for signal, what, bit in (("start", "NC start", "7.1"), ("stop", "NC stop", "7.3"), ("reset", "reset", "7.7")):
        command = group.add_parser(
            signal, help=f"{what}: a rising edge on DB21.DBX{bit} (DB21 + channel - 1)", formatter_class=raw,
            description=f"{what} as the PLC gives it: DB21.DBX{bit} written 1, then 0.",
            epilog=f"example: nckemu program {signal} --port 1102\n")
        command.add_argument("--channel", type=int, default=1, help="the channel, 1.. (DB21 is channel 1)")
        _connection_options(command)
        command.set_defaults(func=run_signal, signal=signal)


def _read_program(path_text: str) -> bytes:
    path = Path(path_text)
    try:
        return path.read_bytes()
    except OSError as exc:
        raise NckConfigError(f"{path}: cannot read ({exc.strerror or exc})") from None


def run_put(args: argparse.Namespace) -> int:
    name = args.name or Path(args.file).name
    program_path(name)  # a name that is no NC file name is refused before anything is sent
    text = _read_program(args.file)
    path = _on_client(args, lambda client: programs.put_program(client, name, text))
    print(json.dumps({"path": path, "name": user_name(path), "bytes": len(text)}) if args.json
          else f"{user_name(path)} ({path}): {len(text)} bytes sent")
    return 0


def run_get(args: argparse.Namespace) -> int:
    path = program_path(args.name)
    text = _on_client(args, lambda client: programs.get_program(client, path))
    if args.out:
        try:
            Path(args.out).write_bytes(text)
        except OSError as exc:
            raise NckConfigError(f"{args.out}: cannot write ({exc.strerror or exc})") from None
    if args.json:
        print(json.dumps({"path": path, "name": user_name(path), "bytes": len(text),
                          **({} if args.out else {"text": _as_text(text)})}))
    elif args.out:
        print(f"{user_name(path)}: {len(text)} bytes written to {args.out}")
    else:
        # The stored bytes as they are (``program get NAME > NAME.MPF`` is the file that was sent, in
        # whatever encoding it had); a terminal gets a line end after a text without one.
        sys.stdout.flush()
        sys.stdout.buffer.write(text)
        if sys.stdout.isatty() and text and not text.endswith(b"\n"):
            sys.stdout.buffer.write(b"\n")
        sys.stdout.buffer.flush()
    return 0


def _as_text(data: bytes) -> str:
    """A program's bytes as text for JSON: UTF-8 where they are, else Latin-1 (as the control reads it)."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def run_list(args: argparse.Namespace) -> int:
    listing = _on_client(args, lambda client: programs.list_directory(client, args.directory))
    if args.json:
        print(json.dumps({"directory": listing.directory,
                          "entries": [{"name": name, "user_name": user_name(f"/{name}"), "bytes": size}
                                      for name, size in listing.entries]}))
        return 0
    print(f"{listing.directory}: {len(listing.entries)} entries")
    for name, size in listing.entries:
        print(f"  {user_name('/' + name):<28} {'' if size is None else size:>10}  {name}")
    return 0


def run_select(args: argparse.Namespace) -> int:
    path = _on_client(args, lambda client: programs.select_program(client, args.name))
    print(json.dumps({"selected": path}) if args.json else f"{user_name(path)} ({path}) selected")
    return 0


def run_signal(args: argparse.Namespace) -> int:
    address = programs.signal_address(args.signal, args.channel)
    _on_client(args, lambda client: programs.pulse(client, args.signal, args.channel))
    print(json.dumps({"signal": args.signal, "channel": args.channel, "address": address}) if args.json
          else f"{args.signal}: rising edge on {address} (channel {args.channel})")
    return 0
