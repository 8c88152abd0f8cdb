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

from nckemu import __version__
from nckemu.errors import NckError

COMMAND_MODULES = (
    "nckemu.emulator.commands",   # serve
    "nckemu.catalogue.commands",  # vars
    "nckemu.clients.commands",    # get, put, pi, comp840c
    "nckemu.traces.commands",     # trace show, trace replay
    "nckemu.thermal.commands",    # simulate, discover
    "nckemu.plcsim.commands",     # plc run
)

log = logging.getLogger(__name__)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="nckemu",
        description="A SINUMERIK NCK/PLC stand-in on the wire, and the tools around it.",
        epilog="Example: nckemu serve --port 1102   then   nckemu get --port 1102 SD43900[AX4]",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"nckemu {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output (-v info, -vv debug)")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            continue
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    try:
        return int(func(args) or 0)
    except NckError as exc:
        print(f"nckemu {args.command}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # `nckemu ... | head`: the reader has gone; nothing is lost by stopping
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
