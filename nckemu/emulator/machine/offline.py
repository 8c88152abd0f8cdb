"""A program run without a server: the same channel, the same cycle, on a simulated clock.

``run_offline(emulator, path)`` selects and starts ``path`` on channel 1 of an emulator built with a
:class:`~nckemu.emulator.machine.clock.SimulatedClock` and steps the machine's cycle
(:meth:`Emulator.step_machine`) until the program ends, raises an alarm or ``max_time_s`` has passed.
An M0 (or M1 with optional stop) is answered with NC start at once: offline nobody presses it. The
cycle is 1 s by default, as a served living machine's (``serve --speed``, ``--cycle 1s``): the time a
program takes does not depend on the cycle; the heat's inputs are taken once a cycle.
What the run would have recorded is sampled every ``sample_s``: the columns of a recording
(``t_s``, ``temp_<sensor>_C``, ``spindle_rpm``, ``pos_<axis>_mm``, and ``err_<axis>_um``: the error
the heat makes on the axis, less the compensation, as a gauge would read it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.machine_file import Axis, Machine
from nckemu.emulator.machine.nck.channel import CHAN_INTERRUPTED, CHAN_RESET
from nckemu.emulator.machine.program.block_record import BlockRecord
from nckemu.errors import NckConfigError

if TYPE_CHECKING:
    from nckemu.emulator.machine.core import Emulator

DEFAULT_MAX_TIME_S = 7 * 24 * 3600.0
OFFLINE_CYCLE_S = 1.0


@dataclass
class OfflineResult:
    outcome: str                    # ended, alarm, timeout
    t_s: float                      # simulated time at the end
    net_time_s: float
    blocks: int
    parts: float
    alarms: list[str] = field(default_factory=list)
    # standard cycles the run called without a motion model: name -> calls (0 s counted for each)
    not_simulated: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)   # e.g. a programmed speed MD35100 held lower

    def not_simulated_lines(self) -> list[str]:
        """"CYCLE62 not simulated: 0 s counted, 3 calls" for each such cycle, by name."""
        return [f"{name} not simulated: 0 s counted, {calls} call{'s' if calls != 1 else ''}"
                for name, calls in sorted(self.not_simulated.items())]


def _has_spindle(machine: Machine) -> bool:
    return any(axis.spindle for axis in machine.axes)


def _recorded_axes(machine: Machine) -> list[Axis]:
    """The axes a recording has columns of (pos_ and err_): those with a recording name, no spindle."""
    return [axis for axis in machine.axes if not axis.spindle and axis.recording]


def recording_columns(emulator: Emulator) -> list[str]:
    machine = emulator.machine
    axes = _recorded_axes(machine)
    columns = ["t_s", *(f"temp_{sensor.name}_C" for sensor in machine.sensors)]
    if _has_spindle(machine):
        columns.append("spindle_rpm")
    columns += [f"pos_{axis.recording}_mm" for axis in axes]
    columns += [f"err_{axis.recording}_um" for axis in axes]
    return columns


def sampler(emulator: Emulator) -> Callable[[float], list[float]]:
    """The row of ``recording_columns`` at a time: what is recorded is worked out once per run, not per row."""
    nck, machine = emulator.nck, emulator.machine
    axes = _recorded_axes(machine)
    spindle = _has_spindle(machine)

    def sample(t_s: float) -> list[float]:
        row = [t_s, *(nck.sensor_temperature_C(sensor.name) for sensor in machine.sensors)]
        if spindle:
            row.append(nck.channels[1].spindle_speed_rpm(1) if nck.channels[1].state.spindles else 0.0)
        row += [nck.actual_position_mm(axis.number) for axis in axes]
        row += [emulator.heat.measured_error_um(axis.number) for axis in axes]
        return row
    return sample


def run_offline(emulator: Emulator, path: str, *, cycle_s: float | None = None, sample_s: float = 1.0,
                max_time_s: float = DEFAULT_MAX_TIME_S,
                on_block: Callable[[BlockRecord], None] | None = None,
                on_sample: Callable[[list[float]], None] | None = None,
                on_progress: Callable[[float, BlockRecord | None], None] | None = None) -> OfflineResult:
    clock = emulator.clock
    if not isinstance(clock, SimulatedClock):
        raise NckConfigError("an offline run needs an emulator built with clock=SimulatedClock()")
    cycle = cycle_s or OFFLINE_CYCLE_S
    channel = emulator.nck.channels[1]
    last: list[BlockRecord | None] = [None]

    def seen(record: BlockRecord) -> None:
        last[0] = record
        if on_block is not None:
            on_block(record)

    listening = on_block is not None or on_progress is not None
    if listening:  # a block record is built only when someone reads it (--blocks, progress)
        channel.block_listeners.append(seen)
    start_s = clock.now_s()
    sample = sampler(emulator)
    channel.select(path)
    channel.start()
    cycles = channel.run.not_simulated if channel.run is not None else {}  # the run fills it as it goes
    if on_sample is not None:
        on_sample(sample(start_s))
    next_sample_s = start_s + sample_s
    k = 0
    outcome = "timeout"
    try:
        while True:
            k += 1
            t_s = start_s + k * cycle
            clock.set(t_s)
            emulator.step_machine(t_s)
            while on_sample is not None and next_sample_s <= t_s + 1e-9:
                on_sample(sample(t_s))
                next_sample_s += sample_s
            if on_progress is not None and k % 600 == 0:
                on_progress(t_s - start_s, last[0])
            status = channel.state.status
            if channel.alarms:
                outcome = "alarm"
                break
            if status == CHAN_RESET:
                outcome = "ended"
                break
            if status == CHAN_INTERRUPTED:
                channel.start()  # M0 / M1: offline nobody waits at the machine
            if t_s - start_s >= max_time_s:
                break
    finally:
        if listening:
            channel.block_listeners.remove(seen)
    if on_sample is not None and next_sample_s - sample_s < clock.now_s() - 1e-9:
        on_sample(sample(clock.now_s()))
    alarms = [alarm.text for alarm in emulator.nck.alarm_list.pending]
    net_s = channel.state.old_net_time_s if outcome == "ended" else channel.net_time_s
    blocks = channel.run.blocks if channel.run is not None else channel.last_run_blocks
    notes = list(channel.run.notes) if channel.run is not None else list(channel.last_run_notes)
    return OfflineResult(outcome, clock.now_s() - start_s, net_s, blocks, channel.state.actual_parts, alarms,
                         dict(cycles), notes)
