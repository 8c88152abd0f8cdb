"""The emulated controller as one object: machine, clock, NCK model, PLC memory, retained state."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from nckemu.emulator.machine.clock import Clock, LiveClock, MonotonicClock
from nckemu.emulator.machine.cycle import CyclePacer, Step
from nckemu.emulator.machine.heat import Heat
from nckemu.emulator.machine.machine_file import Machine, load_machine
from nckemu.emulator.machine.nck.access import HIGHEST_LEVEL, AccessContext
from nckemu.emulator.machine.nck.alarms import ALARM_RETAINED_STATE
from nckemu.emulator.machine.nck.model import NckModel
from nckemu.emulator.machine.plc import PlcModel
from nckemu.emulator.machine.saves import GroupSaves
from nckemu.emulator.machine.state import RetainedStore
from nckemu.errors import NckConfigError, NckError
from nckemu.protocol.addresses import NckAddress
from nckemu.protocol.values import decode_nck_values

# A served machine's ticker (no living machine) when nothing runs: it wakes on any channel change.
IDLE_TICK_S = 1.0

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.core")


SERIAL_NUMBER = "HW_SERIAL_NUMBER"  # MD18030


def serial_number(number: int) -> str:
    """The serial number of a fleet's ``number``-th machine (the first's is the catalogue default)."""
    return f"NCKEMU{number:014d}"


class Emulator:
    """An NCU: NCK and PLC, with optional retained state on disk; the faces (S7, OPC UA, web) come in
    through ``nck`` and ``plc``."""

    def __init__(self, machine: Machine | str | Path | None = None, *, clock: Clock | None = None,
                 state_path: str | Path | None = None) -> None:
        self.machine = machine if isinstance(machine, Machine) else load_machine(machine)
        self.clock = clock or MonotonicClock()
        self.nck = NckModel(self.machine, self.clock)
        self.plc = PlcModel(self.machine, self.nck, clock=self.clock,
                            identity=lambda: (self.name, self.serial_number))  # SZL 0x001C, as umati's
        self.store = RetainedStore(Path(state_path)) if state_path is not None else None
        # The machine's own name among others (a fleet's machine: ``identify``); faces name it by this
        # (the OPC UA ApplicationUri, the umati instance), the machine file's name otherwise.
        self.name = self.machine.name
        # Parts of the machine's state that layers above the emulator report (a living machine's
        # recording and PLC program): name -> a function giving a JSON-able dict (the live page).
        self.status_sections: dict[str, Callable[[], dict[str, Any]]] = {}
        # An alarm text while retained state cannot be written (disk full, read-only directory).
        self.persist_alarm: str | None = None
        self._snapshots = 0
        # Saves off the event loop for the S7 face (its acknowledgements wait for them); saves.py.
        self.saves = GroupSaves(self)
        # The machine's cycle on the server's clock: the channels run their programs and the machine
        # heats in it; a living machine adds its recording and PLC steps (``cycle_steps``) and its cycle
        # time, and starts the cycle itself when its PLC client is connected (``cycle_deferred``).
        self.heat = Heat(self.machine, self.nck)
        self.cycle_s = self.machine.program.cycle_s
        self.cycle_steps: list[Step] = []
        self.cycle_deferred = False
        self.pacer: CyclePacer | None = None
        self._ticker: asyncio.Task[None] | None = None
        # Retained data of faces (the OPC UA face's users): name -> a function giving it, JSON-able; and
        # what the state file held for each, for the face to take up when it starts. A face not started
        # this time keeps what it had: its section is written back as it was read.
        self.face_state: dict[str, Callable[[], Any]] = {}
        self.restored_face_state: dict[str, Any] = {}
        if self.store is not None:
            snapshot = self.store.load()
            if snapshot is not None:
                self.nck.restore_retained(snapshot)
                faces = snapshot.get("faces", {})
                self.restored_face_state = dict(faces) if isinstance(faces, dict) else {}
                log.info("retained state loaded from %s", self.store.path)

    # ------------------------------------------------------------------ the cycle
    def step_machine(self, t_s: float) -> None:
        """The NCK's own part of a cycle at simulated time ``t_s``: programs run, the machine heats."""
        for channel in self.nck.channels.values():
            channel.step(t_s)
        self.heat.step(t_s)

    async def _step(self, k: int, t_s: float) -> None:
        for step in self.cycle_steps:
            await step(k, t_s)
        self.step_machine(t_s)

    async def start_cycle(self) -> None:
        """Run the machine's cycle on the running loop (idempotent): a :class:`CyclePacer` on a
        :class:`LiveClock`, else a tick every ``cycle_s`` of the clock's own time."""
        if self.pacer is not None or self._ticker is not None:
            return
        if isinstance(self.clock, LiveClock):
            first = math.ceil(self.clock.now_s() / self.cycle_s - 1e-9) if self.clock.running else 0
            self.pacer = CyclePacer(self.clock, self.cycle_s, self._step, first_cycle=max(0, first))
            await self.pacer.start()
        else:
            self._ticker = asyncio.create_task(self._tick(), name="nckemu-channel")

    async def stop_cycle(self) -> None:
        pacer, self.pacer = self.pacer, None
        if pacer is not None:
            await pacer.stop()
        ticker, self._ticker = self._ticker, None
        if ticker is not None:
            ticker.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await ticker

    async def _tick(self) -> None:
        # Idle (no program, no heat left), the ticker sleeps up to IDLE_TICK_S and any change of a
        # channel's state wakes it: a fleet of idle machines costs next to nothing.
        wake = asyncio.Event()

        def changed(_channel: object) -> None:
            wake.set()

        for channel in self.nck.channels.values():
            channel.state_listeners.append(changed)
        k = 0
        try:
            while True:
                try:
                    await self._step(k, self.clock.now_s())
                except Exception:  # a step that fails is logged; the machine serves on
                    log.exception("the machine's cycle failed at %.1f s", self.clock.now_s())
                k += 1
                busy = any(channel.run is not None for channel in self.nck.channels.values()) or self.heat.warm
                wake.clear()
                # asyncio.wait, not wait_for: on Python 3.11 wait_for returns the result instead of
                # raising when the wake-up and stop_cycle's cancel meet in one loop turn, and the
                # ticker then never ends (stop hung under load, found by the help-example tests).
                waiter = asyncio.ensure_future(wake.wait())
                try:
                    await asyncio.wait({waiter}, timeout=self.cycle_s if busy else max(self.cycle_s, IDLE_TICK_S))
                finally:
                    waiter.cancel()
        finally:
            for channel in self.nck.channels.values():
                if changed in channel.state_listeners:
                    channel.state_listeners.remove(changed)

    def identify(self, name: str, number: int) -> None:
        """This is the machine ``name``, the ``number``-th (from 1) of a fleet: its own name and serial
        number (MD18030 $MN_HW_SERIAL_NUMBER ``NCKEMU`` and 14 digits), unless its machine file or state
        file gave it another serial number."""
        self.name = name
        store = self.nck.store
        spec = store.spec(SERIAL_NUMBER)
        for key, stored in store.stored.items():
            if key[0] == SERIAL_NUMBER and stored and stored[0] == spec.default:
                store.write_lines(spec, key[1], 1, [serial_number(number)])
                store.active[key] = list(store.stored[key])

    @property
    def serial_number(self) -> str:
        """MD18030 as the NCK holds it now (what every face shows as the serial number)."""
        return str(self.nck.store.active_value(SERIAL_NUMBER, 1)).rstrip()

    @property
    def default_access_level(self) -> int:
        return int(getattr(self.machine, "connection_access_level", 7))

    def persist(self) -> None:
        """Write retained data now; on failure keep serving and raise an alarm instead."""
        if self.store is None:
            return
        try:
            data, sequence = self.encode_retained()
            self.store.write(data, sequence)
        except (OSError, NckConfigError) as exc:
            self.saved(exc)
        else:
            self.saved(None)

    def encode_retained(self) -> tuple[bytes, int]:
        """The state file's bytes now, and their place in the order of snapshots (called on the thread
        that changes the machine, so that the snapshot is consistent)."""
        snapshot = self.nck.retained_snapshot()
        faces = dict(self.restored_face_state)
        faces.update({name: state() for name, state in self.face_state.items()})
        if faces:
            snapshot["faces"] = faces
        self._snapshots += 1
        return RetainedStore.encode(snapshot), self._snapshots

    def saved(self, exc: Exception | None) -> None:
        """After a save: an alarm while retained data cannot be written, cleared when it can again."""
        assert self.store is not None
        if exc is not None:
            if self.persist_alarm is None:
                log.error("retained state cannot be written to %s: %s (serving on, alarm raised)",
                          self.store.path, exc)
            if self.persist_alarm is not None:
                self.nck.alarm_list.clear(self.persist_alarm)
            self.persist_alarm = f"retained state not saved: {exc}"
            self.nck.alarm_list.raise_alarm(self.persist_alarm, ALARM_RETAINED_STATE, (str(exc),))
        else:
            if self.persist_alarm is not None:
                log.warning("retained state written again to %s; alarm cleared", self.store.path)
                self.nck.alarm_list.clear(self.persist_alarm)
            self.persist_alarm = None

    def power_on(self) -> None:
        """Simulated power-on: power-on machine data take effect, 840C TC data are erased."""
        self.nck.power_on()

    def seed_nck(self, values: dict[NckAddress, bytes]) -> int:
        """Write recorded NCK values (as on the wire) with the highest access level, e.g. before a trace
        replay; variables that cannot be set (state data and the like) are skipped. Returns how many
        were written."""
        ctx = AccessContext(level=HIGHEST_LEVEL, client="seed")
        written = 0
        for address, data in values.items():
            try:
                nck_type, length = self.nck.variable_type(address)
                decoded = decode_nck_values(nck_type, data, area=address.area, line_count=address.line_count,
                                            string_length=length)
                self.nck.write(address, decoded, ctx)
                written += 1
            except NckError:
                continue
        return written
