"""Named value sources: how a catalogue variable with ``source = "..."`` gets (and takes) its value.

The catalogue names the source; this table binds the name to behaviour (as pymodbus's simulator binds
``"action": "increment"`` and asyncua a value callback). The model refuses, when it is built, any
variable whose source is not registered here, so a typo in the table is an error at start, not a
silently dead variable.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from nckemu.errors import NckAddressOutOfRange

from .alarms import alarm_number

if TYPE_CHECKING:
    from .channel import Channel, Spindle
    from .model import NckModel

Reader = Callable[["NckModel", int, int], object]           # (model, unit, line) -> value
Writer = Callable[["NckModel", int, int, object], None]     # (model, unit, line, value)


@dataclass(frozen=True)
class Source:
    read: Reader
    write: Writer | None = None


def _sensor_name(model: NckModel, line: int) -> str:
    sensors = model.machine.sensors
    if line > len(sensors):
        raise NckAddressOutOfRange(f"no sensor {line}")
    return sensors[line - 1].name


def _machine_axis_position(model: NckModel, _unit: int, line: int) -> object:
    if line not in model.axes.positions_mm:
        raise NckAddressOutOfRange(f"no machine axis {line}")
    return model.actual_position_mm(line)


def _axis_line(model: NckModel, line: int) -> int:
    """A machine axis by its line (the line is the machine axis number)."""
    if line not in model.axes.positions_mm:
        raise NckAddressOutOfRange(f"no machine axis {line}")
    return line


def _distance_to_go(model: NckModel, _unit: int, line: int) -> object:
    """The emulated axes reach a commanded position at once: nothing is left to go."""
    _axis_line(model, line)
    return 0.0


def _axis_feed_override(model: NckModel, unit: int, line: int) -> object:
    _axis_line(model, line)
    return _channel(model, unit).state.feed_override_pct


def _axis_name(model: NckModel, _unit: int, line: int) -> object:
    """MD10000: the machine axis name of axis <line>; "" for a line without an axis (assumed)."""
    axis = model.machine.axis(line)
    return axis.name if axis is not None else ""


def _channel_axis_name(model: NckModel, unit: int, line: int) -> object:
    """MD20080: the channel axis names; every machine axis is in channel 1, named as the machine axis
    without its trailing digits (X1 -> X), the way SINUMERIK's defaults pair MD10000 and MD20080
    (assumed). Other channels and lines past the last axis: ""."""
    axes = sorted(model.machine.axes, key=lambda axis: axis.number) if unit == 1 else []
    if line > len(axes):
        return ""
    name = axes[line - 1].name
    return name.rstrip("0123456789") or name


def _channel(model: NckModel, unit: int) -> Channel:
    return model.channels[unit]


def _spindle(model: NckModel, unit: int, line: int) -> Spindle:
    return model.channels[unit].spindle(line)


def _program_name(model: NckModel, _unit: int, _line: int) -> object:
    """The selected program's file name without its directory (``_N_TEST_MPF``)."""
    return model.programs.selected.rsplit("/", 1)[-1]


def _set_state(attribute: str, kind: type) -> Writer:
    def write(model: NckModel, unit: int, _line: int, value: object) -> None:
        setattr(_channel(model, unit).state, attribute, kind(value))
    return write


def _state(attribute: str) -> Source:
    """A channel state field that clients may also set (parts counters, overrides)."""
    return Source(lambda model, unit, _line: getattr(_channel(model, unit).state, attribute),
                  _set_state(attribute, float))


def _set_channel_command(model: NckModel, unit: int, _line: int, value: object) -> None:
    _channel(model, unit).command(int(value))  # type: ignore[call-overload]


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
    # no frames are emulated: the work (WCS) position is the machine position (assumed)
    "axes.work_position_by_line": Source(_machine_axis_position),
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
        lambda model, unit, line, value: setattr(_spindle(model, unit, line), "override_pct", float(value))),  # type: ignore[arg-type]
    "channel.spindle_turn_state": Source(lambda model, unit, line: _spindle(model, unit, line).direction),
    "programs.selected_name": Source(_program_name),
    "programs.selected": Source(lambda model, _unit, _line: model.programs.selected),
    "compensation.tc_value": Source(lambda model, unit, _line: model.compensation.tc_value_mm(unit)),
    "compensation.lec_value": Source(lambda model, unit, _line: model.compensation.lec_value_mm(unit)),
    "compensation.total": Source(lambda model, unit, _line: model.compensation.total_mm(unit)),
    "sensors.temperature": Source(
        lambda model, _unit, line: model.sensors.temperature_C(_sensor_name(model, line)),
        lambda model, _unit, line, value: model.sensors.set_temperature(
            _sensor_name(model, line), float(value))),  # type: ignore[arg-type]
}
