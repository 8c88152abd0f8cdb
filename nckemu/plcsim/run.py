"""``nckemu plc run``: a user's STL program in awlsim against the emulator.

In process (the default) the emulator runs on simulated time: the PLC cycle, its timers and the
machine's sensor profiles all follow one clock, which runs as fast as the computer allows or
``speed`` times real time. Against a running controller (``emulator="HOST:PORT"``) time is real, as
it is for that controller.
"""

from __future__ import annotations

import concurrent.futures
import math
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nckemu.clients import NckClient
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.runner import EmulatorThread
from nckemu.errors import NckConfigError, NckError
from nckemu.protocol.addresses import S7Area

from .bridge import BridgeLog, PlcRunner, check_program
from .remote import InputMirror

JOB_WAIT_S = 10.0


@dataclass
class Sample:
    time_s: float
    sensor_C: float
    tc_value_mm: float


@dataclass
class PlcRun:
    samples: list[Sample]
    log: BridgeLog
    flags: bytes = b""   # the program's M area when it stopped

    def flag(self, byte: int, bit: int) -> bool:
        return bool(self.flags[byte] >> bit & 1)

    def flag_real(self, byte: int) -> float:
        return float(struct.unpack_from(">f", self.flags, byte)[0])


def parse_endpoint(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise NckConfigError(f"--emulator {text!r}: expected HOST:PORT, e.g. 127.0.0.1:1102")
    return host, int(port)


def run_program(program: str | Path, *, machine: str | Path | None = None, emulator: str | None = None,
                duration_s: float = 7200.0, cycle_s: float = 1.0, axis: int = 4, sensor: str | None = None,
                sample_every_s: float = 60.0, speed: float | None = None) -> PlcRun:
    """Run ``program`` for ``duration_s``; ``speed`` None runs simulated time as fast as possible."""
    program = Path(program)
    if not program.is_file():
        raise NckConfigError("no such STL source", path=str(program))
    check_program(program)
    if emulator is not None:
        if machine is not None:
            raise NckConfigError("--machine belongs to the in-process emulator; the one at --emulator has its own")
        return _run_remote(program, emulator, duration_s, cycle_s, axis, sample_every_s)
    return _run_in_process(program, machine, duration_s, cycle_s, axis, sensor, sample_every_s, speed)


def _run_in_process(program: Path, machine: str | Path | None, duration_s: float, cycle_s: float, axis: int,
                    sensor: str | None, sample_every_s: float, speed: float | None) -> PlcRun:
    clock = SimulatedClock()
    emulator = Emulator(machine, clock=clock)
    sensor_name = sensor or (emulator.machine.sensors[0].name if emulator.machine.sensors else None)
    samples: list[Sample] = []
    with EmulatorThread(emulator=emulator) as emu, NckClient("127.0.0.1", emu.port) as client:
        def read_peripheral(offset: int, size: int) -> bytes:
            return emu.call(lambda: emulator.plc.read(S7Area.P, 0, offset, size))

        def sample() -> Sample:
            temperature = emu.call(lambda: emulator.nck.sensor_temperature_C(sensor_name)) \
                if sensor_name else math.nan
            return Sample(clock.now_s(), temperature, emu.call(lambda: emulator.nck.tc_value_mm(axis)))

        runner = PlcRunner(program, client, read_peripheral, clock.now_s)
        started_s = time.monotonic()

        def advance() -> None:
            emu.call(lambda: clock.advance(cycle_s))
            if speed:  # hold simulated time to `speed` times the wall clock
                ahead_s = clock.now_s() / speed - (time.monotonic() - started_s)
                if ahead_s > 0:
                    time.sleep(ahead_s)

        flags = _cycle_loop(runner, clock.now_s, advance, duration_s, sample_every_s, sample, samples,
                            wait_for_jobs=True)
    return PlcRun(samples, runner.log, flags)


def _run_remote(program: Path, endpoint: str, duration_s: float, cycle_s: float, axis: int,
                sample_every_s: float) -> PlcRun:
    host, port = parse_endpoint(endpoint)
    samples: list[Sample] = []
    started_s = time.monotonic()

    def now_s() -> float:
        return time.monotonic() - started_s

    with NckClient(host, port) as client:
        mirror = InputMirror(client)
        extensions = True

        def sample() -> Sample:
            nonlocal extensions
            if extensions:  # nckemu's own variables; a real controller has none
                try:
                    temperature_C, tc_mm = client.get("NCKEMU_SENSOR_TEMP[0]", f"NCKEMU_TC_VALUE[AX{axis}]")
                    return Sample(now_s(), temperature_C, tc_mm)
                except NckError:
                    extensions = False
            return Sample(now_s(), math.nan, math.nan)

        runner = PlcRunner(program, client, mirror.read, now_s)

        def advance() -> None:
            mirror.refresh()
            next_cycle_s = (math.floor(now_s() / cycle_s) + 1) * cycle_s
            time.sleep(max(0.0, next_cycle_s - now_s()))

        flags = _cycle_loop(runner, now_s, advance, duration_s, sample_every_s, sample, samples, wait_for_jobs=False)
    return PlcRun(samples, runner.log, flags)


def _cycle_loop(runner: PlcRunner, now_s: Callable[[], float], advance: Callable[[], None], duration_s: float,
                sample_every_s: float, sample: Callable[[], Sample], samples: list[Sample],
                wait_for_jobs: bool) -> bytes:
    next_sample_s = 0.0
    try:
        while now_s() <= duration_s:
            runner.run_cycle()
            pending: list[concurrent.futures.Future[Any]] = runner.pending()
            if pending and wait_for_jobs:  # the cycle did not wait; simulated time waits for the network
                concurrent.futures.wait(pending, timeout=JOB_WAIT_S)
            if now_s() >= next_sample_s:
                samples.append(sample())
                next_sample_s += sample_every_s
            advance()
        return runner.flags()
    finally:
        runner.shutdown()


SEED000_POINTS = ((30.0, 0.0), (40.0, 0.3), (50.0, 0.6))


def seed000_problems(run: PlcRun, tolerance_mm: float = 0.01) -> list[str]:
    """Where the program's compensation departs from seed 000 (0 / 0.3 / 0.6 mm at 30 / 40 / 50 degC),
    in words a PLC programmer can act on."""
    problems = []
    for temperature_C, expected_mm in SEED000_POINTS:
        sample = min(run.samples, key=lambda s: abs(s.sensor_C - temperature_C))
        if abs(sample.tc_value_mm - expected_mm) > tolerance_mm:
            problems.append(
                f"at {sample.sensor_C:.1f} degC (t = {sample.time_s / 60:.0f} min) the Z compensation is "
                f"{sample.tc_value_mm:.3f} mm, but seed 000 expects {expected_mm:.3f} mm: check the comparison "
                f"with 30 degC, the scaling of PIW 420 and the columns of the address DB (SD43900 = W#16#AB7C)")
    if run.log.errors:
        problems.append(f"FB3 reported errors: {'; '.join(run.log.errors[:3])}")
    return problems
