"""Many emulated machines in one process, on one event loop: the fleet file and the running fleet.

A fleet file (TOML) lists ``[[machine]]`` tables: a name, a port (and optionally a loopback address
such as 127.0.0.12, where port 102 can then be used by each machine), a machine file, and the living
machine's recording and PLC program. An optional ``[fleet]`` table gives defaults for every machine
(host, machine file). Relative paths are relative to the fleet file.

Machines share what does not change: the code, the parsed machine file (one ``Machine`` per file) and
the variable table's address index (``nck.store``). Each has its own ``Emulator`` (NCK model, PLC
memory, clock, retained store) and its own server: a write on one is never seen on another, and a
fault on one machine's connection closes that connection only.
"""

from __future__ import annotations

import asyncio
import errno
import ipaddress
import logging
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nckemu.emulator.faces import Face
from nckemu.emulator.faces.s7.server import EmulatorServer, ServerLimits
from nckemu.emulator.machine.clock import Clock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import Machine, load_machine
from nckemu.errors import NckConfigError
from nckemu.textfile import read_text

log = logging.getLogger(__name__)

MACHINE_KEYS = frozenset({"name", "port", "host", "machine", "inputs", "plc", "speed", "cycle", "loop", "opcua"})
FLEET_KEYS = frozenset({"host", "machine"})
DEFAULT_HOST = "127.0.0.1"


@dataclass(frozen=True)
class FleetMachine:
    """One ``[[machine]]`` of a fleet file, checked; paths resolved against the fleet file."""

    name: str
    host: str
    port: int
    machine: str | None = None   # machine TOML; None: the built-in default machine
    inputs: str | None = None    # recording that drives the living machine
    plc: str | None = None       # the user's PLC program (STL) on the living machine
    line: int | None = None      # where it is declared in the fleet file (for messages)
    speed: str | None = None     # the living machine's simulated time per real time ("60x")
    cycle: str | None = None     # its PLC and recording cycle ("1s")
    loop: bool = False           # its recording starts over at its end
    opcua: int | None = None     # the port of its OPC UA face (same host); None: S7 only

    @property
    def address(self) -> str:
        return f"{self.host}:{self.port}"

    @property
    def living(self) -> bool:
        return self.inputs is not None or self.plc is not None or self.speed is not None


# The living machine (a recording and a PLC program on the machine's own live clock) is built above
# the emulator (nckemu.plcsim) and handed in: for a living entry, the clock its Emulator runs on and
# the face that drives it, built from the emulator and its S7 server. Errors name the fleet file line.
FaceFactory = Callable[[Emulator, EmulatorServer], Face]
LivingHook = Callable[[FleetMachine, str], tuple[Clock, FaceFactory]]


@dataclass(frozen=True)
class FleetSpec:
    source: str
    machines: tuple[FleetMachine, ...]


def _table_lines(text: str, header: str) -> list[int]:
    return [number for number, line in enumerate(text.splitlines(), 1) if line.strip() == header]


def _text(row: Mapping[str, Any], key: str, source: str, line: int | None) -> str | None:
    value = row.get(key)
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip():
        raise NckConfigError("expected a non-empty string", path=source, line=line, field=key)
    return value


def _path(row: Mapping[str, Any], key: str, source: str, line: int | None, base: Path,
          default: str | None = None) -> str | None:
    value = _text(row, key, source, line)
    if value is None:
        return default
    resolved = Path(value) if Path(value).is_absolute() else base / value
    if not resolved.is_file():
        raise NckConfigError(f"{value}: no such file", path=source, line=line, field=key)
    return str(resolved)


def _host(value: str | None, source: str, line: int | None) -> str:
    if value is None:
        return DEFAULT_HOST
    try:
        ipaddress.ip_address(value)
    except ValueError:
        raise NckConfigError(f"{value!r} is not an IP address (e.g. 127.0.0.12)", path=source, line=line,
                             field="host") from None
    return value


def _port(row: Mapping[str, Any], source: str, line: int | None, key: str = "port") -> int:
    port = row.get(key)
    if port is None:
        raise NckConfigError("missing (a TCP port, 1..65535; 102 needs root or its own address)",
                             path=source, line=line, field=key)
    if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
        raise NckConfigError(f"{port!r} is not a TCP port (1..65535)", path=source, line=line, field=key)
    return port


def parse_fleet(text: str, source: str, base: Path | None = None) -> FleetSpec:
    """The checked fleet in ``text`` (TOML); ``source`` names it in messages, ``base`` resolves paths."""
    base = base if base is not None else Path(".")
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise NckConfigError(str(exc), path=source) from None
    unknown = sorted(set(document) - {"fleet", "machine"})
    if unknown:
        raise NckConfigError(f"unknown table or key {unknown[0]!r} (known: [fleet], [[machine]])",
                             path=source, field=unknown[0])
    defaults = document.get("fleet", {})
    fleet_line = next(iter(_table_lines(text, "[fleet]")), None)
    if not isinstance(defaults, dict):
        raise NckConfigError("expected a [fleet] table", path=source, field="fleet")
    for key in defaults:
        if key not in FLEET_KEYS:
            raise NckConfigError(f"unknown key (known: {', '.join(sorted(FLEET_KEYS))})", path=source,
                                 line=fleet_line, field=key)
    default_host = _host(_text(defaults, "host", source, fleet_line), source, fleet_line)
    default_machine = _path(defaults, "machine", source, fleet_line, base)
    rows = document.get("machine", [])
    if not isinstance(rows, list) or not all(isinstance(row, dict) for row in rows):
        raise NckConfigError("expected [[machine]] tables", path=source, field="machine")
    if not rows:
        raise NckConfigError("no [[machine]] in it", path=source)
    lines = _table_lines(text, "[[machine]]")
    machines: list[FleetMachine] = []
    names: dict[str, int | None] = {}
    addresses: dict[tuple[str, int], str] = {}
    for index, row in enumerate(rows):
        line = lines[index] if index < len(lines) else None
        for key in row:
            if key not in MACHINE_KEYS:
                raise NckConfigError(f"unknown key (known: {', '.join(sorted(MACHINE_KEYS))})", path=source,
                                     line=line, field=key)
        name = _text(row, "name", source, line)
        if name is None:
            raise NckConfigError("missing (each machine has a name)", path=source, line=line, field="name")
        if name in names:
            raise NckConfigError(f"{name!r} is already the name of the machine on line {names[name]}",
                                 path=source, line=line, field="name")
        names[name] = line
        host = _host(_text(row, "host", source, line), source, line) if "host" in row else default_host
        port = _port(row, source, line)
        opcua = _port(row, source, line, "opcua") if "opcua" in row else None
        for key, taken in (("port", port), ("opcua", opcua)):
            if taken is None:
                continue
            holder = addresses.get((host, taken))
            if holder is not None:
                raise NckConfigError(f"{host}:{taken} is already taken by {holder}", path=source, line=line,
                                     field=key)
            addresses[(host, taken)] = f"machine {name!r}" + (" (its OPC UA face)" if key == "opcua" else "")
        speed = row.get("speed")
        if speed is not None and (isinstance(speed, bool) or not isinstance(speed, str | int | float)):
            raise NckConfigError("expected a speed such as \"60x\" or 60", path=source, line=line, field="speed")
        loop = row.get("loop", False)
        if not isinstance(loop, bool):
            raise NckConfigError("expected true or false", path=source, line=line, field="loop")
        machines.append(FleetMachine(
            name=name, host=host, port=port, line=line,
            machine=_path(row, "machine", source, line, base, default_machine),
            inputs=_path(row, "inputs", source, line, base), plc=_path(row, "plc", source, line, base),
            speed=None if speed is None else str(speed), cycle=_text(row, "cycle", source, line), loop=loop,
            opcua=opcua))
    return FleetSpec(source, tuple(machines))


def load_fleet(path: str | Path) -> FleetSpec:
    path = Path(path)
    return parse_fleet(read_text(path, "a fleet is TOML text"), str(path), path.parent)


def quick_fleet(count: int, base_port: int, machine: str | None = None, host: str = DEFAULT_HOST,
                opcua_base_port: int | None = None) -> FleetSpec:
    """``--count N --base-port P [--opcua-base-port U]``: machines m001.. on ports P, P+1, ... all of one
    machine file, with OPC UA faces on U, U+1, ... when given."""
    if count < 1:
        raise NckConfigError(f"--count {count}: at least one machine")
    for option, first in (("--base-port", base_port), ("--opcua-base-port", opcua_base_port)):
        if first is not None and (first < 1 or first + count - 1 > 65535):
            raise NckConfigError(f"{option} {first}: ports {first}..{first + count - 1} are not all in 1..65535")
    if opcua_base_port is not None and opcua_base_port < base_port + count and base_port < opcua_base_port + count:
        raise NckConfigError(f"--opcua-base-port {opcua_base_port}: its ports overlap the S7 ports "
                             f"{base_port}..{base_port + count - 1}")
    if machine is not None and not Path(machine).is_file():
        raise NckConfigError("no such file", path=machine, field="--machine")
    width = max(3, len(str(count)))
    return FleetSpec(f"--count {count}", tuple(
        FleetMachine(name=f"m{number:0{width}d}", host=host, port=base_port + number - 1, machine=machine,
                     opcua=None if opcua_base_port is None else opcua_base_port + number - 1)
        for number in range(1, count + 1)))


class _MachineCache:
    """One parsed ``Machine`` per machine file: machines are immutable, so the fleet shares them."""

    def __init__(self) -> None:
        self._machines: dict[str | None, Machine] = {}

    def get(self, entry: FleetMachine, source: str) -> Machine:
        machine = self._machines.get(entry.machine)
        if machine is None:
            try:
                machine = load_machine(entry.machine)
            except NckConfigError as exc:
                raise NckConfigError(f"machine {entry.name!r}: {exc}", path=source, line=entry.line,
                                     field="machine") from None
            self._machines[entry.machine] = machine
        return machine


def _refuse_living(entry: FleetMachine, source: str) -> None:
    """Without a living hook (a program using ``Fleet`` alone), living keys are refused, not ignored."""
    for field in ("inputs", "plc", "speed"):
        if getattr(entry, field) is not None:
            raise NckConfigError(f"machine {entry.name!r}: {field} needs the living machine (nckemu.plcsim), "
                                 f"which was not given", path=source, line=entry.line, field=field)


@dataclass
class RunningMachine:
    entry: FleetMachine
    emulator: Emulator
    server: EmulatorServer
    face: Face | None = None
    opcua: Face | None = None     # its OPC UA face (an ``OpcUaFace``)

    @property
    def port(self) -> int:
        return self.server.port

    def ready(self) -> dict[str, Any]:
        return {"name": self.entry.name, "host": self.entry.host, "port": self.port,
                "machine": self.emulator.machine.name, "state": str(self.emulator.store.path)
                if self.emulator.store is not None else None, "living": self.face is not None,
                **(self.opcua.ready if self.opcua is not None else {})}


class Fleet:
    """The machines of a ``FleetSpec``, each an ``Emulator`` with its own server, on the running loop.

    ``state_dir``: each machine keeps its retained data in ``<state_dir>/<name>.json``; ``living``
    builds the living machines (``LivingHook``), without it their keys are refused."""

    def __init__(self, spec: FleetSpec, *, state_dir: str | Path | None = None,
                 limits: ServerLimits | None = None, living: LivingHook | None = None) -> None:
        self.spec = spec
        self.state_dir = Path(state_dir) if state_dir is not None else None
        if self.state_dir is not None and not self.state_dir.is_dir():
            if self.state_dir.exists() or not self.state_dir.parent.is_dir():
                raise NckConfigError("--state: not a directory, and cannot be made one (its parent must exist)",
                                     path=str(self.state_dir))
            self.state_dir.mkdir()
        machines = _MachineCache()
        self.machines: list[RunningMachine] = []
        for entry in spec.machines:
            clock: Clock | None = None
            make_face: FaceFactory | None = None
            if entry.living:
                if living is None:
                    _refuse_living(entry, spec.source)
                else:
                    clock, make_face = living(entry, spec.source)
            state = self.state_dir / f"{entry.name}.json" if self.state_dir is not None else None
            try:
                emulator = Emulator(machines.get(entry, spec.source), state_path=state, clock=clock)
            except NckConfigError as exc:
                if exc.path == spec.source:
                    raise
                raise NckConfigError(f"machine {entry.name!r}: {exc}", path=spec.source, line=entry.line,
                                     field="name") from None
            emulator.identify(entry.name, len(self.machines) + 1)  # its own name and serial number
            server = EmulatorServer(emulator, host=entry.host, port=entry.port, limits=limits)
            face = make_face(emulator, server) if make_face is not None else None
            opcua: Face | None = None
            if entry.opcua is not None:
                from nckemu.emulator.faces.opcua import (
                    OpcUaFace,  # asyncua is imported only by fleets that serve OPC UA
                )
                from nckemu.emulator.machine_check import opcua_settings

                try:
                    # the settings as serve checks them: an error names the machine file's line
                    opcua = OpcUaFace(emulator, entry.host, entry.opcua, opcua_settings(emulator.machine))
                except NckConfigError as exc:
                    raise NckConfigError(f"machine {entry.name!r}: {exc}", path=spec.source, line=entry.line,
                                         field="opcua") from None
            self.machines.append(RunningMachine(entry, emulator, server, face, opcua))

    def __getitem__(self, name: str) -> RunningMachine:
        for machine in self.machines:
            if machine.entry.name == name:
                return machine
        raise KeyError(name)

    async def start(self) -> Fleet:
        """Bind every machine; if one cannot bind, stop those started and raise, naming it."""
        started: list[RunningMachine] = []
        for machine in self.machines:
            try:
                await machine.server.start()
            except OSError as exc:
                await self._stop(started)
                raise NckConfigError(self._bind_error(machine.entry, exc), path=self.spec.source,
                                     line=machine.entry.line, field="port") from None
            started.append(machine)
        # the living machines after every S7 face listens (a PLC program's client connects to its own)
        living = [machine for machine in self.machines if machine.face is not None]
        for index, machine in enumerate(living):
            assert machine.face is not None
            try:
                await machine.face.start()
            except (OSError, NckConfigError) as exc:
                for unstarted in living[index:]:
                    unstarted.face = None
                await self._stop(started)
                raise NckConfigError(f"machine {machine.entry.name!r}: the living machine did not start: {exc}",
                                     path=self.spec.source, line=machine.entry.line) from None
        with_opcua = [machine for machine in self.machines if machine.opcua is not None]
        for index, machine in enumerate(with_opcua):
            assert machine.opcua is not None
            try:
                await machine.opcua.start()
            except OSError as exc:
                for unstarted in with_opcua[index:]:
                    unstarted.opcua = None
                await self._stop(started)
                entry = machine.entry
                raise NckConfigError(self._bind_error(entry, exc, entry.opcua).replace(
                    "cannot bind", "OPC UA face cannot bind"), path=self.spec.source, line=entry.line,
                    field="opcua") from None
        return self

    @staticmethod
    def _bind_error(entry: FleetMachine, exc: OSError, port: int | None = None) -> str:
        where = f"machine {entry.name!r}: cannot bind {entry.host}:{port or entry.port}"
        if exc.errno in (errno.EACCES, errno.EPERM):
            return f"{where} (permission denied: ports below 1024 need root)"
        if exc.errno == errno.EADDRINUSE:
            return f"{where}: already in use"
        if exc.errno == errno.EADDRNOTAVAIL:
            return f"{where}: no such local address (Linux serves all of 127.0.0.0/8)"
        return f"{where}: {exc.strerror or exc}"

    async def stop(self) -> None:
        """Stop every machine (each flushes its retained data); one failing does not keep the rest."""
        await self._stop(self.machines)

    @staticmethod
    async def _stop(machines: list[RunningMachine]) -> None:
        # All at once: an OPC UA face takes about 0.7 s to stop (asyncua waits for its sessions and
        # subscriptions to end), so one after another 20 machines took 10-15 s after SIGTERM.
        async def stop_one(machine: RunningMachine) -> None:
            try:
                if machine.opcua is not None:
                    await machine.opcua.stop()
                if machine.face is not None:
                    await machine.face.stop()
                await machine.server.stop()
            except Exception:  # noqa: BLE001 - a machine's fault must not leave the others running
                log.exception("machine %r did not stop cleanly", machine.entry.name)

        await asyncio.gather(*(stop_one(machine) for machine in machines))
