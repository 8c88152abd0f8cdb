"""Named value sources: how a catalogue variable with ``source = "..."`` gets (and takes) its value.

The catalogue names the source; this table binds the name to behaviour (as pymodbus's simulator binds
``"action": "increment"`` and asyncua a value callback). The model refuses, when it is built, any
variable whose source is not registered here, so a typo in the table is an error at start, not a
silently dead variable.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from nckemu.emulator.machine.nck.alarms import alarm_number
from nckemu.emulator.machine.nck.drives import DRIVE_READERS
from nckemu.emulator.machine.nck.geometric_axes import GEOMETRIC_AXIS_READERS, channel_axis_name
from nckemu.errors import NckAccessDenied, NckAddressOutOfRange, NckPiStateError

if TYPE_CHECKING:
    from nckemu.emulator.machine.nck.channel import Channel, Spindle
    from nckemu.emulator.machine.nck.parts import NckParts

Reader = Callable[["NckParts", int, int], object]           # (model, unit, line) -> value
Writer = Callable[["NckParts", int, int, object], None]     # (model, unit, line, value)
# Sources of variables over several columns (catalogue ``columns``) also get the column.
ColumnReader = Callable[["NckParts", int, int, int], object]          # (model, unit, column, line)
ColumnWriter = Callable[["NckParts", int, int, int, object], None]    # (model, unit, column, line, value)


@dataclass(frozen=True)
class Source:
    """How a computed variable is read and written: by (unit, line), or, for a variable over several
    columns, by (unit, column, line)."""

    read: Reader | None = None
    write: Writer | None = None
    read_column: ColumnReader | None = None
    write_column: ColumnWriter | None = None

    @property
    def by_column(self) -> bool:
        return self.read_column is not None

    @property
    def writable(self) -> bool:
        return self.write is not None or self.write_column is not None

    def read_lines(self, model: NckParts, unit: int, column: int, first: int, count: int) -> list[object]:
        if self.read_column is not None:
            read_at = self.read_column
            return [read_at(model, unit, column, line) for line in range(first, first + count)]
        if self.read is None:
            raise NckAddressOutOfRange("no value source to read")
        read = self.read
        return [read(model, unit, line) for line in range(first, first + count)]

    def write_lines(self, model: NckParts, unit: int, column: int, first: int, values: Sequence[object]) -> None:
        for offset, value in enumerate(values):
            if self.write_column is not None:
                self.write_column(model, unit, column, first + offset, value)
            elif self.write is not None:
                self.write(model, unit, first + offset, value)
            else:
                raise NckAccessDenied("read only")


def _by_column(read: ColumnReader, write: ColumnWriter | None = None) -> Source:
    return Source(read_column=read, write_column=write)


def _sensor_name(model: NckParts, line: int) -> str:
    sensors = model.machine.sensors
    if line > len(sensors):
        raise NckAddressOutOfRange(f"no sensor {line}")
    return sensors[line - 1].name


def _machine_axis_position(model: NckParts, _unit: int, line: int) -> object:
    if line not in model.axes.positions_mm:
        raise NckAddressOutOfRange(f"no machine axis {line}")
    return model.actual_position_mm(line)


def _axis_line(model: NckParts, line: int) -> int:
    """A machine axis by its line (the line is the machine axis number)."""
    if line not in model.axes.positions_mm:
        raise NckAddressOutOfRange(f"no machine axis {line}")
    return line


def _distance_to_go(model: NckParts, _unit: int, line: int) -> object:
    """The emulated axes reach a commanded position at once: nothing is left to go."""
    _axis_line(model, line)
    return 0.0


def _axis_feed_override(model: NckParts, unit: int, line: int) -> object:
    _axis_line(model, line)
    return _channel(model, unit).state.feed_override_pct


def _axis_name(model: NckParts, _unit: int, line: int) -> object:
    """MD10000: the machine axis name of axis <line>; "" for a line without an axis (assumed)."""
    axis = model.machine.axis(line)
    return axis.name if axis is not None else ""


def _channel_axis_name(model: NckParts, unit: int, line: int) -> object:
    """MD20080: the channel axis names; every machine axis is in channel 1, named as the machine axis
    without its trailing digits (X1 -> X), the way SINUMERIK's defaults pair MD10000 and MD20080
    (assumed). Other channels and lines past the last axis: ""."""
    axes = sorted(model.machine.axes, key=lambda axis: axis.number) if unit == 1 else []
    if line > len(axes):
        return ""
    return channel_axis_name(axes[line - 1].name)


def _channel(model: NckParts, unit: int) -> Channel:
    return model.channels[unit]


def _spindle(model: NckParts, unit: int, line: int) -> Spindle:
    return model.channels[unit].spindle(line)


def _selected(model: NckParts, unit: int) -> str:
    """The channel's selected program (channel 1's is also the program store's selection); with none,
    the name a run without a program is shown under (a recording's run)."""
    channel = model.channels.get(unit)
    selected = (channel.selected or channel.recorded_program) if channel is not None else ""
    return selected or (model.programs.selected if unit == 1 else "")


def _program_name(model: NckParts, unit: int, _line: int) -> object:
    """The selected program's file name without its directory (``_N_TEST_MPF``)."""
    return _selected(model, unit).rsplit("/", 1)[-1]


def _set_state(attribute: str, kind: type) -> Writer:
    def write(model: NckParts, unit: int, _line: int, value: object) -> None:
        _channel(model, unit).set_figure(attribute, kind(value))
    return write


def _state(attribute: str) -> Source:
    """A channel state field that clients may also set (parts counters, overrides)."""
    return Source(lambda model, unit, _line: getattr(_channel(model, unit).state, attribute),
                  _set_state(attribute, float))


def _work_position(model: NckParts, unit: int, line: int) -> object:
    _axis_line(model, line)
    return model.work_position_mm(line, unit)


def _set_edge_param(model: NckParts, _unit: int, column: int, line: int, value: object) -> None:
    model.tools.set_edge_param(column, line, float(value))  # type: ignore[arg-type]


def _active_length(component: int) -> Source:
    def read(model: NckParts, unit: int, _line: int) -> object:
        state = _channel(model, unit).state
        return model.tools.active_length_mm(state.t_number, state.d_number, component)
    return Source(read)


def _ori_length(axis: int) -> Source:
    """actOriToolLength1..3: the active tool length along geometry axis X, Y or Z (1..3)."""
    def read(model: NckParts, unit: int, _line: int) -> object:
        state = _channel(model, unit).state
        component = model.machine.tool_settings.ori_length_components[axis - 1]
        return model.tools.active_length_mm(state.t_number, state.d_number, component)
    return Source(read)


def _active_h_number(model: NckParts, unit: int, _line: int) -> object:
    state = _channel(model, unit).state
    return model.tools.h_number(state.t_number, state.d_number)


def _active_radius(model: NckParts, unit: int, _line: int) -> object:
    state = _channel(model, unit).state
    return model.tools.active_radius_mm(state.t_number, state.d_number)


def _set_settable_shift(model: NckParts, unit: int, line: int, value: object) -> None:
    model.frames.set_settable_shift(unit, line, float(value))  # type: ignore[arg-type]


def _set_channel_command(model: NckParts, unit: int, _line: int, value: object) -> None:
    try:
        _channel(model, unit).command(int(value))  # type: ignore[call-overload]
    except NckPiStateError as exc:  # NC start refused (JOG, an alarm): the item's error, the alarm on the list
        raise NckAccessDenied(str(exc)) from None


def _set_mode(model: NckParts, _unit: int, _line: int, value: object) -> None:
    """opMode of the mode group: every channel of it (one mode group) takes the mode. Refused while a
    program runs: the item answers "access denied" (0x03), the control's alarm is on the list."""
    for channel in model.channels.values():
        try:
            channel.set_mode(int(value))  # type: ignore[call-overload]
        except NckPiStateError as exc:
            raise NckAccessDenied(str(exc)) from None


def _channel_value(attribute: str) -> Source:
    return Source(lambda model, unit, _line: getattr(_channel(model, unit).state, attribute))


SOURCES: dict[str, Source] = {
    # SMA actToolBasePos: a channel variable whose line is the machine axis
    "axes.actual_position_by_line": Source(_machine_axis_position),
    "axes.actual_position": Source(lambda model, unit, _line: model.actual_position_mm(unit)),
    "axes.commanded_position": Source(
        lambda model, unit, _line: model.axes.positions_mm[unit],
        lambda model, unit, _line, value: model.axes.set_position(unit, float(value))),  # type: ignore[arg-type]
    "axes.remaining_by_line": Source(_distance_to_go),
    "axes.feed_override_by_line": Source(_axis_feed_override),
    "clock.milliseconds": Source(lambda model, _unit, _line: int(model.clock.now_s() * 1000.0) % 2**32),
    # SEGA actToolBasPosEN: the machine position less the active settable frame's translation
    "axes.work_position_by_line": Source(_work_position),
    "axes.name_by_line": Source(_axis_name),
    "axes.count": Source(lambda model, _unit, _line: len(model.machine.axes)),
    "axes.spindle_count": Source(lambda model, _unit, _line: sum(a.spindle for a in model.machine.axes)),
    "channel.axis_name_by_line": Source(_channel_axis_name),
    "alarms.count": Source(lambda model, _unit, _line: model.alarm_list.count),
    "alarms.by_time": Source(lambda model, _unit, line: alarm_number(model.alarm_list.by_time(line))),
    "alarms.last": Source(lambda model, _unit, line: alarm_number(model.alarm_list.last() if line == 1 else None)),
    "alarms.by_priority": Source(lambda model, _unit, line: alarm_number(model.alarm_list.by_priority(line))),
    "alarms.events": Source(lambda model, _unit, line: alarm_number(model.alarm_list.event(line))),
    "channel.status": Source(lambda model, unit, _line: _channel(model, unit).state.status),
    "channel.program_status": Source(lambda model, unit, _line: _channel(model, unit).state.program_status),
    "channel.command": Source(lambda model, unit, _line: _channel(model, unit).state.status, _set_channel_command),
    "channel.ac_prog": Source(lambda model, unit, _line: _channel(model, unit).ac_prog),
    "channel.start_counter": _channel_value("start_counter"),
    "channel.end_counter": _channel_value("end_counter"),
    "channel.reset_counter": _channel_value("reset_counter"),
    "channel.block_number": _channel_value("block_number"),
    "channel.line_number": _channel_value("line_number"),
    "channel.block_text": _channel_value("block_text"),
    "channel.message": _channel_value("message"),
    "channel.spindle_commanded_speed": Source(
        lambda model, unit, line: _channel(model, unit).spindle_commanded_rpm(line)),
    "bag.mode": Source(lambda model, _unit, _line: model.channels[1].state.mode if model.channels else 2, _set_mode),
    "channel.t_number": Source(lambda model, unit, _line: _channel(model, unit).state.t_number),
    "channel.d_number": Source(lambda model, unit, _line: _channel(model, unit).state.d_number),
    "channel.d_number_text": Source(lambda model, unit, _line: str(_channel(model, unit).state.d_number)),
    "channel.tool_ident": Source(lambda model, unit, _line: _channel(model, unit).state.tool_ident),
    "channel.actual_feed": Source(lambda model, unit, _line: _channel(model, unit).actual_feed_mm_min),
    "channel.commanded_feed": _state("commanded_feed_mm_min"),
    "channel.feed_override": _state("feed_override_pct"),
    "channel.rapid_override": _state("rapid_override_pct"),
    "channel.required_parts": _state("required_parts"),
    "channel.total_parts": _state("total_parts"),
    "channel.actual_parts": _state("actual_parts"),
    "channel.specified_parts": _state("specified_parts"),
    "channel.net_time": Source(lambda model, unit, _line: _channel(model, unit).net_time_s),
    "channel.old_net_time": Source(lambda model, unit, _line: _channel(model, unit).state.old_net_time_s),
    "channel.cutting_time": Source(lambda model, unit, _line: _channel(model, unit).cutting_time_s),
    "channel.spindle_speed": Source(lambda model, unit, line: _channel(model, unit).spindle_speed_rpm(line)),
    "channel.spindle_override": Source(
        lambda model, unit, line: _spindle(model, unit, line).override_pct,
        lambda model, unit, line, value: _channel(model, unit).set_spindle_override(line, float(value))),  # type: ignore[arg-type]
    "channel.spindle_turn_state": Source(lambda model, unit, line: _spindle(model, unit, line).direction),
    # tool offsets (module TO: column = T number) and the active tool's compensation values
    "tools.edge_param": _by_column(lambda model, _unit, column, line: model.tools.edge_param(column, line),
                                   _set_edge_param),
    "tools.edge_param_count": Source(lambda model, _unit, _line: model.tools.params_per_edge),
    "tools.active_length1": _active_length(1),
    "tools.active_length2": _active_length(2),
    "tools.active_length3": _active_length(3),
    "tools.active_radius": Source(_active_radius),
    "tools.ori_length1": _ori_length(1),
    "tools.ori_length2": _ori_length(2),
    "tools.ori_length3": _ori_length(3),
    "tools.active_h_number": Source(_active_h_number),
    # work offsets: settable frames (FU), active frames (FA), the active settable frame's index
    "frames.settable_shift": Source(lambda model, unit, line: model.frames.settable_shift_mm(unit, line),
                                    _set_settable_shift),
    "frames.actual_shift": Source(lambda model, unit, line: model.frames.actual_frame_shift_mm(unit, line)),
    "frames.active_index": Source(lambda model, unit, _line: model.frames.active[unit]),
    "frames.count": Source(lambda model, _unit, _line: model.frames.count),
    # NCK configuration counts
    "nck.channel_count": Source(lambda model, _unit, _line: len(model.channels)),
    "axes.highest_number": Source(lambda model, _unit, _line: max((a.number for a in model.machine.axes), default=0)),
    "programs.selected_name": Source(_program_name),
    "programs.selected": Source(lambda model, unit, _line: _selected(model, unit)),
    "compensation.tc_value": Source(lambda model, unit, _line: model.compensation.tc_value_mm(unit)),
    "compensation.lec_value": Source(lambda model, unit, _line: model.compensation.lec_value_mm(unit)),
    "compensation.total": Source(lambda model, unit, _line: model.compensation.total_mm(unit)),
    "sensors.temperature": Source(
        lambda model, _unit, line: model.sensors.temperature_C(_sensor_name(model, line)),
        lambda model, _unit, line, value: model.sensors.set_temperature(
            _sensor_name(model, line), float(value))),  # type: ignore[arg-type]
    # SINAMICS drive parameters (area V): drives.py computes them
    **{name: Source(read) for name, read in DRIVE_READERS.items()},
    # SGA (/Channel/GeometricAxis): lines are the channel's axes in the WCS, geometric_axes.py
    **{name: Source(read) for name, read in GEOMETRIC_AXIS_READERS.items()},
}
