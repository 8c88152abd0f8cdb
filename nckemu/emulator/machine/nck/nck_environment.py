"""The interpreter's view of the NCK while a program runs on a channel: R parameters (the ones the NCK
serves), machine positions, work offsets and frames, tool lengths and radii, system variables (part
counters, machine and setting data, the clock, the NCK's I/O) and where a called subprogram is found.

:class:`NckEnvironment` is one of the three parts of a program run: program_run.py consumes the
interpreter's events, run_geometry.py moves the channel's axes, and this answers the
interpreter's questions. A part counter a program writes goes through the channel (``set_figure``).
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime
from typing import TYPE_CHECKING

from nckemu.emulator.machine.nck import nck_io
from nckemu.emulator.machine.nck.programs import program_text
from nckemu.emulator.machine.nck.run_geometry import channel_axes, path_axis_names
from nckemu.emulator.machine.program.environment import ProgramEnvironment, UndefinedName
from nckemu.emulator.machine.program.motions import ALARM_NAME_NOT_DEFINED, ProgramAlarm
from nckemu.errors import NckError, NckNoSuchFile, NckPiBadArguments

if TYPE_CHECKING:
    from nckemu.catalogue.table import VariableSpec
    from nckemu.emulator.machine.machine_file import Machine
    from nckemu.emulator.machine.nck.channel import Channel
    from nckemu.emulator.machine.nck.parts import NckParts
    from nckemu.emulator.machine.nck.store import VariableStore

# Where a called subprogram is looked for after the caller's own directory (programs.md 7).
SEARCH_DIRECTORIES = ("/_N_SPF_DIR", "/_N_CUS_DIR", "/_N_CMA_DIR", "/_N_CST_DIR", "/_N_MPF_DIR")
# Machine data ($MN_ NCK, $MC_ channel, $MA_ axis) and setting data ($SN_, $SC_, $SA_) a program
# reads by their catalogue name; writing machine data is the control's "data write-protected".
DATA_PREFIXES = frozenset({"$MN_", "$MC_", "$MA_", "$SN_", "$SC_", "$SA_"})
ALARM_WRITE_PROTECTED = 17070  # UNCONFIRMED number ("data write-protected")
# The NCK's date and time ($A_YEAR ... $A_MSECOND), local time of the emulator's clock.
CLOCK_VARIABLES = frozenset({"$A_YEAR", "$A_MONTH", "$A_DAY", "$A_HOUR", "$A_MINUTE", "$A_SECOND",
                             "$A_MSECOND"})
# The part counters a program reads and writes: system variable -> the channel state's field.
PART_COUNTERS = {"$AC_ACTUAL_PARTS": "actual_parts", "$AC_TOTAL_PARTS": "total_parts",
                 "$AC_REQUIRED_PARTS": "required_parts", "$AC_SPECIAL_PARTS": "specified_parts"}


def r_parameter_lines(store: VariableStore, machine: Machine) -> tuple[VariableSpec, int, int]:
    """R's catalogue entry, the line R0 is on (the machine's r_parameter_line_offset) and how many R
    parameters a program has (raises KeyError when the catalogue has no R)."""
    spec = store.spec("R")
    offset = machine.settings.r_parameter_line_offset
    return spec, offset, spec.lines - offset + 1


def _clock_value(key: str, now_s: float) -> int:
    moment = datetime.fromtimestamp(now_s) if now_s > 1.0e8 else datetime.now()
    if key == "$A_MSECOND":
        return moment.microsecond // 1000
    return int(getattr(moment, key[3:].lower()))



class NckEnvironment(ProgramEnvironment):
    """The interpreter's view of the NCK: the channel's axes, the NCK's R parameters and state."""

    def __init__(self, channel: Channel, parts: NckParts, block_time_s: Callable[[], float],
                 now_s: Callable[[], float] | None = None) -> None:
        self._channel = channel
        self._parts = parts
        self._block_time_s = block_time_s   # $AC_TIME: the time since the current block began (the run's)
        # the run's time: the PLC's answers fall due on it (nck/nck_io.py)
        self._now_s = now_s or parts.clock.now_s
        self._axes = channel_axes(parts)
        super().__init__(axes=path_axis_names(parts, self._axes), r_parameters=self._r_spec_lines())
        self.reset_inch = parts.machine.program.inch_basic_system  # MD10240 as the machine file has it
        self.repeated_g_group = parts.machine.program.repeated_g_group

    def _r_spec_lines(self) -> int:
        # R is read and written in nearly every block of a computed contour: its entry and line offset
        # are looked up once a run (the table and the machine file do not change while it runs)
        self._r_spec, self._r_offset, count = r_parameter_lines(self._parts.store, self._parts.machine)
        return count

    def _r_line(self, index: int) -> int:
        line = index + self._r_offset
        if not 1 <= line <= self._r_spec.lines or index < 0:
            raise UndefinedName(f"R{index}")
        return line

    def r_parameter(self, index: int) -> float:
        return float(self._parts.store.read_lines(self._r_spec, self._channel.number, self._r_line(index), 1)[0])

    def set_r_parameter(self, index: int, value: float) -> None:
        self._parts.store.write_lines(self._r_spec, self._channel.number, self._r_line(index), [float(value)])

    def machine_position_mm(self, axis: str) -> float:
        number = self._axes.get(axis.upper())
        if number is None:
            raise UndefinedName(axis)
        return self._parts.axes.positions_mm[number]

    def work_offset_mm(self, frame: str, axis: str) -> float:
        from nckemu.emulator.machine.machine_file import SETTABLE_FRAMES

        number = self._axes.get(axis.upper())
        index = SETTABLE_FRAMES.get(frame.upper())
        frames = self._parts.frames
        if number is None or index is None or index >= frames.count:
            return 0.0
        return frames.shifts_mm[self._channel.number][index].get(number, 0.0)

    def set_work_offset_mm(self, frame: str, axis: str, value_mm: float) -> None:
        from nckemu.emulator.machine.machine_file import SETTABLE_FRAMES

        number = self._axes.get(axis.upper())
        index = SETTABLE_FRAMES.get(frame.upper())
        frames = self._parts.frames
        if number is None or index is None or index >= frames.count:
            raise UndefinedName(frame)
        frames.shifts_mm[self._channel.number][index][number] = float(value_mm)

    def select_settable_frame(self, frame: str) -> None:
        from nckemu.emulator.machine.machine_file import SETTABLE_FRAMES

        index = SETTABLE_FRAMES.get(frame.upper())
        if index is not None and index < self._parts.frames.count:
            self._parts.frames.select(self._channel.number, index)

    def set_programmable_frame(self, frame: object) -> None:
        from nckemu.emulator.machine.frame_math import Frame

        if isinstance(frame, Frame):
            self._parts.frames.set_programmable(self._channel.number, frame)

    def tool_length_mm(self, tool: int | str | None, edge: int | None) -> float:
        number = self.tool_number(tool)
        if not number or not edge:
            return 0.0
        try:
            return self._parts.tools.active_length_mm(number, edge, 1)
        except NckError:
            return 0.0

    def tool_radius_mm(self, tool: int | str | None, edge: int | None) -> float:
        number = self.tool_number(tool)
        if not number or not edge:
            return 0.0
        try:
            return self._parts.tools.active_radius_mm(number, edge)
        except NckError:
            return 0.0

    def tool_number(self, tool: int | str | None) -> int:
        if isinstance(tool, int):
            return tool
        if isinstance(tool, str):
            for number, ident in self._parts.tools.idents.items():
                if ident.upper() == tool.upper():
                    return number
        return 0

    def system_variable(self, name: str, indices: tuple[object, ...] = ()) -> object:
        key = name.upper()
        state = self._channel.state
        if key == "$AC_TIME":  # time since the start of the block (s)
            return max(0.0, self._block_time_s())
        if key in ("$AA_IM", "$AA_MM") and len(indices) == 1 and str(indices[0]).upper() in self._axes:
            # the actual machine position, with the compensation ($P_EP, $AA_IW: the interpreter's own)
            return self._parts.actual_position_mm(self._axes[str(indices[0]).upper()])
        if key in PART_COUNTERS:
            return self._channel.figure(PART_COUNTERS[key])
        if key == "$AC_PROG":
            return self._channel.ac_prog
        if key == "$P_TOOLNO":
            return state.t_number
        if key == "$P_TOOL":
            return state.d_number
        if key[:4] in DATA_PREFIXES:
            spec, unit, line = self._data_address(key, indices)
            return self._parts.store.active_value(spec.name, unit, line)
        if key in CLOCK_VARIABLES:
            return _clock_value(key, self._parts.clock.now_s())
        if key in nck_io.READABLE:
            io = self._parts.nck_io
            io.settle(self._now_s())
            return io.read(key, self._io_index(key, indices))
        raise UndefinedName(name)

    def _io_index(self, key: str, indices: tuple[object, ...]) -> int:
        if len(indices) != 1 or not isinstance(indices[0], int | float):
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{key}[n]: one number as the index")
        return int(indices[0])

    def set_system_variable(self, name: str, indices: tuple[object, ...], value: object) -> None:
        key = name.upper()
        if key[:4] in DATA_PREFIXES:
            spec, unit, line = self._data_address(key, indices)
            if key[1] == "M":  # machine data: set up by the machine maker, not by a part program
                raise ProgramAlarm(ALARM_WRITE_PROTECTED, f"{name}: machine data {spec.number} is write-protected "
                                                          "for a part program (the machine file sets it)")
            store = self._parts.store
            store.write_lines(spec, unit, line, [store.checked_value(spec, value)])
            return
        if key in nck_io.WRITABLE:
            self._parts.nck_io.write(key, self._io_index(key, indices), float(value),  # type: ignore[arg-type]
                                     self._now_s())
            return
        attribute = PART_COUNTERS.get(key)
        if attribute is None:
            raise UndefinedName(name)
        self._channel.set_figure(attribute, float(value))  # type: ignore[arg-type]

    def _data_address(self, key: str, indices: tuple[object, ...]) -> tuple[VariableSpec, int, int]:
        """The catalogue entry, unit and line of ``$MA_MAX_AX_VELO[X]``, ``$MN_..[2]``, ``$SA_..[AX4]``:
        axis data take the axis (its name, AXn, or its number) as the last index, an array its element
        (from 0) first; channel data are this channel's."""
        try:
            spec = self._parts.store.spec(key[4:])
        except KeyError:
            raise UndefinedName(key) from None
        if not spec.number.startswith(f"{key[1]}D"):  # $M.. is machine data (MD), $S.. setting data (SD)
            raise UndefinedName(key)
        area = key[2]
        rest = list(indices)
        if area == "A":
            if not rest:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{key}: axis data need the axis ({key}[X])")
            unit = self._axis_unit(rest.pop())
        else:
            unit = self._channel.number if area == "C" else 1
        line = 1
        if rest:
            element = rest[0]
            if not isinstance(element, int | float) or not 0 <= int(element) < spec.lines:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{key}[{element}]: index outside 0..{spec.lines - 1}")
            line = int(element) + 1
        if (spec.name, unit) not in self._parts.store.active:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{key}: not defined for unit {unit}")
        return spec, unit, line

    def _axis_unit(self, axis: object) -> int:
        if isinstance(axis, int | float):
            return int(axis)
        text = str(axis).upper()
        if text in self._axes:
            return self._axes[text]
        if text.startswith("AX") and text[2:].isdigit():
            return int(text[2:])
        raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"axis {axis} not defined")

    def global_variables(self) -> dict:
        return self._parts.programs.definitions.variables()

    def macros(self) -> dict[str, str]:
        return self._parts.programs.definitions.macros()

    def find_program(self, name: str, caller: str) -> tuple[str, str] | None:
        from nckemu.catalogue.program_names import program_path

        programs = self._parts.programs
        stem = name.strip().upper()
        candidates: list[str] = []
        if "/" in stem or stem.endswith((".SPF", ".MPF")) or stem.startswith("_N_"):
            try:
                candidates.append(program_path(stem, default_type="SPF"))
            except NckPiBadArguments:
                return None
        else:
            if not stem.replace("_", "A").isalnum():
                return None
            caller_dir = caller.rsplit("/", 1)[0] if "/" in caller else ""
            for directory in (caller_dir, *SEARCH_DIRECTORIES):
                if not directory:
                    continue
                for kind in ("SPF", "MPF"):
                    candidates.append(f"{directory}/_N_{stem}_{kind}")
        for path in dict.fromkeys(candidates):
            if programs.exists(path):
                try:
                    return path, program_text(programs.read(path))
                except NckNoSuchFile:
                    continue
        return None
