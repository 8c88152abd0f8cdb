"""A user's STL program driven by a recording: what would the NCK have compensated?

The in-process emulator runs on simulated time with the recording's time base. Each PLC cycle
(``cycle_s``) the machine's sensors take the recording's ``temp_<name>_C`` (linear interpolation
between rows), so the program reads them through each sensor's ``plc_input`` scaling, and the axes
take their ``pos_<letter>_mm``; ``spindle_rpm`` drives a ``spindle_rpm`` input and the NCK's
actual speed of spindle 1 (what FB2 GET of actSpeed reads). At every recording row the temperature
compensation the NCK applies to the chosen axis (SD43900/43910/43920 as the program wrote them,
MD32750's bits, the MD32760 rate limit, the position) is sampled.

Sign: ``sim_<axis>_um`` is the compensation in the direction of the error it cancels, so that
``err - sim`` is the error left after compensation. With the default ``compensation_sign = -1`` a
positive TC value moves the axis negative, cancelling a positive (growing) error: seed 000's bed at
40 degC writes K0 = 0.3 mm and gives ``sim = +300 um``.
"""

from __future__ import annotations

import concurrent.futures
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nckemu.clients import NckClient
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import Axis, Machine, load_machine
from nckemu.emulator.runner import EmulatorThread
from nckemu.errors import NckConfigError
from nckemu.protocol.addresses import S7Area
from nckemu.thermal.recordings.recording import Recording

from .bridge import BridgeLog, PlcRunner, check_program
from .drive import (  # noqa: F401 (their old home)
    NCK_SPINDLE,
    SPINDLE_SPEED_SENSOR,
    RecordingDrive,
    check_inputs,
    nck_spindle_speed,
    sensor_column,
)

JOB_WAIT_S = 10.0
TC_BIT_POSITION_DEPENDENT = 2
# The marker a generated program carries when it writes tan beta (SD43910) and P0 (SD43920).
POSITION_DEPENDENT_MARKER = "nckemu: position-dependent compensation"

@dataclass
class RecordingRun:
    axis: Axis
    sim_um: np.ndarray                 # per recording row
    log: BridgeLog
    cycles: int
    warnings: list[str] = field(default_factory=list)
    probes: dict[str, np.ndarray] = field(default_factory=dict)
    # Recording time = the emulator's (and the job log's) simulated time + this.
    clock_offset_s: float = 0.0


def recording_axis(machine: Machine, letter: str) -> Axis:
    """The machine axis a recording letter (or a machine axis number) names."""
    if letter.isdigit():
        axis = machine.axis(int(letter))
        if axis is None:
            raise NckConfigError(f"--axis {letter}: the machine has no axis {letter}", path=machine.source)
        if not axis.recording:
            raise NckConfigError(f"machine axis {axis.number} ({axis.name}) has no recording letter: set "
                                 f"recording = \"Z\" in its [[axis]]", path=machine.source, field="axis.recording")
        return axis
    matches = [a for a in machine.axes if a.recording.upper() == letter.upper() and not a.spindle]
    if not matches:
        raise NckConfigError(f"no machine axis has the recording letter {letter!r} (set recording = \"{letter}\" in "
                             f"one [[axis]]; the default is the first letter of its name)", path=machine.source,
                             field="axis.recording")
    if len(matches) > 1:
        raise NckConfigError(f"axes {', '.join(a.name for a in matches)} share the recording letter {letter!r}",
                             path=machine.source, field="axis.recording")
    return matches[0]


def _check_axis(recording: Recording, axis: Axis) -> None:
    if axis.recording not in recording.errors_um and axis.recording not in recording.positions_mm:
        raise NckConfigError(f"the recording has neither err_{axis.recording}_um nor pos_{axis.recording}_mm "
                             f"for axis {axis.name}", path=recording.source, line=1)


def plc_inputs(machine: Machine, recording: Recording) -> tuple[list[str], bool]:
    """The temperature sensors the PLC reads (with a column), and whether it can read the spindle speed
    (a wired spindle_rpm input, or FB2 GET of the NCK's actual speed when the machine has a spindle)."""
    sensors = [s.name for s in machine.sensors if s.plc_input and s.name != SPINDLE_SPEED_SENSOR
               and f"temp_{s.name}_C" in recording.temperatures_C]
    spindle = (any(s.plc_input and s.name == SPINDLE_SPEED_SENSOR for s in machine.sensors)
               or nck_spindle_speed(machine)) and recording.spindle_rpm is not None
    return sensors, spindle


def position_dependent_warning(program_text: str, machine: Machine, axis: Axis) -> str | None:
    """A generated program that writes tan beta / P0 does nothing unless MD32750 bit 1 is set."""
    if POSITION_DEPENDENT_MARKER not in program_text:
        return None
    value = machine.initial.get("MD32750", {}).get(axis.number, 0)
    if isinstance(value, list):
        value = value[0] if value else 0
    if int(value) & TC_BIT_POSITION_DEPENDENT:
        return None
    return (f"the program writes position-dependent compensation (SD43910 tan beta, SD43920 P0) but "
            f"{machine.source} does not set MD32750 bit 1 for axis {axis.number}: the NCK ignores that part "
            f"(add MD32750 = {{ {axis.number} = {int(value) | 3} }} under [initial])")


def run_on_recording(program: str | Path, machine: str | Path | Machine | None, recording: Recording,
                     axis_letter: str, cycle_s: float = 1.0, progress: bool | None = None,
                     probes: dict[str, Callable[[PlcRunner], float]] | None = None,
                     warmup_s: float = 120.0) -> RecordingRun:
    """Run ``program`` over the whole ``recording``; sample the applied compensation at every row.

    The PLC starts ``warmup_s`` before the first row with the first row's inputs (the machine ran
    before the recording began), so a program writing once a minute has written by the first row.

    ``progress`` None: a tqdm bar on a terminal only. ``probes`` read the PLC (e.g. a DB value) at
    every row, for tests.
    """
    program = Path(program)
    if not program.is_file():
        raise NckConfigError("no such STL source", path=str(program))
    if not cycle_s > 0:
        raise NckConfigError("--cycle must be positive")
    program_text = check_program(program)
    machine = machine if isinstance(machine, Machine) else load_machine(machine)
    axis = recording_axis(machine, axis_letter)
    _check_axis(recording, axis)
    drive = RecordingDrive(machine, recording, cycle_s, warmup_s=warmup_s)
    warnings = [w for w in [position_dependent_warning(program_text, machine, axis)] if w]

    t_rows = drive.t_rows
    t0, cycles = drive.t0_s, drive.cycles
    t_cycles = t0 + cycle_s * np.arange(cycles)
    sign = -machine.settings.compensation_sign
    ipo_s = machine.ipo_cycle_s
    # The first row index at or after each cycle's start: rows in [t_k, t_k+1) are sampled after cycle k.
    row_bounds = np.searchsorted(t_rows, np.append(t_cycles[1:], math.inf), side="left").tolist()
    rows = t_rows.tolist()
    sim_um = np.full(len(rows), math.nan)
    probe_values = {name: np.full(len(rows), math.nan) for name in probes or {}}

    clock = SimulatedClock(0.0)  # simulated time starts at 0 with the first cycle
    emulator = Emulator(machine, clock=clock)
    nck = emulator.nck
    from tqdm import tqdm

    with EmulatorThread(emulator=emulator) as emu, NckClient("127.0.0.1", emu.port) as client:
        def read_peripheral(offset: int, size: int) -> bytes:
            # A PIW read only looks up sensor values, which only this thread sets: no hop needed
            # even while a job started in this cycle is on the emulator's thread.
            return emulator.plc.read(S7Area.P, 0, offset, size)

        runner = PlcRunner(program, client, read_peripheral, clock.now_s)
        bar = tqdm(total=cycles, unit="cycle", disable=None if progress is None else not progress,
                   desc=f"PLC on {Path(recording.source).name}", mininterval=0.5)
        next_row = 0
        try:
            # The emulator's thread touches the model only while it serves a job, and every job is
            # awaited before the next cycle: between cycles the model is ours without a thread hop
            # (emu.call costs about 0.9 ms a cycle, more than awlsim's cycle itself).
            for k in range(cycles):
                # The cycle a live `serve --inputs` runs too (plcsim/live.py): the recording's
                # inputs, then the program; only the clock and the wait for jobs differ.
                clock.set(k * cycle_s)
                drive.apply(nck, k)
                runner.run_cycle()
                pending = runner.pending()
                if pending:  # the cycle did not wait; simulated time waits for the network
                    concurrent.futures.wait(pending, timeout=JOB_WAIT_S)
                end = row_bounds[k]
                if end > next_row:
                    # One interpolation cycle after the row: the NCK recomputes the TC from the new
                    # position (and a value just written) in its next IPO cycle, not at the same instant.
                    limit = (k + 1) * cycle_s if k + 1 < cycles else math.inf
                    for row in range(next_row, end):
                        clock.set(max(clock.now_s(), min(rows[row] - t0 + ipo_s, limit)))
                        sim_um[row] = sign * nck.tc_value_mm(axis.number) * 1000.0
                    for name, probe in (probes or {}).items():
                        probe_values[name][next_row:end] = probe(runner)
                    next_row = end
                if k % 256 == 0:
                    bar.update(256 if k else 1)
            bar.update(cycles - bar.n)
        finally:
            bar.close()
            runner.shutdown()
    return RecordingRun(axis, sim_um, runner.log, cycles, warnings, probe_values, t0)


def with_simulation(recording: Recording, letter: str, sim_um: np.ndarray) -> Recording:
    return Recording(recording.source, recording.t_s, recording.temperatures_C, recording.spindle_rpm,
                     recording.positions_mm, recording.errors_um, {**recording.simulated_um, letter: sim_um})


def write_atomically(path: str | Path, recording: Recording) -> None:
    """No partial SIM.csv on failure (``cliutil.write_atomically``)."""
    from nckemu.cliutil import write_atomically as write_whole
    from nckemu.thermal.recordings.recording import write_recording

    write_whole(path, lambda temporary: write_recording(temporary, recording))
