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

if TYPE_CHECKING:
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


SOURCES: dict[str, Source] = {
    # SMA actToolBasePos: a channel variable whose line is the machine axis
    "axes.actual_position_by_line": Source(_machine_axis_position),
    "axes.actual_position": Source(lambda model, unit, _line: model.actual_position_mm(unit)),
    "axes.commanded_position": Source(
        lambda model, unit, _line: model.axes.positions_mm[unit],
        lambda model, unit, _line, value: model.axes.set_position(unit, float(value))),  # type: ignore[arg-type]
    "alarms.count": Source(lambda model, _unit, _line: model.alarm_list.count),
    "programs.selected": Source(lambda model, _unit, _line: model.programs.selected),
    "compensation.tc_value": Source(lambda model, unit, _line: model.compensation.tc_value_mm(unit)),
    "compensation.lec_value": Source(lambda model, unit, _line: model.compensation.lec_value_mm(unit)),
    "compensation.total": Source(lambda model, unit, _line: model.compensation.total_mm(unit)),
    "sensors.temperature": Source(
        lambda model, _unit, line: model.sensors.temperature_C(_sensor_name(model, line)),
        lambda model, _unit, line, value: model.sensors.set_temperature(
            _sensor_name(model, line), float(value))),  # type: ignore[arg-type]
}
