"""What the NCK model's collaborators may use of it: its parts, by a narrow protocol.

Named value sources (``sources``), PI services (``pi_services``) and a channel's program run
(``program_run.py`` and its environment and geometry) are handed the model, but type against :class:`NckParts`,
not the model class, so they depend on the parts they touch (axes, channels, tools, ...) and the
model depends on them, never the other way round.

A part named here never takes :class:`NckParts` (that would close a circle, type imports counted):
what a part needs of the others it names in its own protocol, beside it: ``channel.ChannelParts``,
``drives.DriveInputs``, ``geometric_axes.WorkpieceParts``. The model satisfies them all.
"""

from __future__ import annotations

from typing import Protocol

from nckemu.emulator.machine.clock import Clock
from nckemu.emulator.machine.machine_file import Machine
from nckemu.emulator.machine.nck.alarms import Alarms
from nckemu.emulator.machine.nck.axes import Axes
from nckemu.emulator.machine.nck.channel import Channel
from nckemu.emulator.machine.nck.compensation import Compensation
from nckemu.emulator.machine.nck.drives import Drives
from nckemu.emulator.machine.nck.frames import Frames
from nckemu.emulator.machine.nck.nck_io import NckIo
from nckemu.emulator.machine.nck.programs import Programs
from nckemu.emulator.machine.nck.sensors import Sensors
from nckemu.emulator.machine.nck.store import VariableStore
from nckemu.emulator.machine.nck.tools import Tools


class NckParts(Protocol):
    """The NCK's parts and the few whole-NCK operations a source or a PI service needs."""

    machine: Machine
    clock: Clock
    store: VariableStore
    axes: Axes
    sensors: Sensors
    compensation: Compensation
    programs: Programs
    alarm_list: Alarms
    channels: dict[int, Channel]
    tools: Tools
    frames: Frames
    drives: Drives
    nck_io: NckIo

    def actual_position_mm(self, axis: int) -> float: ...

    def work_position_mm(self, axis: int, channel: int = 1) -> float: ...

    def power_on(self) -> None: ...

    def activate_new_config(self) -> list[str]: ...
