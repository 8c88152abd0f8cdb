"""``nckemu plc run``: a user's STL program in awlsim, against an in-process emulator on simulated time."""

from __future__ import annotations

import concurrent.futures
from dataclasses import dataclass
from pathlib import Path

from nckemu.clients import NckClient
from nckemu.emulator.clock import SimulatedClock
from nckemu.emulator.core import Emulator
from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol.addresses import S7Area

from .bridge import BridgeLog, PlcRunner


@dataclass
class Sample:
    time_s: float
    sensor_C: float
    tc_value_mm: float


@dataclass
class PlcRun:
    samples: list[Sample]
    log: BridgeLog


def run_program(program: str | Path, *, machine: str | Path | None = None, duration_s: float = 7200.0,
                cycle_s: float = 1.0, axis: int = 4, sensor: str | None = None, sample_every_s: float = 60.0
                ) -> PlcRun:
    clock = SimulatedClock()
    emulator = Emulator(machine, clock=clock)
    sensor_name = sensor or (emulator.machine.sensors[0].name if emulator.machine.sensors else None)
    samples: list[Sample] = []
    with EmulatorThread(emulator=emulator) as emu, NckClient("127.0.0.1", emu.port) as client:
        def read_peripheral(offset: int, size: int) -> bytes:
            return emu.call(lambda: emulator.plc.read(S7Area.P, 0, offset, size))

        runner = PlcRunner(Path(program), client, read_peripheral, clock.now_s)
        next_sample_s = 0.0
        try:
            while clock.now_s() <= duration_s:
                runner.run_cycle()
                pending = runner.pending()
                if pending:  # the cycle did not wait; simulated time waits for the network instead
                    concurrent.futures.wait(pending, timeout=10)
                if clock.now_s() >= next_sample_s:
                    temperature = emu.call(lambda: emulator.nck.sensor_temperature_C(sensor_name)) \
                        if sensor_name else float("nan")
                    samples.append(Sample(clock.now_s(), temperature, emu.call(lambda: emulator.nck.tc_value_mm(axis))))
                    next_sample_s += sample_every_s
                emu.call(lambda: clock.advance(cycle_s))
        finally:
            runner.shutdown()
    return PlcRun(samples, runner.log)


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
