"""The NCK model: variables by typed address, temperature compensation, leadscrew tables, PI services.

It never sees bytes. Reads and writes go through the variable table (``variables.toml``); the
compensation engine follows an injectable clock at the IPO cycle and is advanced lazily in closed
form (between two events the applied value ramps linearly toward a fixed target, so jumping two
simulated hours costs the same as one cycle).
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from nckemu.protocol.addresses import NckAddress, NckArea, NckType
from nckemu.protocol.errors import (
    NckAccessDenied,
    NckAddressOutOfRange,
    NckConfigError,
    NckItemError,
    NckObjectDoesNotExist,
    NckServiceError,
    NckTypeInconsistent,
)

from ..clock import Clock
from ..machine import Machine
from .access import AccessContext
from .leadscrew import LeadscrewTable, parse_leadscrew_program
from .table import KNOWN_MODULES, VariableSpec, table_index

log = logging.getLogger(__name__)

SNAPSHOT_FORMAT = "nckemu-retained"
SNAPSHOT_VERSION = 1

# Header errors of PI services (class, code). The sources give no NCK-specific codes: these are
# the generic S7 codes that fit best, kept in one place so they can be corrected.
PI_ERROR_UNKNOWN_SERVICE = (0x81, 0x04)      # service not implemented on the module
PI_ERROR_BAD_ARGUMENTS = (0xD4, 0x05)        # syntax error in function parameters
PI_ERROR_WRONG_PASSWORD = (0xD6, 0x02)       # incorrect password entered
PI_ERROR_NO_SUCH_FILE = (0xD2, 0x01)         # syntax error in block name (no such program)
PI_ERROR_STATE = (0x84, 0x02)                # service cannot execute owing to the object's status
PI_ERROR_ACCESS = (0x87, 0x03)               # access to object refused (protection level)

# The power-on / NCK reset service name is not in our sources: an assumption.
PI_POWER_ON = "_N_NCKRES"
# nckemu extension (no Siemens service): load a leadscrew table program from a file on the emulator's
# host, as `serve --lec` does at start. Arguments: the address identification and the file's path.
PI_LOAD_LEADSCREW = "_N_NCKEMU_LEC"

TC_BIT_POSITION_INDEPENDENT = 0x01
TC_BIT_POSITION_DEPENDENT = 0x02
TC_BIT_TOOL_DIRECTION = 0x04

_AXIS_REF = re.compile(r"^AX(\d+)$", re.IGNORECASE)


@dataclass
class _TcRamp:
    """The 840D TC value applied to an axis and the IPO-quantized time it belongs to."""

    applied_mm: float = 0.0
    time_s: float = 0.0


@dataclass(frozen=True)
class Tc840c:
    k_tcabs_mm: float
    tan_beta: float
    p0_mm: float
    position_independent: bool
    position_dependent: bool

    def value_mm(self, position_mm: float) -> float:
        value = self.k_tcabs_mm if self.position_independent else 0.0
        if self.position_dependent:
            value += self.tan_beta * (position_mm - self.p0_mm)
        return value


class NckModel:
    """The NCK of one machine."""

    def __init__(self, machine: Machine, clock: Clock) -> None:
        self.machine = machine
        self.clock = clock
        self._index = table_index()
        self._resolved: dict[NckAddress, tuple[VariableSpec, int]] = {}
        self._stored: dict[tuple[str, int], list[Any]] = {}
        self._active: dict[tuple[str, int], list[Any]] = {}
        for spec in self._index.values():
            if spec.computed:
                continue
            for unit in self._units(spec):
                self._stored[(spec.name, unit)] = [spec.default] * spec.lines
        self._valid_units = {spec.name: frozenset(self._units(spec)) for spec in self._index.values()}
        self._apply_initial()
        self._active = {key: list(values) for key, values in self._stored.items()}
        self._positions_mm = {axis.number: axis.position_mm for axis in machine.axes}
        self._axis_specs = {axis.number: axis for axis in machine.axes}
        self._referenced = {axis.number: axis.referenced for axis in machine.axes}
        now_s = clock.now_s()
        self._tc = {axis.number: _TcRamp(0.0, now_s) for axis in machine.axes}
        self._tc_840c: dict[int, Tc840c] = {}
        self._lec_loaded: dict[tuple[int, int], LeadscrewTable] = {}
        self._lec_active: dict[int, LeadscrewTable] = {}
        self._sensor_override_C: dict[str, float] = {}
        self._power_on_hooks: list[Callable[[], None]] = []
        self._programs = {"/_N_MPF_DIR/_N_TEST_MPF", "/_N_MPF_DIR/_N_MAIN_MPF"}
        self._selected_program = ""
        self.alarms: list[str] = []

    # ------------------------------------------------------------------ set-up
    def _units(self, spec: VariableSpec) -> list[int]:
        units: list[int] = []
        for area in spec.areas:
            if area == NckArea.A:
                units.extend(axis.number for axis in self.machine.axes)
            elif area == NckArea.C:
                units.extend(range(1, self.machine.channels + 1))
            else:
                units.append(1)
        return units

    def _apply_initial(self) -> None:
        from .table import find_by_name

        for name, per_unit in self.machine.initial.items():
            spec = find_by_name(name)
            if spec is None or spec.computed:
                raise NckConfigError(f"no stored NCK variable {name!r}", path=self.machine.source,
                                     field=f"initial.{name}")
            for unit, value in per_unit.items():
                key = (spec.name, unit)
                if key not in self._stored:
                    raise NckConfigError(f"{name} has no unit {unit}", path=self.machine.source,
                                         field=f"initial.{name}")
                values = value if isinstance(value, list) else [value]
                for line, item in enumerate(values):
                    self._stored[key][line] = self._checked_value(spec, item)

    def add_power_on_hook(self, callback: Callable[[], None]) -> None:
        self._power_on_hooks.append(callback)

    # ------------------------------------------------------------------ addressing
    def _resolve(self, address: NckAddress) -> tuple[VariableSpec, int]:
        resolved = self._resolved.get(address)
        if resolved is None:
            resolved = self._resolve_uncached(address)
            if len(self._resolved) < 4096:  # hot addresses; a flood of distinct ones is not cached
                self._resolved[address] = resolved
        return resolved

    def _resolve_uncached(self, address: NckAddress) -> tuple[VariableSpec, int]:
        if address.module not in KNOWN_MODULES:
            raise NckObjectDoesNotExist(f"module 0x{address.module:02X} is not served")
        spec = self._index.get((address.module, address.column))
        if spec is None or address.area not in spec.areas:
            raise NckObjectDoesNotExist(f"no variable at module 0x{address.module:02X} column "
                                        f"{address.column} in area {NckArea(address.area).name}")
        unit = address.unit
        if address.area in (NckArea.N, NckArea.B) and unit == 0:
            unit = 1
        if unit not in self._valid_units[spec.name]:
            raise NckObjectDoesNotExist(f"{spec.name}: unit {address.unit} does not exist")
        last = address.line + address.line_count - 1
        if address.line < 1 or address.line_count < 1 or last > spec.lines:
            raise NckAddressOutOfRange(f"{spec.name}: lines {address.line}..{last} outside 1..{spec.lines}")
        return spec, unit

    def variable_type(self, address: NckAddress) -> tuple[NckType, int | None]:
        spec, _unit = self._resolve(address)
        return spec.nck_type, spec.string_length

    # ------------------------------------------------------------------ read / write
    def read_typed(self, address: NckAddress, ctx: AccessContext
                   ) -> tuple[NckType, int | None, list[object]]:
        """Type, string length and values in one lookup (the server's hot path)."""
        spec, _unit = self._resolve(address)
        return spec.nck_type, spec.string_length, self.read(address, ctx)

    def read(self, address: NckAddress, ctx: AccessContext) -> list[object]:
        spec, unit = self._resolve(address)
        if not ctx.may(spec.read_level):
            raise NckAccessDenied(f"{spec.number} needs access level {spec.read_level}")
        lines = range(address.line, address.line + address.line_count)
        if spec.computed:
            return [self._computed(spec, unit, line) for line in lines]
        values = self._stored[(spec.name, unit)]
        return values[address.line - 1:address.line - 1 + address.line_count]

    def write(self, address: NckAddress, values: Sequence[object], ctx: AccessContext) -> bool:
        spec, unit = self._resolve(address)
        if spec.read_only:
            raise NckAccessDenied(f"{spec.number} {spec.name} is read only")
        if not ctx.may(spec.write_level):
            raise NckAccessDenied(f"{spec.number} {spec.name} needs access level {spec.write_level}, "
                                  f"the connection has {ctx.level}")
        if len(values) != address.line_count:
            raise NckTypeInconsistent(f"{len(values)} values for {address.line_count} lines")
        checked = [self._checked_value(spec, value) for value in values]
        if spec.computed:
            for offset, value in enumerate(checked):
                self._write_computed(spec, unit, address.line + offset, value)
            return False
        self._advance_all()
        stored = self._stored[(spec.name, unit)]
        stored[address.line - 1:address.line - 1 + address.line_count] = checked
        if spec.effective in ("immediate", "reset"):
            self._active[(spec.name, unit)] = list(stored)
        return spec.retained

    def _checked_value(self, spec: VariableSpec, value: object) -> object:
        if spec.nck_type == NckType.STRING:
            return str(value)
        if spec.nck_type in (NckType.REAL4, NckType.REAL8):
            number = float(value)  # type: ignore[arg-type]
            if not math.isfinite(number):
                raise NckItemError(f"{spec.number}: {number} is not a finite number",
                                   return_code=self.machine.settings.limit_violation_return_code)
        else:
            number = int(value)  # type: ignore[call-overload]
        if ((spec.minimum is not None and number < spec.minimum)
                or (spec.maximum is not None and number > spec.maximum)):
            raise NckItemError(f"{spec.number} {spec.name}: {number} outside {spec.minimum}..{spec.maximum}",
                               return_code=self.machine.settings.limit_violation_return_code)
        return number

    def _active_value(self, name: str, unit: int, line: int = 1) -> Any:
        return self._active[(name, unit)][line - 1]

    def _stored_value(self, name: str, unit: int, line: int = 1) -> Any:
        return self._stored[(name, unit)][line - 1]

    # ------------------------------------------------------------------ computed variables
    def _computed(self, spec: VariableSpec, unit: int, line: int) -> object:
        name = spec.name
        if name == "actToolBasePos":
            if line not in self._positions_mm:
                raise NckAddressOutOfRange(f"no machine axis {line}")
            return self.actual_position_mm(line)
        if name == "numAlarms":
            return len(self.alarms)
        if name == "progName":
            return self._selected_program
        if name == "NCKEMU_TC_VALUE":
            return self.tc_value_mm(unit)
        if name == "NCKEMU_LEC_VALUE":
            return self.lec_value_mm(unit)
        if name == "NCKEMU_COMP_TOTAL":
            return self.compensation_mm(unit)
        if name == "NCKEMU_COMMANDED_POS":
            return self._positions_mm[unit]
        if name == "NCKEMU_ACTUAL_POS":
            return self.actual_position_mm(unit)
        if name == "NCKEMU_SENSOR_TEMP":
            sensors = self.machine.sensors
            if line > len(sensors):
                raise NckAddressOutOfRange(f"no sensor {line}")
            return self.sensor_temperature_C(sensors[line - 1].name)
        raise NckObjectDoesNotExist(f"{name} has no value source")

    def _write_computed(self, spec: VariableSpec, unit: int, line: int, value: object) -> None:
        if spec.name == "NCKEMU_COMMANDED_POS":
            self.set_axis_position(unit, float(value))  # type: ignore[arg-type]
        elif spec.name == "NCKEMU_SENSOR_TEMP":
            sensors = self.machine.sensors
            if line > len(sensors):
                raise NckAddressOutOfRange(f"no sensor {line}")
            self.set_sensor_temperature(sensors[line - 1].name, float(value))  # type: ignore[arg-type]
        else:
            raise NckAccessDenied(f"{spec.name} is read only")

    # ------------------------------------------------------------------ machine state
    def _axis(self, axis: int) -> None:
        if axis not in self._positions_mm:
            raise NckObjectDoesNotExist(f"machine axis {axis} does not exist")

    def set_axis_position(self, axis: int, position_mm: float) -> None:
        self._axis(axis)
        spec = self.machine.axis(axis)
        assert spec is not None
        if not spec.rotary and not spec.travel_min_mm <= position_mm <= spec.travel_max_mm:
            raise NckItemError(f"axis {spec.name}: {position_mm} mm outside its travel "
                               f"{spec.travel_min_mm}..{spec.travel_max_mm}",
                               return_code=self.machine.settings.limit_violation_return_code)
        self._advance(axis)
        self._positions_mm[axis] = position_mm

    def axis_position_mm(self, axis: int) -> float:
        self._axis(axis)
        return self._positions_mm[axis]

    def set_referenced(self, axis: int, referenced: bool) -> None:
        self._axis(axis)
        self._advance(axis)
        self._referenced[axis] = referenced
        if not referenced:
            self._lec_active.pop(axis, None)

    def sensor_temperature_C(self, name: str) -> float:
        for sensor in self.machine.sensors:
            if sensor.name == name:
                break
        else:
            raise NckObjectDoesNotExist(f"no sensor {name!r}")
        if name in self._sensor_override_C:
            return self._sensor_override_C[name]
        if not sensor.profile:
            return sensor.temperature_C
        t_s = self.clock.now_s()
        points = sensor.profile
        if t_s <= points[0][0]:
            return points[0][1]
        for (t0, c0), (t1, c1) in zip(points, points[1:], strict=False):
            if t_s <= t1:
                return c0 + (c1 - c0) * (t_s - t0) / (t1 - t0)
        return points[-1][1]

    def set_sensor_temperature(self, name: str, temperature_C: float) -> None:
        self.sensor_temperature_C(name)
        self._sensor_override_C[name] = temperature_C

    # ------------------------------------------------------------------ compensation
    def _tc_type(self, axis: int) -> int:
        return int(self._active_value("TEMP_COMP_TYPE", axis))

    def tc_target_mm(self, axis: int) -> float:
        """ΔK = K0 + tanβ·(P − P0), with only the parts the active MD32750 enables."""
        comp_type = self._tc_type(axis)
        if self.machine.settings.tc_requires_referenced and not self._referenced[axis]:
            return 0.0
        target = 0.0
        if comp_type & TC_BIT_POSITION_INDEPENDENT:
            target += float(self._stored_value("TEMP_COMP_ABS_VALUE", axis))
        if comp_type & TC_BIT_POSITION_DEPENDENT:
            slope = float(self._stored_value("TEMP_COMP_SLOPE", axis))
            p0_mm = float(self._stored_value("TEMP_COMP_REF_POSITION", axis))
            target += slope * (self._positions_mm[axis] - p0_mm)
        if comp_type & TC_BIT_TOOL_DIRECTION:
            target += self.tool_direction_tc_mm(axis)
        return target

    def tool_direction_tc_mm(self, axis: int) -> float:
        """SD42960 TOOL_TEMP_COMP[component] of channel 1, limited by MD20392 without an alarm, where
        MD20390 is on. Which component acts on which axis is a machine setting (unconfirmed)."""
        component = self._axis_specs[axis].tool_temp_comp_component
        if component is None or not int(self._active_value("TOOL_TEMP_COMP_ON", 1)):
            return 0.0
        value_mm = float(self._stored_value("TOOL_TEMP_COMP", 1, component))
        limit_mm = float(self._active_value("TOOL_TEMP_COMP_LIMIT", 1, component))
        return max(-limit_mm, min(limit_mm, value_mm))

    def tc_max_step_mm(self, axis: int) -> float:
        """Largest change per IPO cycle: MD32760 · MD32000 · T_IPO (MD32000 is in mm/min)."""
        factor = float(self._active_value("COMP_ADD_VELO_FACTOR", axis))
        max_velo_mm_per_s = float(self._active_value("MAX_AX_VELO", axis)) / 60.0
        return factor * max_velo_mm_per_s * self.machine.ipo_cycle_s

    def _advance(self, axis: int) -> None:
        ramp = self._tc[axis]
        ipo_s = self.machine.ipo_cycle_s
        cycles = math.floor((self.clock.now_s() - ramp.time_s) / ipo_s + 1e-9)
        if cycles <= 0:
            return
        ramp.time_s += cycles * ipo_s
        delta = self.tc_target_mm(axis) - ramp.applied_mm
        if delta == 0.0:
            return
        reach = cycles * self.tc_max_step_mm(axis)
        ramp.applied_mm = ramp.applied_mm + delta if abs(delta) <= reach else \
            ramp.applied_mm + math.copysign(reach, delta)

    def _advance_all(self) -> None:
        for axis in self._tc:
            self._advance(axis)

    def tc_value_mm(self, axis: int) -> float:
        """Applied temperature compensation: the smoothed 840D part plus any 840C part."""
        self._axis(axis)
        self._advance(axis)
        value = self._tc[axis].applied_mm
        tc_840c = self._tc_840c.get(axis)
        if tc_840c is not None:
            value += tc_840c.value_mm(self._positions_mm[axis])
        return value

    def lec_value_mm(self, axis: int) -> float:
        self._axis(axis)
        table = self._lec_active.get(axis)
        if table is None or not self._referenced[axis]:
            return 0.0
        return table.value_mm(self._positions_mm[axis])

    def compensation_mm(self, axis: int) -> float:
        """Total compensation of the axis: TC + LEC (summed, as the 840C manual says they are)."""
        return self.tc_value_mm(axis) + self.lec_value_mm(axis)

    def actual_position_mm(self, axis: int) -> float:
        """Where the axis really is: a positive compensation moves it negative (sign is a setting)."""
        return self._positions_mm[axis] + self.machine.settings.compensation_sign * self.compensation_mm(axis)

    def apply_840c_tc(self, axis: int, k_tcabs_mm: float, tan_beta: float, p0_mm: float,
                      position_independent: bool, position_dependent: bool) -> None:
        """840C: applied at once, without smoothing; erased at power-on."""
        self._axis(axis)
        self._tc_840c[axis] = Tc840c(k_tcabs_mm, tan_beta, p0_mm, position_independent, position_dependent)

    def tc_840c(self, axis: int) -> Tc840c | None:
        return self._tc_840c.get(axis)

    # ------------------------------------------------------------------ leadscrew tables
    def _axis_number(self, reference: str) -> int | None:
        match = _AXIS_REF.match(reference)
        if match:
            number = int(match.group(1))
            return number if number in self._positions_mm else None
        for axis in self.machine.axes:
            if axis.name.upper() == reference.upper():
                return axis.number
        return None

    def load_leadscrew_program(self, text: str, source: str = "<string>") -> list[LeadscrewTable]:
        """Load $AA_ENC_COMP tables (only while MD32700 = 0 is active); they act after power-on."""
        tables = parse_leadscrew_program(
            text, source, self._axis_number,
            lambda axis, encoder: int(self._active_value("MM_ENC_COMP_MAX_POINTS", axis, encoder + 1)))
        for table in tables:
            if int(self._active_value("ENC_COMP_ENABLE", table.axis, table.encoder + 1)):
                raise NckServiceError(f"{source}: axis {table.axis}: tables can be loaded only while "
                                      f"MD32700 ENC_COMP_ENABLE[{table.encoder}] = 0 is active",
                                      error_class=PI_ERROR_STATE[0], error_code=PI_ERROR_STATE[1])
        for table in tables:
            self._lec_loaded[(table.axis, table.encoder)] = table
        return tables

    def _activate_leadscrew(self) -> None:
        self._lec_active.clear()
        for (axis, encoder), table in self._lec_loaded.items():
            if encoder == 0 and int(self._active_value("ENC_COMP_ENABLE", axis, 1)) and self._referenced[axis]:
                self._lec_active[axis] = table

    # ------------------------------------------------------------------ power on
    def power_on(self) -> None:
        """Power-on: new machine data take effect, LEC activates, 840C TC data are erased."""
        self._advance_all()
        self._active = {key: list(values) for key, values in self._stored.items()}
        now_s = self.clock.now_s()
        for ramp in self._tc.values():
            ramp.applied_mm = 0.0
            ramp.time_s = now_s
        self._tc_840c.clear()
        self._activate_leadscrew()
        for hook in self._power_on_hooks:
            hook()
        log.info("NCK power-on")

    # ------------------------------------------------------------------ PI services
    def pi_service(self, service: str, arguments: Sequence[str], ctx: AccessContext) -> None:
        handler = _PI_HANDLERS.get(service)
        if handler is None:
            raise NckServiceError(f"PI service {service} is not supported",
                                  error_class=PI_ERROR_UNKNOWN_SERVICE[0], error_code=PI_ERROR_UNKNOWN_SERVICE[1])
        expected, function = handler
        if len(arguments) != expected:
            raise NckServiceError(f"{service} takes {expected} arguments, got {len(arguments)}",
                                  error_class=PI_ERROR_BAD_ARGUMENTS[0], error_code=PI_ERROR_BAD_ARGUMENTS[1])
        function(self, list(arguments), ctx)

    def _pi_login(self, arguments: list[str], ctx: AccessContext) -> None:
        level = self.machine.passwords.get(arguments[1])
        if level is None:
            raise NckServiceError("incorrect password", error_class=PI_ERROR_WRONG_PASSWORD[0],
                                  error_code=PI_ERROR_WRONG_PASSWORD[1])
        ctx.level = min(ctx.level, level)

    def _pi_logout(self, arguments: list[str], ctx: AccessContext) -> None:
        ctx.level = self.machine.connection_access_level

    def _pi_select(self, arguments: list[str], ctx: AccessContext) -> None:
        if arguments[1] not in self._programs:
            raise NckServiceError(f"no program {arguments[1]}", error_class=PI_ERROR_NO_SUCH_FILE[0],
                                  error_code=PI_ERROR_NO_SUCH_FILE[1])
        self._selected_program = arguments[1]

    def _pi_delete(self, arguments: list[str], ctx: AccessContext) -> None:
        if arguments[1] not in self._programs:
            raise NckServiceError(f"no file {arguments[1]}", error_class=PI_ERROR_NO_SUCH_FILE[0],
                                  error_code=PI_ERROR_NO_SUCH_FILE[1])
        if arguments[1] == self._selected_program:
            raise NckServiceError(f"{arguments[1]} is selected", error_class=PI_ERROR_STATE[0],
                                  error_code=PI_ERROR_STATE[1])
        self._programs.discard(arguments[1])

    def _pi_setudt(self, arguments: list[str], ctx: AccessContext) -> None:
        log.info("user data taken over (_N_SETUDT)")

    def _pi_power_on(self, arguments: list[str], ctx: AccessContext) -> None:
        self.power_on()

    def _pi_load_leadscrew(self, arguments: list[str], ctx: AccessContext) -> None:
        from .table import find_by_name

        enable = find_by_name("ENC_COMP_ENABLE")
        assert enable is not None
        if not ctx.may(enable.write_level):  # the same protection as the machine data that enables it
            raise NckServiceError(f"loading a table needs access level {enable.write_level}",
                                  error_class=PI_ERROR_ACCESS[0], error_code=PI_ERROR_ACCESS[1])
        path = arguments[1]
        try:
            with open(path, encoding="utf-8") as handle:
                text = handle.read()
        except (OSError, UnicodeDecodeError) as exc:
            log.warning("%s %s: cannot read (%s)", PI_LOAD_LEADSCREW, path, exc)
            raise NckServiceError(f"cannot read {path}", error_class=PI_ERROR_NO_SUCH_FILE[0],
                                  error_code=PI_ERROR_NO_SUCH_FILE[1]) from None
        try:
            tables = self.load_leadscrew_program(text, path)
        except NckServiceError as exc:
            log.warning("%s: %s", PI_LOAD_LEADSCREW, exc)
            raise
        except NckConfigError as exc:  # the wire has no room for the line; the log has it
            log.warning("%s: %s", PI_LOAD_LEADSCREW, exc)
            raise NckServiceError(str(exc), error_class=PI_ERROR_BAD_ARGUMENTS[0],
                                  error_code=PI_ERROR_BAD_ARGUMENTS[1]) from None
        log.info("%s: %d table(s) from %s; active after power-on with MD32700 = 1", PI_LOAD_LEADSCREW,
                 len(tables), path)

    def add_program(self, path: str) -> None:
        self._programs.add(path)

    # ------------------------------------------------------------------ retained data
    def retained_snapshot(self) -> dict[str, Any]:
        values: dict[str, dict[str, list[Any]]] = {}
        for (name, unit), stored in self._stored.items():
            spec = next(s for s in self._index.values() if s.name == name)
            if spec.retained:
                values.setdefault(name, {})[str(unit)] = list(stored)
        leadscrew = [
            {"axis": t.axis, "encoder": t.encoder, "values_mm": list(t.values_mm), "step_mm": t.step_mm,
             "min_mm": t.min_mm, "max_mm": t.max_mm, "modulo": t.modulo}
            for t in self._lec_loaded.values()
        ]
        return {"format": SNAPSHOT_FORMAT, "version": SNAPSHOT_VERSION, "values": values,
                "leadscrew": leadscrew}

    def restore_retained(self, snapshot: dict[str, Any]) -> None:
        """Retained values as after a restart (so they are active, as after power-on)."""
        if snapshot.get("format") != SNAPSHOT_FORMAT or snapshot.get("version") != SNAPSHOT_VERSION:
            raise NckConfigError("not an nckemu retained-state snapshot of version 1", field="format")
        try:
            for name, per_unit in snapshot["values"].items():
                for unit_text, stored in per_unit.items():
                    key = (name, int(unit_text))
                    if key not in self._stored:
                        log.warning("retained %s unit %s is not on this machine; ignored", name, unit_text)
                        continue
                    if len(stored) != len(self._stored[key]):
                        raise NckConfigError(f"{name}[{unit_text}] has {len(stored)} lines", field="values")
                    self._stored[key] = list(stored)
            self._lec_loaded = {}
            for row in snapshot.get("leadscrew", []):
                table = LeadscrewTable(int(row["axis"]), int(row["encoder"]),
                                       tuple(float(v) for v in row["values_mm"]), float(row["step_mm"]),
                                       float(row["min_mm"]), float(row["max_mm"]), bool(row["modulo"]))
                self._lec_loaded[(table.axis, table.encoder)] = table
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise NckConfigError(f"damaged retained-state snapshot: {exc!r}") from None
        self._active = {key: list(values) for key, values in self._stored.items()}
        self._activate_leadscrew()


_PI_HANDLERS: dict[str, tuple[int, Callable[[NckModel, list[str], AccessContext], None]]] = {
    "_N_LOGIN_": (2, NckModel._pi_login),
    "_N_LOGOUT": (1, NckModel._pi_logout),
    "_N_SELECT": (2, NckModel._pi_select),
    "_N_F_DELE": (2, NckModel._pi_delete),
    "_N_SETUDT": (1, NckModel._pi_setudt),
    PI_POWER_ON: (1, NckModel._pi_power_on),
    PI_LOAD_LEADSCREW: (2, NckModel._pi_load_leadscrew),
}
