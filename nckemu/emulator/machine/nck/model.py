"""The NCK of one machine: the components of each concern composed behind the datastore interface.

It never sees bytes. ``store`` holds stored and active values by typed address, ``axes`` and
``sensors`` the machine's state, ``compensation`` the TC and LEC engines, ``programs`` and
``alarm_list`` and ``channels`` (program run state) what the NCK reports; variables with a named ``source`` are computed through
``sources.SOURCES`` and PI services run through ``pi_services``. The dispatcher sees only the
``NckDatastore`` methods (read_typed, variable_type, read, write, pi_service, power_on).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

from nckemu.catalogue.leadscrew import LeadscrewTable
from nckemu.catalogue.pi_services import PI_LOAD_LEADSCREW, PI_POWER_ON  # noqa: F401 (old import path)
from nckemu.catalogue.table import VariableSpec, load_table
from nckemu.emulator.machine.clock import Clock
from nckemu.emulator.machine.machine_file import Machine
from nckemu.emulator.machine.nck import pi_services
from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.emulator.machine.nck.alarms import Alarms
from nckemu.emulator.machine.nck.axes import Axes
from nckemu.emulator.machine.nck.channel import Channel
from nckemu.emulator.machine.nck.compensation import (  # noqa: F401 (old import path)
    TC_BIT_POSITION_DEPENDENT,
    TC_BIT_POSITION_INDEPENDENT,
    TC_BIT_TOOL_DIRECTION,
    Compensation,
    Tc840c,
)
from nckemu.emulator.machine.nck.drives import Drives
from nckemu.emulator.machine.nck.frames import Frames
from nckemu.emulator.machine.nck.nck_environment import r_parameter_lines
from nckemu.emulator.machine.nck.nck_io import NckIo
from nckemu.emulator.machine.nck.program_run import ProgramRun
from nckemu.emulator.machine.nck.programs import Programs
from nckemu.emulator.machine.nck.sensors import Sensors
from nckemu.emulator.machine.nck.sources import SOURCES
from nckemu.emulator.machine.nck.store import VariableStore
from nckemu.emulator.machine.nck.tools import Tools
from nckemu.emulator.machine.program.motions import ProgramAlarm
from nckemu.errors import NckAccessDenied, NckConfigError, NckTypeInconsistent
from nckemu.protocol.addresses import NckAddress, NckArea, NckType

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.nck.model")

SNAPSHOT_FORMAT = "nckemu-retained"
SNAPSHOT_VERSION = 1


def check_sources(specs: Sequence[VariableSpec], source: str) -> None:
    """Every computed variable names a registered value source (and a writable one, if writable)."""
    for spec in specs:
        if spec.source is None:
            continue
        bound = SOURCES.get(spec.source)
        if bound is None:
            raise NckConfigError(f"{spec.name}: unknown value source {spec.source!r} (known: "
                                 f"{', '.join(sorted(SOURCES))})", path=source, field="source")
        if (spec.columns > 1) != bound.by_column:
            raise NckConfigError(f"{spec.name}: value source {spec.source!r} "
                                 f"{'takes' if bound.by_column else 'does not take'} the column, but the "
                                 f"variable has {spec.columns} column(s)", path=source, field="columns")
        if not spec.read_only and not bound.writable:
            raise NckConfigError(f"{spec.name}: value source {spec.source!r} cannot be written, but "
                                 f"write_level is {spec.write_level}", path=source, field="write_level")


class NckModel:
    """The NCK of one machine."""

    def __init__(self, machine: Machine, clock: Clock, specs: Sequence[VariableSpec] | None = None) -> None:
        self.machine = machine
        self.clock = clock
        if specs is None:
            specs = machine.variables or load_table()
        specs = tuple(specs)
        check_sources(specs, machine.source)
        self.drives = Drives(machine)
        self.store = VariableStore(specs, self._units, machine.settings.limit_violation_return_code)
        self.store.apply_initial(machine.initial, self._finder(specs), machine.source)
        self.store.activate_all()
        self.axes = Axes(machine, before_change=lambda axis: self.compensation.advance(axis))
        self.sensors = Sensors(machine, clock)
        self.compensation = Compensation(machine, clock, self.store, self.axes)
        self.programs = Programs()
        self.alarm_list = Alarms(clock)
        # $A_IN/$A_OUT and the PLC-NCK data area ($A_DBB ...) programs use; the machine file's PLC answers
        self.nck_io = NckIo(machine.nck_io)
        self.programs.definitions.on_checked = self._definition_checked
        self._r_value_files(machine)
        spindles = sum(axis.spindle for axis in machine.axes)
        # The channels' runs work on the whole NCK (programs, axes, alarms, tools, frames, store), read
        # when a program runs: the tools and frames below come before any.
        self.channels = {number: Channel(number, clock, spindles if number == 1 else 0, self, self._start_run)
                         for number in range(1, machine.channels + 1)}
        self.tools = Tools(machine)
        self.frames = Frames(machine, machine.channels)
        if machine.tool_settings.active_t:
            self.select_tool(machine.tool_settings.active_t, machine.tool_settings.active_d)
        self._power_on_hooks: list[Callable[[], None]] = []
        # Told of every accepted write (after it landed): one write can move other variables (a
        # compensation value moves the axis' positions), so listeners get the address only as a hint.
        self.write_listeners: list[Callable[[NckAddress], None]] = []

    def _start_run(self, channel: Channel, path: str, text: str, start_s: float) -> ProgramRun:
        """A channel's run of a program, on this NCK."""
        return ProgramRun(channel, self, path, text, start_s)

    def _r_value_files(self, machine: Machine) -> None:
        """An R value file (NAME.RPA) written to the NCK sets channel 1's R parameters."""
        try:
            r_spec, r_offset, count = r_parameter_lines(self.store, machine)
        except KeyError:
            return
        self.programs.r_parameters = (
            count, lambda index, value: self.store.write_lines(r_spec, 1, index + r_offset, [value]))

    def _definition_checked(self, path: str, alarm: ProgramAlarm | None) -> None:
        """A definition file refused stays on the alarm list (with its file and line) until a good
        version of that file is activated, as the control reports a failed activation."""
        prefix = f"definition file {path} refused: "
        for text in [text for text in self.alarm_list.active if text.startswith(prefix)]:
            self.alarm_list.clear(text)
        if alarm is not None:
            self.alarm_list.raise_alarm(prefix + str(alarm), alarm.number, (alarm.program, str(alarm.line)))

    @staticmethod
    def _finder(specs: Sequence[VariableSpec]) -> Callable[[str], VariableSpec | None]:
        """By Siemens number or name in this machine's table (as ``find_by_name`` in the built-in one)."""
        index: dict[str, VariableSpec] = {}
        for spec in specs:
            index.setdefault(spec.number.upper(), spec)
            index.setdefault(spec.name.upper(), spec)
        return lambda name: index.get(name.upper())

    def _units(self, spec: VariableSpec) -> list[int]:
        units: list[int] = []
        for area in spec.areas:
            if area == NckArea.A:
                units.extend(axis.number for axis in self.machine.axes)
            elif area == NckArea.C:
                units.extend(range(1, self.machine.channels + 1))
            elif area == NckArea.V:
                units.extend(self.drives.units(spec.module))
            else:
                units.append(1)
        return units

    @property
    def alarms(self) -> list[str]:
        return self.alarm_list.active

    def add_power_on_hook(self, callback: Callable[[], None]) -> None:
        self._power_on_hooks.append(callback)

    # ------------------------------------------------------------------ NckDatastore
    def variable_type(self, address: NckAddress) -> tuple[NckType, int | None]:
        spec, _unit = self.store.resolve(address)
        return spec.nck_type, spec.string_length

    def read_typed(self, address: NckAddress, ctx: AccessContext
                   ) -> tuple[NckType, int | None, list[object]]:
        """Type, string length and values in one lookup (the server's hot path)."""
        spec, _unit = self.store.resolve(address)
        return spec.nck_type, spec.string_length, self.read(address, ctx)

    def read(self, address: NckAddress, ctx: AccessContext) -> list[object]:
        spec, unit = self.store.resolve(address)
        if not ctx.may(spec.read_level):
            raise NckAccessDenied(f"{spec.number} needs access level {spec.read_level}")
        if spec.source is not None:
            return SOURCES[spec.source].read_lines(self, unit, address.column, address.line, address.line_count)
        return self.store.read_lines(spec, unit, address.line, address.line_count)

    def write(self, address: NckAddress, values: Sequence[object], ctx: AccessContext) -> bool:
        """Write typed values; True when retained data changed (the caller persists before answering)."""
        spec, unit = self.store.resolve(address)
        if spec.read_only:
            raise NckAccessDenied(f"{spec.number} {spec.name} is read only")
        if not ctx.may(spec.write_level):
            raise NckAccessDenied(f"{spec.number} {spec.name} needs access level {spec.write_level}, "
                                  f"the connection has {ctx.level}")
        if len(values) != address.line_count:
            raise NckTypeInconsistent(f"{len(values)} values for {address.line_count} lines")
        checked = [self.store.checked_value(spec, value) for value in values]
        if spec.source is not None:
            bound = SOURCES[spec.source]
            if not bound.writable:
                raise NckAccessDenied(f"{spec.name} is read only")
            bound.write_lines(self, unit, address.column, address.line, checked)
            self._tell_written(address)
            return False
        self.compensation.advance_all()
        self.store.write_lines(spec, unit, address.line, checked)
        self._tell_written(address)
        return spec.retained

    def _tell_written(self, address: NckAddress) -> None:
        for listener in self.write_listeners:
            listener(address)

    def pi_service(self, service: str, arguments: Sequence[str], ctx: AccessContext) -> None:
        pi_services.run_service(self, service, arguments, ctx)

    def activate_new_config(self) -> list[str]:
        """PI _N_CONFIG: machine data with effectiveness "new_conf" take effect (as at power-on, but
        nothing else of a power-on happens); the names activated."""
        self.compensation.advance_all()
        return self.store.activate("new_conf")

    def power_on(self) -> None:
        """Power-on: new machine data take effect, LEC activates, 840C TC data are erased."""
        self.compensation.advance_all()
        self.store.activate_all()
        self.compensation.power_on()
        for hook in self._power_on_hooks:
            hook()
        log.info("NCK power-on")

    # ------------------------------------------------------------------ machine state (for tests, PLC)
    def set_axis_position(self, axis: int, position_mm: float) -> None:
        self.axes.set_position(axis, position_mm)

    def axis_position_mm(self, axis: int) -> float:
        return self.axes.position_mm(axis)

    def set_referenced(self, axis: int, referenced: bool) -> None:
        self.axes.set_referenced(axis, referenced)

    def sensor_temperature_C(self, name: str) -> float:
        return self.sensors.temperature_C(name)

    def sensor_temperature_reader(self, name: str) -> Callable[[], float]:
        return self.sensors.temperature_reader(name)

    def set_sensor_temperature(self, name: str, temperature_C: float) -> None:
        self.sensors.set_temperature(name, temperature_C)

    def set_spindle_speed(self, spindle: int, rpm: float | None, channel: int = 1) -> None:
        """The measured actual speed of a channel's spindle (actSpeed); None: the commanded one again."""
        self.channels[channel].set_measured_speed(spindle, rpm)

    def set_drive_load(self, drive: int, load_pct: float | None) -> None:
        """A drive's load (torque utilization, %) from outside; None: back to the model's own."""
        self.drives.set_load(drive, load_pct)

    def select_tool(self, t_number: int, d_number: int, channel: int = 1) -> None:
        """A tool change (T, M6) and offset selection (D) in a channel: actTNumber, actDNumber,
        actToolIdent and the active lengths and radius follow. T0 / D0: no tool, no offset."""
        if t_number and t_number not in self.tools.edges:
            raise NckConfigError(f"no tool T{t_number}", field="t_number")
        if d_number and not self.tools.has_edge(t_number, d_number):
            raise NckConfigError(f"T{t_number} has no cutting edge D{d_number}", field="d_number")
        self.channels[channel].set_tool(t_number, self.tools.idents.get(t_number, ""), d_number)

    def select_frame(self, index: int, channel: int = 1) -> None:
        """G500 (0), G54 (1), G55 (2) ...: the settable frame the channel's work position uses."""
        self.frames.select(channel, index)

    def work_position_mm(self, axis: int, channel: int = 1) -> float:
        """The actual position in the work coordinate system: machine position less the active work
        offset's translation, through the frame the running program has programmed on it."""
        return self.frames.work_position_mm(channel, axis, self.actual_position_mm)

    def add_program(self, path: str) -> None:
        self.programs.add(path)

    # ------------------------------------------------------------------ compensation
    def tc_target_mm(self, axis: int) -> float:
        return self.compensation.tc_target_mm(axis)

    def tc_max_step_mm(self, axis: int) -> float:
        return self.compensation.tc_max_step_mm(axis)

    def tc_value_mm(self, axis: int) -> float:
        return self.compensation.tc_value_mm(axis)

    def lec_value_mm(self, axis: int) -> float:
        return self.compensation.lec_value_mm(axis)

    def compensation_mm(self, axis: int) -> float:
        return self.compensation.total_mm(axis)

    def actual_position_mm(self, axis: int) -> float:
        """Where the axis really is: a positive compensation moves it negative (sign is a setting)."""
        return self.axes.positions_mm[axis] + self.machine.settings.compensation_sign * self.compensation_mm(axis)

    def apply_840c_tc(self, axis: int, k_tcabs_mm: float, tan_beta: float, p0_mm: float,
                      position_independent: bool, position_dependent: bool) -> None:
        self.compensation.apply_840c_tc(
            axis, Tc840c(k_tcabs_mm, tan_beta, p0_mm, position_independent, position_dependent))

    def tc_840c(self, axis: int) -> Tc840c | None:
        return self.compensation.tc_840c(axis)

    def load_leadscrew_program(self, text: str, source: str = "<string>") -> list[LeadscrewTable]:
        return self.compensation.load_leadscrew_program(text, source)

    # ------------------------------------------------------------------ retained data
    def retained_snapshot(self) -> dict[str, Any]:
        leadscrew = [
            {"axis": t.axis, "encoder": t.encoder, "values_mm": list(t.values_mm), "step_mm": t.step_mm,
             "min_mm": t.min_mm, "max_mm": t.max_mm, "modulo": t.modulo}
            for t in self.compensation.lec_loaded.values()
        ]
        return {"format": SNAPSHOT_FORMAT, "version": SNAPSHOT_VERSION, "values": self.store.retained_values(),
                "leadscrew": leadscrew, "programs": self.programs.snapshot()}

    def restore_retained(self, snapshot: dict[str, Any]) -> None:
        """Retained values as after a restart (so they are active, as after power-on)."""
        if snapshot.get("format") != SNAPSHOT_FORMAT or snapshot.get("version") != SNAPSHOT_VERSION:
            raise NckConfigError("not an nckemu retained-state snapshot of version 1", field="format")
        try:
            self.store.restore_values(snapshot["values"])
            tables = [
                LeadscrewTable(int(row["axis"]), int(row["encoder"]), tuple(float(v) for v in row["values_mm"]),
                               float(row["step_mm"]), float(row["min_mm"]), float(row["max_mm"]),
                               bool(row["modulo"]))
                for row in snapshot.get("leadscrew", [])
            ]
            if "programs" in snapshot:  # older snapshots kept no programs
                self.programs.restore(snapshot["programs"])
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise NckConfigError(f"damaged retained-state snapshot: {exc!r}") from None
        self.compensation.lec_loaded.clear()
        self.compensation.set_loaded(tables)
        self.store.activate_all()
        self.compensation.activate_leadscrew()
