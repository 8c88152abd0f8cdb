"""A recording as the machine's inputs, cycle by cycle: the one code path of `plc run --inputs` and a
living `serve --inputs`.

Cycle k starts at recording time ``t0 + k * cycle_s`` (``t0`` is ``warmup_s`` before the first row,
rounded to whole cycles: the machine ran before the log began). At each cycle the machine's sensors
take the recording's ``temp_<name>_C`` (linear between rows), so the PLC reads them through each
sensor's ``plc_input`` scaling; axes with a ``pos_<letter>_mm`` column take it; ``spindle_rpm``
drives a ``spindle_rpm`` input and the NCK's actual speed of spindle 1. Past the last row the last
row's inputs hold, or, looping, the recording starts over at its first row.

A spindle that turns means a program runs: the recording's spindle speed also drives channel 1 as an
HMI would see it. When the spindle starts, the channel is started (active, program running, its net
program time counting; the mode group is in AUTOMATIC, the machine file's default); when it has stood
still for ``PROGRAM_END_IDLE_S`` of recording time, the program has ended (M30: a part counted, the
net time kept as the last program's, the channel reset). A stop shorter than that (a tool change)
leaves the program running. That run is shown under the recording's name as a main program
(``recording_program_path``: ``day-1.csv`` runs as ``/_N_MPF_DIR/_N_DAY_1_MPF``), so progName,
workPandProgName, umati ActiveProgram Name and CNC ActProgramName name it; no such program is stored.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from nckemu.catalogue.program_names import MAX_NAME_CHARS, program_path
from nckemu.emulator.machine.machine_file import Machine
from nckemu.emulator.machine.nck.channel import CHAN_ACTIVE
from nckemu.emulator.machine.nck.model import NckModel
from nckemu.errors import NckConfigError
from nckemu.thermal.recordings.recording import Recording

# A [[sensor]] with this name carries the spindle speed to the PLC (its "degrees" are rpm): driven
# from the recording's spindle_rpm column; the generator computes centrifugal growth from it.
SPINDLE_SPEED_SENSOR = "spindle_rpm"
# The recording's spindle_rpm also drives the NCK's actual speed (actSpeed) of this spindle of
# channel 1, so a program can read it with FB2 GET instead.
NCK_SPINDLE = 1
# Below this the spindle stands (a recording's noise around 0 is not a program).
SPINDLE_TURNING_RPM = 1.0
# A spindle standing this long (recording time) has ended its program: the channel counts a part.
PROGRAM_END_IDLE_S = 600.0


def recording_program_path(run_name: str) -> str:
    """The main program a recording's run is shown as: the run's name (the file's name without its
    extension) in upper case, each character that is not a letter, digit or _ made _, at most 24
    characters, ``REC_`` in front of a name that does not begin with a letter."""
    stem = re.sub(r"[^A-Z0-9_]", "_", run_name.upper().encode("ascii", "replace").decode("ascii"))
    if not stem[:1].isalpha():
        stem = "REC_" + stem
    return program_path(stem.rstrip("_")[:MAX_NAME_CHARS].rstrip("_") or "REC")


def sensor_column(recording: Recording, name: str) -> np.ndarray | None:
    if name == SPINDLE_SPEED_SENSOR:
        return recording.spindle_rpm
    return recording.temperatures_C.get(f"temp_{name}_C")


def nck_spindle_speed(machine: Machine) -> bool:
    """Whether the NCK has a spindle whose actual speed a recording's spindle_rpm drives."""
    return any(axis.spindle for axis in machine.axes)


def check_inputs(machine: Machine, recording: Recording) -> dict[int, np.ndarray]:
    """The columns every wired sensor needs (one line naming file, line and column when one is
    missing), and the positions of the axes the recording drives, checked against their travel."""
    for sensor in machine.sensors:
        key = f"temp_{sensor.name}_C"
        if sensor.name == SPINDLE_SPEED_SENSOR:
            if sensor.plc_input and recording.spindle_rpm is None:
                raise NckConfigError(f"the recording has no spindle_rpm column, which the spindle speed input "
                                     f"({sensor.plc_input}) of {machine.source} needs", path=recording.source,
                                     line=1, field="spindle_rpm")
            continue
        if sensor.plc_input and key not in recording.temperatures_C:
            raise NckConfigError(f"the recording has no column {key!r}, which sensor {sensor.name!r} "
                                 f"({sensor.plc_input}) of {machine.source} needs", path=recording.source,
                                 line=1, field=key)
    positions: dict[int, np.ndarray] = {}
    for candidate in machine.axes:
        values = recording.positions_mm.get(candidate.recording) if candidate.recording else None
        if values is None or candidate.rotary:
            continue
        outside = np.flatnonzero((values < candidate.travel_min_mm) | (values > candidate.travel_max_mm))
        if len(outside):
            row = int(outside[0])
            raise NckConfigError(f"{values[row]:g} mm is outside the travel of axis {candidate.name} "
                                 f"({candidate.travel_min_mm:g}..{candidate.travel_max_mm:g} mm)",
                                 path=recording.source, line=row + 2, field=f"pos_{candidate.recording}_mm")
        positions[candidate.number] = values
    return positions


@dataclass(frozen=True)
class CycleInputs:
    """What cycle k sets: recording time, and the values by sensor name / axis number."""

    t_rec_s: float
    sensors_C: tuple[tuple[str, float], ...]
    positions_mm: tuple[tuple[int, float], ...]
    spindle_rpm: float | None
    recording_pass: int


class RecordingDrive:
    """The inputs of each PLC cycle from a recording; ``apply(nck, k)`` sets them."""

    def __init__(self, machine: Machine, recording: Recording, cycle_s: float = 1.0, *,
                 warmup_s: float = 120.0, loop: bool = False) -> None:
        if not cycle_s > 0:
            raise NckConfigError("--cycle must be positive")
        self.machine = machine
        self.recording = recording
        self.cycle_s = float(cycle_s)
        self.loop = loop
        positions = check_inputs(machine, recording)
        self.t_rows = np.asarray(recording.t_s, dtype=float)
        first, last = float(self.t_rows[0]), float(self.t_rows[-1])
        # Recording time = simulated time + t0: cycle 0 runs at t0, warmup_s before the first row.
        self.t0_s = first - math.ceil(max(warmup_s, 0.0) / self.cycle_s - 1e-9) * self.cycle_s
        # Cycles of the first pass, the warm-up included; a looping pass starts at the first row.
        self.cycles = int(math.floor((last - self.t0_s) / self.cycle_s + 1e-9)) + 1
        self.pass_cycles = int(math.floor((last - first) / self.cycle_s + 1e-9)) + 1
        self._sensors = [(s.name, column) for s in machine.sensors
                         if (column := sensor_column(recording, s.name)) is not None]
        self._positions = list(positions.items())
        self._spindle = recording.spindle_rpm if recording.spindle_rpm is not None and nck_spindle_speed(machine) \
            else None
        self._idle_since_s: float | None = None  # recording time the spindle stopped, a program running
        self.program = recording_program_path(recording.name)  # what the faces name the recording's run
        # The first pass is interpolated once for all its cycles (the offline run's hot loop).
        t_cycles = self.t0_s + self.cycle_s * np.arange(self.cycles)
        self._first = self._series(t_cycles)

    def _series(self, t_cycles: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray],
                                                      np.ndarray | None]:
        return (t_cycles, [np.interp(t_cycles, self.t_rows, column) for _name, column in self._sensors],
                [np.interp(t_cycles, self.t_rows, values) for _number, values in self._positions],
                None if self._spindle is None else np.interp(t_cycles, self.t_rows, self._spindle))

    def recording_time_s(self, k: int) -> tuple[float, int]:
        """Recording time of cycle k and the pass it belongs to (1 = the first)."""
        if k < self.cycles:
            return self.t0_s + k * self.cycle_s, 1
        if not self.loop:
            return float(self.t_rows[-1]), 1
        j = k - self.cycles
        return float(self.t_rows[0]) + (j % self.pass_cycles) * self.cycle_s, 2 + j // self.pass_cycles

    def inputs(self, k: int) -> CycleInputs:
        if k < self.cycles:
            t_cycles, sensors, positions, spindle = self._first
            return self._pack(float(t_cycles[k]), 1, [float(series[k]) for series in sensors],
                              [float(series[k]) for series in positions],
                              None if spindle is None else float(spindle[k]))
        if not self.loop:  # past the end the last row holds
            return self._pack(float(self.t_rows[-1]), 1, [float(column[-1]) for _name, column in self._sensors],
                              [float(values[-1]) for _number, values in self._positions],
                              None if self._spindle is None else float(self._spindle[-1]))
        t_rec, recording_pass = self.recording_time_s(k)
        _t, sensors, positions, spindle = self._series(np.asarray([t_rec]))
        return self._pack(t_rec, recording_pass, [float(series[0]) for series in sensors],
                          [float(series[0]) for series in positions], None if spindle is None else float(spindle[0]))

    def _pack(self, t_rec: float, recording_pass: int, sensors_C: list[float], positions_mm: list[float],
              spindle_rpm: float | None) -> CycleInputs:
        return CycleInputs(t_rec, tuple(zip((name for name, _c in self._sensors), sensors_C, strict=True)),
                           tuple(zip((number for number, _v in self._positions), positions_mm, strict=True)),
                           spindle_rpm, recording_pass)

    def apply(self, nck: NckModel, k: int) -> CycleInputs:
        """Set cycle k's inputs on the model (its clock already at the cycle's time)."""
        inputs = self.inputs(k)
        for name, value in inputs.sensors_C:
            nck.set_sensor_temperature(name, value)
        for number, value in inputs.positions_mm:
            nck.set_axis_position(number, value)
        if inputs.spindle_rpm is not None:
            nck.set_spindle_speed(NCK_SPINDLE, inputs.spindle_rpm)
            self._run_program(nck, inputs)
        return inputs

    def _run_program(self, nck: NckModel, inputs: CycleInputs) -> None:
        """Channel 1 as the spindle says: turning, a program runs; standing long, it has ended."""
        channel = nck.channels.get(1)
        if channel is None or inputs.spindle_rpm is None:
            return
        active = channel.state.status == CHAN_ACTIVE
        if abs(inputs.spindle_rpm) >= SPINDLE_TURNING_RPM:
            self._idle_since_s = None
            if not active:
                channel.run_without_program(self.program)  # the recording says a program runs; none is selected
            return
        if not active:
            return
        t_rec = inputs.t_rec_s
        if self._idle_since_s is None or t_rec < self._idle_since_s:  # stopped now, or a new pass began
            self._idle_since_s = t_rec
        elif t_rec - self._idle_since_s >= PROGRAM_END_IDLE_S:
            channel.end_program()
            self._idle_since_s = None
