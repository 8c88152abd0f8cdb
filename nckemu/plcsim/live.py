"""A living machine: a recording and the user's STL program driving a served machine on its clock.

``LiveMachine(emulator, inputs=..., plc=..., speed=..., loop=..., server=...)`` hangs its steps on
the emulator's :class:`~nckemu.emulator.machine.cycle.CyclePacer` (the emulator owns it: its channels run
programs in the same cycle, after these steps): every ``cycle_s`` of simulated time the
recording's inputs (``drive.RecordingDrive``, the same as ``plc run --inputs``) and then one cycle of
the program in awlsim (``bridge.PlcRunner``, the same as offline), its FB2/FB3/FB4 jobs going to the
machine's own S7 face on the same event loop, as a client. The pacer holds the clock at the cycle's
time until the cycle and its jobs are done, so a client reading at simulated time t sees what the
offline run computed at t; only the clock differs (simulated there, ``speed`` times the wall clock
here).

A program that faults at run time stops (the PLC goes to STOP, as a real one would); the recording
goes on driving the machine and every face keeps serving; the log, ``-v`` and the live page say so.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Coroutine
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from nckemu.clients.async_client import AsyncNckClient
from nckemu.emulator.faces.s7.server import EmulatorServer
from nckemu.emulator.machine.clock import LiveClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.cycle import CyclePacer, PacerStats
from nckemu.emulator.machine.plc.channel_signals import (
    BYTE_MODE_ACTIVE,
    BYTE_STATE,
    FIRST_CHANNEL_DB,
    MODE_GROUP_DB,
)
from nckemu.errors import NckConfigError, NckError
from nckemu.protocol.addresses import S7Area
from nckemu.thermal.recordings.recording import Recording, load_recording

from .bridge import PlcRunner, awlsim_error_text, check_program
from .drive import CycleInputs, RecordingDrive

log = logging.getLogger(__name__)
T = TypeVar("T")

JOB_WAIT_S = 10.0
# A PLC cycle that takes this much wall time is taken for a hanging program (an endless loop).
CYCLE_WATCHDOG_WALL_S = 1.0
MINUTE_S = 60.0
# Jobs and errors kept in the bridge's log (the older ones are counted, then dropped).
LOG_KEEP = 500


def parse_speed(text: str) -> float:
    """``60x`` or ``60``: simulated seconds per wall second, positive."""
    try:
        speed = float(text.strip().lower().removesuffix("x"))
    except ValueError:
        raise NckConfigError(f"--speed {text!r}: expected a factor such as 60x, 600 or 1x") from None
    if not speed > 0 or speed != speed or speed == float("inf"):
        raise NckConfigError(f"--speed {text}: simulated time must run forward (a factor above 0, e.g. 1x)")
    return speed


class _LoopSubmit:
    """What the bridge needs of a client (``submit`` and ``async_client``), on the running loop."""

    def __init__(self, client: AsyncNckClient) -> None:
        self.async_client = client

    def submit(self, coroutine: Coroutine[Any, Any, T]) -> asyncio.Task[T]:
        return asyncio.ensure_future(coroutine)


@dataclass
class LiveStatus:
    """What the live machine reports (the page's "PLC" and "recording" parts, -v's minute line)."""

    speed: float
    cycle_s: float
    t_s: float = 0.0
    t_rec_s: float | None = None
    recording: str | None = None
    recording_pass: int = 1
    recording_end: bool = False
    plc: str = "none"               # none, RUN, STOP
    program: str | None = None
    fault: str | None = None
    cycles: int = 0
    jobs: dict[str, int] = field(default_factory=lambda: {"PUT": 0, "GET": 0, "PI": 0})
    job_errors: int = 0
    last_error: str | None = None
    lag_s: float = 0.0
    slips: int = 0
    step_wall_ms: float = 0.0


class LiveMachine:
    """A recording and an STL program driving ``emulator`` on its :class:`LiveClock`.

    ``emulator`` must have been built with ``clock=LiveClock()`` (its model keeps the clock it was
    built with); ``speed`` is set on that clock. ``plc`` needs ``server``: the program's FB2/FB3/FB4
    reach the model through the machine's S7 face, started before :meth:`start`. Bad input (columns the
    machine needs, a program without OB1 or that awlsim cannot load) is refused here, before anything
    runs. ``on_minute(line)`` gets one line per simulated minute, at most one per wall second.
    """

    def __init__(self, emulator: Emulator, *, inputs: Recording | str | Path | None = None,
                 plc: str | Path | None = None, speed: float = 1.0, loop: bool = False, cycle_s: float = 1.0,
                 server: EmulatorServer | None = None, warmup_s: float = 120.0,
                 on_minute: Callable[[str], None] | None = None) -> None:
        if not isinstance(emulator.clock, LiveClock):
            raise NckConfigError("a live machine needs an emulator built with clock=LiveClock()")
        if not cycle_s > 0:
            raise NckConfigError("--cycle must be positive")
        if not speed > 0 or speed == float("inf"):
            raise NckConfigError(f"--speed {speed}: simulated time must run forward (a factor above 0, e.g. 1x)")
        if plc is not None and server is None:
            raise NckConfigError("the PLC program reaches the NCK through the machine's S7 face: pass server=")
        self.emulator = emulator
        self.clock: LiveClock = emulator.clock
        self.clock.speed = speed
        self.server = server
        self.cycle_s = float(cycle_s)
        self.on_minute = on_minute
        recording = load_recording(inputs, need_errors=False) if isinstance(inputs, str | Path) else inputs
        self.drive = RecordingDrive(emulator.machine, recording, cycle_s, warmup_s=warmup_s, loop=loop) \
            if recording is not None else None
        self.program = Path(plc) if plc is not None else None
        self.runner: PlcRunner | None = None
        if self.program is not None:
            if not self.program.is_file():
                raise NckConfigError("no such STL source", path=str(self.program))
            check_program(self.program)
            # Loaded (and refused, if awlsim cannot) now; its client connects at start().
            self._client = AsyncNckClient("127.0.0.1", 0, timeout_s=JOB_WAIT_S)
            self.runner = PlcRunner(self.program, _LoopSubmit(self._client), self._read_peripheral,
                                    self.clock.now_s, watchdog_wall_s=CYCLE_WATCHDOG_WALL_S)
        self.status = LiveStatus(speed=speed, cycle_s=self.cycle_s,
                                 recording=recording.source if recording is not None else None,
                                 plc="RUN" if self.runner is not None else "none",
                                 program=str(self.program) if self.program is not None else None)
        # The emulator's pacer runs this machine's steps (recording, PLC) before the channels' in each
        # cycle; the cycle starts when the PLC's client is connected (start()).
        emulator.cycle_s = self.cycle_s
        emulator.cycle_deferred = True
        emulator.cycle_steps.append(self._step)
        self._stats = PacerStats()
        self._first_k: int | None = None
        self._started = False
        self._interface: list[tuple[int, bytearray, int]] | None = None
        self._sent: dict[int, bytes] = {}
        # The first line after the first minute (the ready line comes first).
        self._next_line_s = MINUTE_S * max(1, int(-(-speed // MINUTE_S)))
        self._next_line_wall_s = 0.0
        self._last_inputs: CycleInputs | None = None
        self.plc_peer: str | None = None
        self._plc_connection: Any = None
        # Jobs and errors folded out of the bridge's log (a server runs for days: the log must not grow).
        self._jobs_folded = {"PUT": 0, "GET": 0, "PI": 0}
        self._errors_folded = 0
        emulator.status_sections["live"] = self.snapshot

    @property
    def t0_s(self) -> float:
        """Recording time of simulated time 0 (the first cycle)."""
        return self.drive.t0_s if self.drive is not None else 0.0

    def _read_peripheral(self, offset: int, size: int) -> bytes:
        return self.emulator.plc.read(S7Area.P, 0, offset, size)

    # ------------------------------------------------------------------ start / stop
    async def start(self) -> LiveMachine:
        if self.runner is not None:
            assert self.server is not None
            host = self.server.host if self.server.host not in ("0.0.0.0", "", "::") else "127.0.0.1"
            self._client.host, self._client.port = host, self.server.port
            before = {id(connection) for connection in self.server.connections}
            await self._client.connect()
            # The program's own connection, so the page can tell it from the outside clients.
            mine = [c for c in self.server.connections if id(c) not in before]
            self.plc_peer = mine[0].peer if len(mine) == 1 else None
            # A real PLC's path to its NCK is never idle: the program's connection is kept alive
            # however long it goes without a job (the server closes idle clients after 300 s).
            self._plc_connection = mine[0] if len(mine) == 1 else None
        # A cycle the server started before this machine existed starts over with this machine's cycle.
        await self.emulator.stop_cycle()
        self._started = True
        await self.emulator.start_cycle()
        return self

    @property
    def pacer(self) -> CyclePacer | None:
        return self.emulator.pacer

    async def stop(self) -> None:
        pacer = self.emulator.pacer
        if pacer is not None:
            self._stats = pacer.stats
        await self.emulator.stop_cycle()
        if self.runner is not None:
            self.runner.shutdown()
            await self._client.disconnect()

    # ------------------------------------------------------------------ one cycle
    async def _step(self, k_pacer: int, t_s: float) -> None:
        # The emulator's pacer may run before this machine has started (its PLC client connected):
        # nothing of it runs until then, and its cycles count from its first.
        if not self._started:
            return
        if self._first_k is None:
            self._first_k = k_pacer
        k = k_pacer - self._first_k
        if self.drive is not None:
            self._last_inputs = self.drive.apply(self.emulator.nck, k)
        runner = self.runner
        if self._plc_connection is not None:
            self._plc_connection.last_activity_s = time.monotonic()
        if runner is not None and self.status.fault is None:
            self._interface_in(runner)
            try:
                runner.run_cycle()
            except Exception as exc:  # awlsim's run-time errors: the PLC stops, the machine serves on
                self._fault(exc, t_s)
            self._interface_out(runner)
            pending = runner.pending()
            if pending:  # simulated time waits for the network, as offline
                await asyncio.wait(pending, timeout=JOB_WAIT_S)
            if len(runner.log.jobs) > LOG_KEEP * 2 or len(runner.log.errors) > LOG_KEEP * 2:
                self._fold_log()
        self.status.cycles = k + 1
        self.status.t_s = t_s
        if t_s >= self._next_line_s:
            self._minute(t_s)

    # ------------------------------------------------------------------ the NCK interface DBs
    def _interface_dbs(self, runner: PlcRunner) -> list[tuple[int, bytearray, int]]:
        """DB11 and DB21.. as the program declares them: (number, its memory in awlsim, first NCK byte).
        Bytes below the first NCK byte are the PLC's (requests), from it on the NCK's (states: DB11.DBB6,
        DB21.DBB35, docs/programs.md); whatever the program writes there reaches the NCK once per cycle."""
        found = []
        channels = len(self.emulator.nck.channels)
        for number, first_nck in ((MODE_GROUP_DB, BYTE_MODE_ACTIVE),
                                  *((FIRST_CHANNEL_DB + n, BYTE_STATE) for n in range(channels))):
            try:
                db = runner.sim.cpu.getDB(number)
                memory = db.structInstance.memory.getDataBytes() if db is not None else None
            except Exception:  # not declared by the program: the PLC does not use that interface
                memory = None
            if memory is not None and number in self.emulator.plc.data_blocks:
                found.append((number, memory, first_nck))
        return found

    def _interface_in(self, runner: PlcRunner) -> None:
        """The NCK's part of the interface DBs (DB21.DBB35, DB11.DBB6, ...) into the program's DBs."""
        if self._interface is None:
            self._interface = self._interface_dbs(runner)
        plc = self.emulator.plc.data_blocks
        for number, memory, first in self._interface:
            end = min(len(memory), len(plc[number]))
            if end > first:
                memory[first:end] = plc[number][first:end]
            # another writer (an S7 client, an OPC UA write) changed the PLC's part: the program sees it
            mine = min(first, end)
            if bytes(plc[number][:mine]) != self._sent.get(number, bytes(plc[number][:mine])):
                memory[:mine] = plc[number][:mine]

    def _interface_out(self, runner: PlcRunner) -> None:
        """The program's part (DB21.DBX7.1 NC start, DB11.DBX0.2 JOG, ...) to the NCK, as a write of the
        PLC memory would (so its edges act exactly as an S7 client's)."""
        plc = self.emulator.plc
        for number, memory, first in self._interface or ():
            end = min(first, len(memory), len(plc.data_blocks[number]))
            mine = bytes(memory[:end])
            if mine != bytes(plc.data_blocks[number][:end]):
                plc.write(S7Area.DB, number, 0, mine)
            self._sent[number] = mine

    def _fold_log(self) -> None:
        """Count the older jobs and errors and drop them, keeping the last ``LOG_KEEP`` of each."""
        assert self.runner is not None
        log_ = self.runner.log
        for job in log_.jobs[:-LOG_KEEP]:
            self._jobs_folded[job.block] = self._jobs_folded.get(job.block, 0) + 1
        del log_.jobs[:-LOG_KEEP]
        self._errors_folded += max(0, len(log_.errors) - LOG_KEEP)
        del log_.errors[:-LOG_KEEP]

    def _fault(self, exc: Exception, t_s: float) -> None:
        text = awlsim_error_text(exc) or type(exc).__name__
        if text.startswith("line "):
            text = f"{self.program.name if self.program else 'program'} {text}"
        self.status.fault = f"at {_clock_text(t_s)}: {text}"
        self.status.plc = "STOP"
        log.error("the PLC program faulted at simulated %s and is in STOP (the machine serves on): %s",
                  _clock_text(t_s), text[:300])

    def _minute(self, t_s: float) -> None:
        minutes = int(t_s // MINUTE_S)
        # One line per simulated minute, but never more than one per wall second: at 600x a line
        # every ten simulated minutes.
        step_min = max(1, int(-(-self.clock.speed // MINUTE_S)))
        self._next_line_s = (minutes // step_min + 1) * step_min * MINUTE_S
        now_wall = time.monotonic()
        if self.on_minute is None or now_wall < self._next_line_wall_s:
            return
        self._next_line_wall_s = now_wall + 0.5
        self.on_minute(self.minute_line())

    # ------------------------------------------------------------------ status
    def snapshot(self) -> dict[str, Any]:
        status = self.status
        inputs = self._last_inputs
        if inputs is not None:
            status.t_rec_s = inputs.t_rec_s
            status.recording_pass = inputs.recording_pass
            status.recording_end = self.drive is not None and not self.drive.loop and status.cycles > self.drive.cycles
        status.lag_s = self.clock.lag_s()
        status.slips = self.clock.slips
        stats = self.pacer.stats if self.pacer is not None else self._stats
        status.step_wall_ms = 1000.0 * stats.step_wall_s / stats.cycles if stats.cycles else 0.0
        if self.runner is not None:
            jobs = self.runner.log.jobs
            status.jobs = {kind: self._jobs_folded.get(kind, 0) + sum(1 for job in jobs if job.block == kind)
                           for kind in ("PUT", "GET", "PI")}
            status.job_errors = self._errors_folded + len(self.runner.log.errors)
            status.last_error = self.runner.log.errors[-1] if self.runner.log.errors else None
        return {"speed": status.speed, "cycle_s": status.cycle_s, "t_s": self.clock.now_s(),
                "t_rec_s": None if inputs is None else inputs.t_rec_s,   # of the last cycle run
                "recording": status.recording, "recording_pass": status.recording_pass,
                "recording_end": status.recording_end, "plc": status.plc, "program": status.program,
                "fault": status.fault, "cycles": status.cycles, "jobs": status.jobs,
                "job_errors": status.job_errors, "last_error": status.last_error, "lag_s": status.lag_s,
                "slips": status.slips, "step_wall_ms": status.step_wall_ms, "plc_peer": self.plc_peer}

    def minute_line(self) -> str:
        """One line about the machine now: time, recording, sensors, compensation, PLC, clients."""
        snap = self.snapshot()
        nck = self.emulator.nck
        parts = [f"t {_clock_text(snap['t_s'])}"]
        if snap["t_rec_s"] is not None:
            parts.append(f"rec {_clock_text(snap['t_rec_s'])}" + (f" pass {snap['recording_pass']}"
                                                                   if snap["recording_pass"] > 1 else "")
                         + (" (end, holding)" if snap["recording_end"] else ""))
        for sensor in self.emulator.machine.sensors:
            parts.append(f"{sensor.name} {nck.sensor_temperature_C(sensor.name):.2f}")
        for axis in self.emulator.machine.axes:
            if axis.spindle:
                continue
            try:
                tc_mm = nck.tc_value_mm(axis.number)
            except NckError:
                continue
            if tc_mm:
                parts.append(f"TC {axis.name} {tc_mm * 1000.0:+.1f} um")
        if snap["plc"] != "none":
            jobs = snap["jobs"]
            parts.append(f"PLC {snap['plc']} {snap['cycles']} cycles, {jobs['PUT']} PUT {jobs['GET']} GET "
                         f"{jobs['PI']} PI, {snap['job_errors']} errors")
        if self.server is not None:
            parts.append(f"{len(self.server.connections)} connections")
        if snap["lag_s"] > self.cycle_s:
            parts.append(f"behind {snap['lag_s']:.0f} s")
        if snap["slips"]:
            parts.append(f"slipped {snap['slips']} times")
        return "live: " + ", ".join(parts)


def _clock_text(t_s: float) -> str:
    sign = "-" if t_s < 0 else ""
    seconds = int(round(abs(t_s)))
    return f"{sign}{seconds // 3600:02d}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"
