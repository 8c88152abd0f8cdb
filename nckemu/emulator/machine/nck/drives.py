"""SINAMICS drives as the NCK serves them in its drive area V: r-parameters computed from the machine,
p-parameters stored with the defaults a drive ships with.

Addressing (LSC, the 828D collector; docs/assumptions.md): area V, unit = drive number, column =
parameter number, line = parameter index + 1, module = drive object: 0x80 the control unit (CU), 0x81
the infeed (line module, LSC's "power supply module"), 0x82 the motor module of the drive. Values
travel big-endian, as everything in the drive areas. The catalogue (``variables.toml``) has one row per
parameter; the r-parameters name a value source ``drives.<object>.<parameter>`` bound here.

What the values follow:
  load       a drive's torque utilization in % (r0081): what ``set_load`` gave it, else its standstill
             load plus what its speed adds (friction and windage; no cutting is emulated)
  speed      a spindle drive turns with its spindle's actual speed (channel 1); feed axes stand
  r0035      the motor sensor's temperature (a recording's temp_<sensor>_C on a living machine), else
             ambient plus a steady rise with the square of the load
  r0030/27   torque-generating current in proportion to the load; r0027 adds the magnetizing current
  r0032      mechanical power (load x speed) over the efficiency, plus copper losses
  r0080      torque: the load of the rated torque (rated power over rated speed)
  r0026      the DC link at the supply's level; the infeed's r0032 is the drives' power over its efficiency
  r0037      power unit temperatures: ambient plus a rise with the current at the measured indices,
             ``unmeasured_C`` at the others
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Protocol

from nckemu.emulator.machine.machine_file import Drive, Machine
from nckemu.errors import NckObjectDoesNotExist

if TYPE_CHECKING:
    from nckemu.emulator.machine.nck.channel import Channel
    from nckemu.emulator.machine.nck.sensors import Sensors

# Drive objects (the module byte of an area-V item).
CONTROL_UNIT = 0x80
INFEED = 0x81
MOTOR_MODULE = 0x82
DRIVE_OBJECTS = {CONTROL_UNIT: "control unit", INFEED: "infeed", MOTOR_MODULE: "motor module"}
# The control unit and the infeed are one each in the line-up, reached with unit 1 (as LSC reads them;
# inferred: LSC never sends another unit for them).
SHARED_OBJECT_UNIT = 1

# r0037 power unit temperatures, by index (SINAMICS S120 list manual's meaning of the indices, from our
# reading; assumed): which are measured on a motor module and how much of the rise each sees.
R0037_MEASURED: dict[int, float] = {
    0: 1.0,    # inverter, maximum value
    1: 1.25,   # depletion layer (chip), maximum value
    3: 0.0,    # air intake
    4: 0.4,    # interior of the power unit
    5: 1.0,    # inverter 1
}
R0037_INDICES = 20


class DriveInputs(Protocol):
    """What the drive values read of the NCK: channel 1's spindles (the speed), the sensors (a motor
    sensor) and the line-up itself. Not the whole NCK (``parts.NckParts`` names the drives among its parts):
    the drives and the NCK would import each other."""

    @property
    def channels(self) -> Mapping[int, Channel]: ...

    @property
    def sensors(self) -> Sensors: ...

    @property
    def drives(self) -> Drives: ...


class Drives:
    """The line-up: drives by number, each with an optional load set from outside."""

    def __init__(self, machine: Machine) -> None:
        self.machine = machine
        self.settings = machine.drive_settings
        self.by_number: dict[int, Drive] = {drive.number: drive for drive in machine.drives}
        self._load_pct: dict[int, float] = {}
        spindle_axes = sorted(axis.number for axis in machine.axes if axis.spindle)
        # A spindle drive reports its spindle's speed: spindle s of channel 1 is the s-th spindle axis.
        self._spindle_of_axis = {axis: index for index, axis in enumerate(spindle_axes, 1)}

    @property
    def numbers(self) -> list[int]:
        return sorted(self.by_number)

    def units(self, module: int) -> list[int]:
        """The units of area V a drive object answers at."""
        if module == MOTOR_MODULE:
            return self.numbers
        return [SHARED_OBJECT_UNIT] if self.by_number else []

    def drive(self, number: int) -> Drive:
        drive = self.by_number.get(number)
        if drive is None:
            raise NckObjectDoesNotExist(f"no drive {number}")
        return drive

    def drive_of_axis(self, axis: int) -> Drive | None:
        return next((drive for drive in self.by_number.values() if drive.axis == axis), None)

    # ------------------------------------------------------------------ machine state
    def set_load(self, number: int, load_pct: float | None) -> None:
        """A drive's load in % from outside (a test, a PLC, a recording); None: back to the model's."""
        self.drive(number)
        if load_pct is None:
            self._load_pct.pop(number, None)
        else:
            self._load_pct[number] = float(load_pct)

    def speed_rpm(self, model: DriveInputs, number: int) -> float:
        drive = self.drive(number)
        spindle = self._spindle_of_axis.get(drive.axis or 0)
        channel = model.channels.get(1)
        if spindle is None or channel is None or spindle not in channel.state.spindles:
            return 0.0
        return channel.spindle_speed_rpm(spindle)

    def load_pct(self, model: DriveInputs, number: int) -> float:
        override = self._load_pct.get(number)
        if override is not None:
            return override
        drive = self.drive(number)
        fraction = min(abs(self.speed_rpm(model, number)) / drive.rated_speed_rpm, 1.5)
        return drive.standstill_load_pct + drive.speed_load_pct * fraction

    # ------------------------------------------------------------------ r-parameters of a motor module
    def torque_current_A(self, model: DriveInputs, number: int) -> float:
        """r0030: the torque-generating current Iq, in proportion to the load."""
        return self.drive(number).rated_current_A * self.load_pct(model, number) / 100.0

    def current_A(self, model: DriveInputs, number: int) -> float:
        """r0027: the absolute current, Iq and the magnetizing current Id together."""
        return math.hypot(self.torque_current_A(model, number), self.drive(number).magnetizing_current_A)

    def torque_Nm(self, model: DriveInputs, number: int) -> float:
        """r0080: the load (torque utilization, r0081) of the rated torque, rated power over rated speed."""
        drive = self.drive(number)
        rated_Nm = drive.rated_power_kW * 1000.0 / (2.0 * math.pi * drive.rated_speed_rpm / 60.0)
        return rated_Nm * self.load_pct(model, number) / 100.0

    def power_kW(self, model: DriveInputs, number: int) -> float:
        """r0032: electrical active power, motoring positive: load x speed over the efficiency, plus the
        copper losses of the current."""
        drive = self.drive(number)
        load = self.load_pct(model, number) / 100.0
        speed = min(abs(self.speed_rpm(model, number)) / drive.rated_speed_rpm, 1.0)
        mechanical_kW = drive.rated_power_kW * load * speed
        losses_kW = drive.rated_power_kW * (1.0 - self.settings.efficiency) * load * load
        return mechanical_kW / self.settings.efficiency + losses_kW

    def motor_temperature_C(self, model: DriveInputs, number: int) -> float:
        """r0035: the motor sensor, else ambient plus a steady rise with the square of the load."""
        drive = self.drive(number)
        if drive.motor_sensor is not None:
            return model.sensors.temperature_C(drive.motor_sensor)
        load = self.load_pct(model, number) / 100.0
        return self.settings.ambient_C + self.settings.motor_rise_K * load * load

    def power_unit_temperature_C(self, model: DriveInputs, number: int, index: int) -> float:
        """r0037[index]: ambient plus a rise with the current where the power unit has a sensor."""
        share = R0037_MEASURED.get(index)
        if share is None:
            return self.settings.unmeasured_C
        drive = self.drive(number)
        utilization = self.current_A(model, number) / drive.rated_current_A
        return self.settings.ambient_C + self.settings.power_unit_rise_K * share * utilization

    def temperatures_C(self, model: DriveInputs) -> list[dict[str, object]]:
        """Each drive's motor and power unit (inverter) temperature, for the live page."""
        return [{"number": number, "axis": self.by_number[number].axis,
                 "motor_C": self.motor_temperature_C(model, number),
                 "power_unit_C": self.power_unit_temperature_C(model, number, 0),
                 "load_pct": self.load_pct(model, number), "power_kW": self.power_kW(model, number)}
                for number in self.numbers]

    # ------------------------------------------------------------------ the infeed
    def infeed_power_kW(self, model: DriveInputs) -> float:
        """r0032 of the infeed: what the motor modules draw, over the infeed's efficiency."""
        return sum(self.power_kW(model, number) for number in self.numbers) / self.settings.infeed_efficiency


def _motor(value: Callable[[Drives, DriveInputs, int], float]) -> Callable[[DriveInputs, int, int], object]:
    def read(model: DriveInputs, unit: int, _line: int) -> object:
        return value(model.drives, model, unit)
    return read


# The value sources of the drive parameters (registered in ``sources.SOURCES``): (model, unit, line).
DRIVE_READERS: dict[str, Callable[[DriveInputs, int, int], object]] = {
    "drives.motor.r0021": _motor(lambda drives, model, unit: drives.speed_rpm(model, unit)),
    "drives.motor.r0026": lambda model, _unit, _line: model.drives.settings.dc_link_V,
    "drives.motor.r0027": _motor(lambda drives, model, unit: drives.current_A(model, unit)),
    "drives.motor.r0030": _motor(lambda drives, model, unit: drives.torque_current_A(model, unit)),
    "drives.motor.r0032": _motor(lambda drives, model, unit: drives.power_kW(model, unit)),
    "drives.motor.r0035": _motor(lambda drives, model, unit: drives.motor_temperature_C(model, unit)),
    "drives.motor.r0037": lambda model, unit, line: model.drives.power_unit_temperature_C(model, unit, line - 1),
    "drives.motor.r0080": _motor(lambda drives, model, unit: drives.torque_Nm(model, unit)),
    "drives.motor.r0081": _motor(lambda drives, model, unit: drives.load_pct(model, unit)),
    "drives.infeed.r0026": lambda model, _unit, _line: model.drives.settings.dc_link_V,
    "drives.infeed.r0032": lambda model, _unit, _line: model.drives.infeed_power_kW(model),
}
