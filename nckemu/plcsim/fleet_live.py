"""Living machines in a fleet: ``nckemu fleet`` with ``inputs``/``plc``/``speed`` in a ``[[machine]]``.

The fleet lives in the emulator, which never imports plcsim; this module hands it the living machine
(``LiveMachine`` on the machine's own ``LiveClock``), as ``serve_live`` does for ``nckemu serve``.
"""

from __future__ import annotations

import argparse
import functools
from typing import Any

from nckemu.emulator.faces.s7.server import EmulatorServer
from nckemu.emulator.fleet import FaceFactory, FleetMachine
from nckemu.emulator.machine.clock import LiveClock
from nckemu.emulator.machine.core import Emulator
from nckemu.errors import NckConfigError


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    fleet = subparsers.choices.get("fleet")
    if fleet is not None:
        fleet.set_defaults(func=functools.partial(_run_living_fleet, fleet.get_default("func")))


def _run_living_fleet(run_fleet: Any, args: argparse.Namespace) -> int:
    return int(run_fleet(args, living=living_machine) or 0)


def living_machine(entry: FleetMachine, source: str) -> tuple[LiveClock, FaceFactory]:
    """The clock and the face of a living ``[[machine]]``; bad values name the fleet file's line."""
    from .commands import _cycle
    from .live import LiveMachine, parse_speed

    try:
        speed = parse_speed(entry.speed) if entry.speed is not None else 1.0
    except NckConfigError as exc:
        raise NckConfigError(f"machine {entry.name!r}: {exc}", path=source, line=entry.line, field="speed") from None
    try:
        cycle_s = _cycle(entry.cycle) if entry.cycle is not None else 1.0
    except NckConfigError as exc:
        raise NckConfigError(f"machine {entry.name!r}: {exc}", path=source, line=entry.line, field="cycle") from None
    if entry.loop and entry.inputs is None:
        raise NckConfigError(f"machine {entry.name!r}: loop starts a recording over: it needs inputs",
                             path=source, line=entry.line, field="loop")

    def make(emulator: Emulator, server: EmulatorServer) -> LiveMachine:
        try:
            return LiveMachine(emulator, inputs=entry.inputs, plc=entry.plc, speed=speed, loop=entry.loop,
                               cycle_s=cycle_s, server=server)
        except NckConfigError as exc:
            raise NckConfigError(f"machine {entry.name!r}: {exc}", path=source, line=entry.line) from None

    return LiveClock(speed), make
