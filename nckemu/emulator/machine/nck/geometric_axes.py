"""The channel's axes in the workpiece coordinate system: BTSS module SGA, ``/Channel/GeometricAxis``.

A GeometricAxis row's line is not a machine axis (as in ``/Channel/MachineAxis``) but an axis of the
channel in the workpiece coordinate system: the geometry axes first, named by MD20060
AXCONF_GEOAX_NAME_TAB (X, Y, Z by default), then the channel's other path axes by machine axis number
(assumed; a spindle has no WCS position). On the default machine (X1, Y1, SP1, Z1) line 3 is Z1, machine
axis 4. Only channel 1 holds axes, as for the channel axis names (MD20080).

Positions: the machine position less the active settable frame's translation and through the frame a
running program has programmed (TRANS, ROT, SCALE, MIRROR; the ``workPosition`` row takes them off too),
the tool base; the
programmed point (``actProgPos``, ``cmdProgPos``) lies the active tool edge's length along that geometry
axis below it (actOriToolLength1..3). ``cmd...`` is where the NCK commands the axis, ``act...`` where it
is, the temperature and leadscrew compensation included.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Protocol

from nckemu.emulator.machine.machine_file import GEOMETRY_AXIS_NAMES
from nckemu.errors import NckAddressOutOfRange

if TYPE_CHECKING:
    from nckemu.emulator.machine.machine_file import Machine
    from nckemu.emulator.machine.nck.axes import Axes
    from nckemu.emulator.machine.nck.frames import Frames
    from nckemu.emulator.machine.nck.tools import Tools


class ActiveEdge(Protocol):
    """The tool edge a channel has active (its state's T and D numbers)."""

    @property
    def t_number(self) -> int: ...

    @property
    def d_number(self) -> int: ...


class EdgeOfChannel(Protocol):
    @property
    def state(self) -> ActiveEdge: ...


class WorkpieceParts(Protocol):
    """What the workpiece view of the channel's axes reads of the NCK: the machine's axes and tool
    settings, the axes' positions (commanded and, compensation included, actual), the frames, the
    tools and each channel's active edge. Not the whole NCK (``parts.NckParts``): the channel's
    planner names the geometry axes from here, and the channel is one of the NCK's parts."""

    @property
    def machine(self) -> Machine: ...

    @property
    def axes(self) -> Axes: ...

    @property
    def frames(self) -> Frames: ...

    @property
    def tools(self) -> Tools: ...

    @property
    def channels(self) -> Mapping[int, EdgeOfChannel]: ...

    def actual_position_mm(self, axis: int) -> float: ...


def channel_axis_name(machine_axis_name: str) -> str:
    """MD20080 by default: the machine axis name without its trailing digits (X1 -> X)."""
    return machine_axis_name.rstrip("0123456789") or machine_axis_name


def wcs_axes(model: WorkpieceParts, channel: int) -> list[tuple[str, int]]:
    """The channel's axes in WCS order: (channel axis name, machine axis number) per line from 1."""
    if channel != 1:
        return []
    path_axes = [axis for axis in sorted(model.machine.axes, key=lambda axis: axis.number) if not axis.spindle]
    named = {channel_axis_name(axis.name).upper(): axis for axis in reversed(path_axes)}  # the first of a name
    geometry = [named[name] for name in GEOMETRY_AXIS_NAMES if name in named]
    others = [axis for axis in path_axes if axis not in geometry]
    return [(channel_axis_name(axis.name), axis.number) for axis in geometry + others]


def _axis(model: WorkpieceParts, channel: int, line: int) -> tuple[int, int]:
    """(machine axis number, geometry axis index 1..3 or 0) of a GeometricAxis line."""
    axes = wcs_axes(model, channel)
    if not 1 <= line <= len(axes):
        raise NckAddressOutOfRange(f"channel {channel} has no axis {line} in the workpiece coordinate system "
                                   f"(it has {len(axes)})")
    name, number = axes[line - 1]
    geometry = GEOMETRY_AXIS_NAMES.index(name.upper()) + 1 if name.upper() in GEOMETRY_AXIS_NAMES else 0
    return number, geometry


def _tool_length_mm(model: WorkpieceParts, channel: int, geometry: int) -> float:
    """The active tool edge's length along geometry axis ``geometry`` (1..3; 0 for another axis)."""
    if not geometry:
        return 0.0
    state = model.channels[channel].state
    component = model.machine.tool_settings.ori_length_components[geometry - 1]
    return float(model.tools.active_length_mm(state.t_number, state.d_number, component))


def _tool_base_of_mm(model: WorkpieceParts, channel: int, number: int, actual: bool) -> float:
    """The tool base of machine axis ``number`` in the channel's WCS."""
    machine_mm = model.actual_position_mm if actual else model.axes.positions_mm.__getitem__
    return model.frames.work_position_mm(channel, number, machine_mm)


def tool_base_mm(model: WorkpieceParts, channel: int, line: int, *, actual: bool = True) -> float:
    number, _geometry = _axis(model, channel, line)
    return _tool_base_of_mm(model, channel, number, actual)


def programmed_point_mm(model: WorkpieceParts, channel: int, line: int, *, actual: bool = True) -> float:
    number, geometry = _axis(model, channel, line)  # once: a read lists the channel's axes
    return _tool_base_of_mm(model, channel, number, actual) - _tool_length_mm(model, channel, geometry)


def axis_name(model: WorkpieceParts, channel: int, line: int) -> str:
    axes = wcs_axes(model, channel)
    return axes[line - 1][0] if 1 <= line <= len(axes) else ""


# The value sources of the GeometricAxis rows (registered in ``sources.SOURCES``): (model, unit, line).
GEOMETRIC_AXIS_READERS: dict[str, Callable[[WorkpieceParts, int, int], object]] = {
    "geometric_axes.actual_tool_base": lambda model, unit, line: tool_base_mm(model, unit, line),
    "geometric_axes.commanded_tool_base": lambda model, unit, line: tool_base_mm(model, unit, line, actual=False),
    "geometric_axes.actual_programmed": lambda model, unit, line: programmed_point_mm(model, unit, line),
    "geometric_axes.commanded_programmed": lambda model, unit, line: programmed_point_mm(
        model, unit, line, actual=False),
    "geometric_axes.name": axis_name,
}
