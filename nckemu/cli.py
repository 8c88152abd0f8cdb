"""The ``nckemu`` command.

Each area of the project registers its own subcommands from a ``commands`` module with a
``register(subparsers)`` function; every subcommand sets ``func(args) -> int`` (the exit code).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

import nckemu
from nckemu.errors import NckConfigError, NckError

COMMAND_MODULES = (
    "nckemu.emulator.commands",   # serve, machine show
    "nckemu.emulator.fleet_commands",  # fleet
    "nckemu.catalogue.commands",  # vars
    "nckemu.clients.commands",    # get, put, pi, comp840c, lec
    "nckemu.clients.program_commands",  # program put, get, list, select, start, stop, reset
    "nckemu.traces.commands",     # trace show, trace replay
    "nckemu.thermal.commands",    # simulate, discover
    "nckemu.thermal.recordings.commands",  # recording import, recording check
    "nckemu.plcsim.commands",     # plc run, plc stubs
    "nckemu.plcsim.fleet_live",   # fleet: living machines (inputs/plc in a [[machine]])
    "nckemu.emulator.program_commands",  # program run (the program group)
    "nckemu.twin.commands",       # machine fit, machine compare
)

# Which modules register (or extend) each command. A command line names one command, so only its
# modules are imported: `nckemu get` starts without the emulator, the interpreter or numpy (about half a
# second less for every client call a script or a PLC test makes). tests/test_cli.py keeps this equal to
# what the whole command line builds.
COMMAND_HOMES: dict[str, tuple[str, ...]] = {
    "serve": ("nckemu.emulator.commands", "nckemu.plcsim.commands"),  # plcsim adds the living machine
    "machine": ("nckemu.emulator.commands", "nckemu.twin.commands"),
    "fleet": ("nckemu.emulator.fleet_commands", "nckemu.plcsim.fleet_live"),
    "vars": ("nckemu.catalogue.commands",),
    **dict.fromkeys(("get", "put", "pi", "comp840c", "lec"), ("nckemu.clients.commands",)),
    "program": ("nckemu.clients.program_commands", "nckemu.emulator.program_commands"),
    "trace": ("nckemu.traces.commands",),
    "simulate": ("nckemu.thermal.commands",),
    "discover": ("nckemu.thermal.commands", "nckemu.plcsim.commands"),  # plcsim adds --write-stl
    "recording": ("nckemu.thermal.recordings.commands",),
    "plc": ("nckemu.plcsim.commands",),
    "loop": ("nckemu.plcsim.commands",),
}

log = logging.getLogger(__name__)


class _Parser(argparse.ArgumentParser):
    """argparse with one line for a usage error and exit code 1 (bad input, as every command's)."""

    def error(self, message: str) -> NoReturn:
        self.exit(1, f"{self.prog}: {message} (see {self.prog} --help)\n")


class _VersionAction(argparse.Action):
    """argparse's version action, with the installed version looked up only when asked for."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS,
                 default: str = argparse.SUPPRESS, help: str = "show program's version number and exit") -> None:
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: object, option_string: str | None = None) -> None:
        print(f"nckemu {nckemu.__version__}")
        parser.exit()


def _add_logging_options(parser: argparse.ArgumentParser, *, top: bool) -> None:
    # On every command too, so that `nckemu serve -v` works as `nckemu -v serve`; SUPPRESS keeps a
    # subcommand from resetting what the top level set.
    default: object = 0 if top else argparse.SUPPRESS
    parser.add_argument("-v", "--verbose", action="count", default=default,
                        help="more log output (-v info, -vv debug); serve logs at info already")
    parser.add_argument("--log-file", metavar="FILE", default=None if top else argparse.SUPPRESS,
                        help="append the log to FILE instead of stderr")


def _walk(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):
                found += [sub, *_walk(sub)]
    return found


def _command_word(argv: Sequence[str]) -> str | None:
    """The command an argument list names (its first word that is not a top-level option), if any."""
    words = iter(argv)
    for word in words:
        if word == "--log-file":
            next(words, None)
        elif not word.startswith("-"):
            return word
    return None


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The whole command line's parser; given ``argv`` naming a known command, only that command's."""
    command = _command_word(argv) if argv is not None else None
    modules = COMMAND_MODULES
    if command in COMMAND_HOMES:
        modules = tuple(name for name in COMMAND_MODULES if name in COMMAND_HOMES[command])
    parser = _Parser(
        prog="nckemu",
        description="A SINUMERIK NCK/PLC stand-in on the wire, and the tools around it.",
        epilog="Example: nckemu serve --port 1102   then   nckemu get --port 1102 SD43900[AX4]\n"
               "Client commands reach NCKEMU_HOST:NCKEMU_PORT (default 127.0.0.1:102) unless --host/--port say.\n"
               "--json prints machine-readable output on stdout; --json-out FILE (- for stdout) writes it to a file.\n",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action=_VersionAction)
    _add_logging_options(parser, top=True)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in modules:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            continue
        module.register(subparsers)
    for sub in _walk(parser):
        _add_logging_options(sub, top=False)
    return parser


def _configure_logging(args: argparse.Namespace) -> None:
    # The server says who connects and which jobs it refuses without -v; the other commands warn only.
    base = logging.INFO if args.command == "serve" else logging.WARNING
    level = max(logging.DEBUG, base - 10 * min(args.verbose, 2))
    handler: logging.Handler
    if args.log_file:
        try:
            handler = logging.FileHandler(args.log_file, encoding="utf-8")
        except OSError as exc:
            raise NckConfigError(f"--log-file: cannot write: {exc.strerror}", path=args.log_file) from None
    else:
        handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    handler.set_name("nckemu")
    root = logging.getLogger()
    for old in [h for h in root.handlers if h.get_name() == "nckemu"]:  # an earlier main() in this process
        root.removeHandler(old)
        old.close()
    root.addHandler(handler)
    root.setLevel(level)


def main(argv: Sequence[str] | None = None) -> int:
    arguments = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(arguments)
    try:
        args = parser.parse_args(arguments)
    except SystemExit as exc:  # --help, --version (0) and usage errors (1): a code, not an exit, for callers
        return exc.code if isinstance(exc.code, int) else 1
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    command = " ".join(part for part in (args.command, getattr(args, "plc_command", None),
                                         getattr(args, "trace_command", None),
                                         getattr(args, "machine_command", None),
                                         getattr(args, "recording_command", None)) if part)
    try:
        _configure_logging(args)
        return int(func(args) or 0)
    except NckError as exc:
        print(f"nckemu {command}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # `nckemu ... | head`: the reader has gone; nothing is lost by stopping
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (OSError, UnicodeDecodeError) as exc:  # last resort: each known case is caught where it happens
        where = f" ({exc.filename})" if isinstance(exc, OSError) and exc.filename else ""
        print(f"nckemu {command}: {exc.__class__.__name__}{where}: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
