"""A machine from TOML: axes, sensors, tools, work offsets, PLC data blocks, initial data and settings
for open facts.

One machine per file; the built-in default machine is ``machines/default.toml`` in this package.
Every problem is reported as an ``NckConfigError`` naming the file and the field.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any

from nckemu.catalogue.edges import STANDARD_EDGE_PARAMS
from nckemu.catalogue.table import VariableSpec, load_table, machine_table, row_lines
from nckemu.emulator.machine.io_points import NckIoSettings, parse_nck_io
from nckemu.errors import NckConfigError
from nckemu.heat_response import SENSOR, HeatTerm, parse_terms
from nckemu.textfile import read_text


@dataclass(frozen=True)
class Axis:
    number: int
    name: str
    travel_min_mm: float = -1.0e6
    travel_max_mm: float = 1.0e6
    rotary: bool = False
    spindle: bool = False
    referenced: bool = True
    position_mm: float = 0.0
    # Which component (1..3) of SD42960 TOOL_TEMP_COMP acts on this axis when MD32750 bit 2 is set;
    # None: none. Unconfirmed: taken as the tool length components L1/L2/L3 under G17 (Z, Y, X).
    tool_temp_comp_component: int | None = None
    # The axis letter of this axis in a recording (pos_<letter>_mm, err_<letter>_um, sim_<letter>_um);
    # `recording = "Z"` in the machine file, by default the first letter of the name ("" for none).
    recording: str = ""
    # The thermal error a running program's heat makes on this axis: µm per K that each named sensor has
    # risen by that heat (emulator/machine/heat.py; `program run --out` writes it as err_<axis>_um).
    thermal_um_per_K: dict[str, float] = field(default_factory=dict)


# The default allocation of SD42960's components to geometry axes, by the first letter of the axis name.
TOOL_TEMP_COMP_COMPONENTS = {"Z": 1, "Y": 2, "X": 3}
# MD20060 AXCONF_GEOAX_NAME_TAB, as SINUMERIK delivers it: the channel's geometry axes (the workpiece
# view of the axes, nck/geometric_axes.py, and the path the planner plans, program/planner.py).
GEOMETRY_AXIS_NAMES = ("X", "Y", "Z")


# The bytes of each of the PLC's input, output and flag areas (plc/memory.py): a sensor's ``plc_input`` word
# lies in the input area. Here, with the machine's shape, so that the machine file does not import the PLC.
PLC_AREA_BYTES = 2048


@dataclass(frozen=True)
class Sensor:
    name: str
    temperature_C: float = 20.0
    plc_input: str | None = None
    raw_offset: float = 0.0
    raw_per_C: float = 276.48
    # (t_s, temperature_C) points; linear in between, end values held.
    profile: tuple[tuple[float, float], ...] = ()
    # The heat a running machine makes (emulator/machine/heat.py): a first-order response with time
    # constant ``heat_time_constant_s`` towards ``heat_spindle_K_per_krpm`` per 1000 rpm of the spindle plus
    # ``heat_axes_K_per_m_min`` per m/min of path speed, added to the value above (assumed defaults).
    heat_spindle_K_per_krpm: float = 1.0
    heat_axes_K_per_m_min: float = 0.2
    heat_time_constant_s: float = 600.0
    # A fitted response (``[[sensor.response]]``, nckemu/heat_response.py; `nckemu machine fit` writes
    # it): when present it replaces the three keys above for this sensor.
    response: tuple[HeatTerm, ...] = ()

    def raw_value(self, temperature_C: float) -> int:
        raw = round(self.raw_offset + self.raw_per_C * temperature_C)
        return max(-32768, min(32767, raw))


# The cutting edge parameters a machine file may name, by parameter number (the line within one edge of
# module TO): 1 tool type, 2 cutting edge position, 3..5 geometry lengths 1..3, 6 radius, 12..14 wear of
# lengths 1..3, 15 wear of the radius (the order of an 840D sl 4.7 edge in OPCTD; single source). The
# other parameters of an edge exist and read 0.
EDGE_PARAMETERS: dict[str, int] = {
    "type": 1, "edge_position": 2, "length1_mm": 3, "length2_mm": 4, "length3_mm": 5, "radius_mm": 6,
    "wear_length1_mm": 12, "wear_length2_mm": 13, "wear_length3_mm": 14, "wear_radius_mm": 15,
    # Beyond 25 (a machine with more cutting edge parameters): LSC reads line 26 of an edge as its H number
    # and line 34 as its number of teeth (Siemens' $TC_DPH / $TC_DPNT by our reading; docs/assumptions.md).
    "h_number": 26, "teeth": 34,
}
# numCuttEdgeParams: STANDARD_EDGE_PARAMS by default (catalogue/edges.py); LSC reads 35 lines of one
# 840D sl edge at once, so a machine may configure up to that.
MAX_EDGE_PARAMS = 35
# D numbers per tool: MD18105's default maximum is 9 (Siemens W1); T numbers 1..32000 (A2).
MAX_EDGES_PER_TOOL = 9
MAX_T_NUMBER = 32000
TOOL_IDENT_BYTES = 32   # actToolIdent's field length (NCVS)

# Settable frames by name and index (the line block of module FU): G500 is frame 0, G54..G57 are 1..4,
# G505..G599 are 5..99 (index order inferred from the G-code order; docs/assumptions.md).
SETTABLE_FRAMES: dict[str, int] = {"G500": 0, "G54": 1, "G55": 2, "G56": 3, "G57": 4,
                                   **{f"G{code}": code - 500 for code in range(505, 600)}}
DEFAULT_SETTABLE_FRAMES = 5   # G500, G54..G57


@dataclass(frozen=True)
class Tool:
    """One tool of the TO unit: its T number, its name and its cutting edges (D1, D2, ...), each the
    values of parameters 1..n (n = the machine's ``cutting_edge_params``)."""

    number: int
    ident: str = ""
    edges: tuple[tuple[float, ...], ...] = ()


# actOriToolLength1..3 (S columns 113..115): the tool length along geometry axes X, Y, Z; which length
# component (1..3) lies along each. G17 with a milling tool: L3 along X, L2 along Y, L1 along Z (W1); a
# lathe with turning tools under G18: L1 along X, L2 along Z (write [1, 3, 2]). Inferred: no orientation.
DEFAULT_ORI_LENGTH_COMPONENTS = (3, 2, 1)


@dataclass(frozen=True)
class ToolSettings:
    cutting_edge_params: int = STANDARD_EDGE_PARAMS
    # The tool and cutting edge active in channel 1 at start (actTNumber, actDNumber); 0: none.
    active_t: int = 0
    active_d: int = 0
    ori_length_components: tuple[int, int, int] = DEFAULT_ORI_LENGTH_COMPONENTS


@dataclass(frozen=True)
class WorkOffsets:
    """The settable frames of channel 1 (translations only): frame index -> machine axis -> shift."""

    active: int = 0
    count: int = DEFAULT_SETTABLE_FRAMES
    shifts_mm: dict[int, dict[int, float]] = field(default_factory=dict)


@dataclass(frozen=True)
class Drive:
    """A SINAMICS drive the NCK reaches in its drive area V: unit = ``number``. Its motor module (drive
    object 0x82) drives machine axis ``axis``; ratings set what current and power a load means."""

    number: int
    axis: int | None = None
    # The [[sensor]] whose temperature the motor's r0035 reports (a recording's temp_<sensor>_C on a
    # living machine); None: ambient plus a steady rise with the load (``DriveSettings``).
    motor_sensor: str | None = None
    rated_power_kW: float = 1.5
    rated_current_A: float = 4.0
    rated_speed_rpm: float = 3000.0
    # Id of an induction motor (enters r0027); 0 for a synchronous servo motor.
    magnetizing_current_A: float = 0.0
    # Load (torque utilization, %) at standstill, and what turning at rated speed adds (friction and
    # windage; no cutting is emulated). ``NckModel.set_drive_load`` overrides both.
    standstill_load_pct: float = 2.0
    speed_load_pct: float = 10.0


# Defaults of a drive a machine file does not list, by what its axis is (inferred, not from a source):
# a 1FK7-size feed motor and a 1PH8-size spindle motor.
FEED_DRIVE = {"rated_power_kW": 1.5, "rated_current_A": 4.0, "rated_speed_rpm": 3000.0,
              "magnetizing_current_A": 0.0, "standstill_load_pct": 2.0, "speed_load_pct": 10.0}
SPINDLE_DRIVE = {"rated_power_kW": 7.5, "rated_current_A": 20.0, "rated_speed_rpm": 8000.0,
                 "magnetizing_current_A": 7.0, "standstill_load_pct": 0.0, "speed_load_pct": 15.0}


@dataclass(frozen=True)
class DriveSettings:
    """Values of the drive line-up as a whole ([drives]); docs/assumptions.md says where each comes from."""

    # r0026 DC link voltage: an active line module on 3 AC 400 V regulates 600 V (inferred).
    dc_link_V: float = 600.0
    # Ambient of motors and power units, and their steady rises at rated load (inferred).
    ambient_C: float = 25.0
    motor_rise_K: float = 60.0
    power_unit_rise_K: float = 30.0
    # Motor module and infeed efficiencies (r0032 electrical power of a drive, of the infeed).
    efficiency: float = 0.9
    infeed_efficiency: float = 0.95
    # What a temperature index without a sensor reads (r0037).
    unmeasured_C: float = -200.0
    # Transport size of read answers from the drive areas: 0x09 (octet string) as every NCK answer, or
    # 0x07 (REAL), which a commented-out decoder of LSC tested for (no capture of a real answer found).
    answer_transport_size: int = 0x09


@dataclass(frozen=True)
class ProgramSettings:
    """How the channel runs part programs ([program]; docs/programs.md says where each comes from)."""

    # The channel's cycle on the server's clock when no living machine sets one (simulated seconds).
    cycle_s: float = 0.1
    # Blocks the channel executes at most per cycle (an endless loop never starves the faces).
    max_blocks_per_cycle: int = 5000
    # The spindle's acceleration in speed control (rev/s²; MD35200's name is unconfirmed, so a setting).
    spindle_accel_rev_s2: float = 50.0
    # Path motion waits for the spindle to reach its speed (as MD35500 SPIND_ON_SPEED_AT_IPO_START = 1).
    wait_for_spindle: bool = True
    # M1 stops only with "optional stop" selected (SINF optStopActive), as on the control.
    optional_stop: bool = False
    # The alarm NC start raises where the control refuses it (JOG, nothing selected, an alarm pending),
    # and the one a refused mode change raises: 16912 / 16913 are UNCONFIRMED.
    start_refused_alarm: int = 16912
    mode_refused_alarm: int = 16913
    # The alarm a move beyond an axis' travel raises (10720 software limit switch; from memory, unconfirmed).
    travel_alarm: int = 10720
    # The basic system is inch (MD10240 SCALING_SYSTEM_IS_METRIC = 0): G70 after reset, and F in inch/min
    # under G70 and G71 alike (G700/G710 set both); an inch post's program on its own machine.
    inch_basic_system: bool = False
    # Two G functions of one group that does not define the block's syntax (G90 G91): "last_wins" (the
    # last written is active) or "alarm" (12060 "same G group programmed repeatedly"); both UNCONFIRMED.
    repeated_g_group: str = "last_wins"


REPEATED_G_GROUP_CHOICES = ("last_wins", "alarm")


@dataclass(frozen=True)
class Settings:
    compensation_sign: int = -1
    tc_requires_referenced: bool = False
    r_parameter_line_offset: int = 1
    limit_violation_return_code: int = 0x05
    # Userdata error codes (docs/assumptions.md): an SZL ID the PLC lacks, a known SZL ID with an index
    # it lacks, a userdata group or subfunction it does not serve.
    szl_unknown_id_error: int = 0xD401
    szl_unknown_index_error: int = 0xD402
    userdata_not_served_error: int = 0x8104
    # Header error of the ACK to a job function we do not serve (upload, download, ...); C snap7 gives
    # upload/download 0xD241 (protection level), python-snap7 and GH107's 840D sl 0x8104.
    unsupported_function_error: int = 0x8104
    # SZL 0x0131 / 0x0232 index 0 in the layout python-snap7 3.3 reads (no real CPU defines index 0).
    szl_index0_python_snap7: bool = True
    # 840C TC: refuse P0 = 0 with the A flag (the manual only advises against it).
    c840_refuse_p0_at_zero: bool = False
    # Bytes of part-program text the NCK's program store holds; a transfer that would exceed it is
    # refused with "store full". Assumed default (3 MiB; no source gives an NCU's figure).
    program_store_bytes: int = 3 * 1024 * 1024
    # NC program download: the window the NCK announces and after which it pushes "continue
    # download" (inferred from libnodave, which waits after 8 blocks; docs/programs-transfer.md).
    nc_download_window: int = 8


@dataclass(frozen=True)
class Machine:
    name: str
    source: str
    ipo_cycle_s: float = 0.004
    pdu_size_max: int = 960
    max_amq: int = 8
    channels: int = 1
    connection_access_level: int = 7
    passwords: dict[str, int] = field(default_factory=dict)
    settings: Settings = field(default_factory=Settings)
    axes: tuple[Axis, ...] = ()
    sensors: tuple[Sensor, ...] = ()
    data_blocks: dict[int, int] = field(default_factory=dict)
    # {"MD32750": {4: 1}, "SD43900": {4: 0.0}}: variable name -> unit -> value (or list of lines)
    initial: dict[str, dict[int, Any]] = field(default_factory=dict)
    # The NCK variable table with the file's [[var]] rows (added, or overriding built-in rows by name);
    # empty: the built-in catalogue.
    variables: tuple[VariableSpec, ...] = ()
    tools: tuple[Tool, ...] = ()
    tool_settings: ToolSettings = field(default_factory=ToolSettings)
    work_offsets: WorkOffsets = field(default_factory=WorkOffsets)
    # The [opcua] table as written (users and rights of the OPC UA face; checked by emulator/faces/opcua).
    opcua: dict[str, Any] = field(default_factory=dict)
    # SINAMICS drives (area V): the file's [[drive]] rows, else one per machine axis (drive n = axis n).
    drives: tuple[Drive, ...] = ()
    drive_settings: DriveSettings = field(default_factory=DriveSettings)
    program: ProgramSettings = field(default_factory=ProgramSettings)
    # [nck_io]: points that read so from power on, and what the PLC sets when the channel outputs an
    # M function or a program sets an NCK output (io_points.py)
    nck_io: NckIoSettings = field(default_factory=NckIoSettings)

    def tool(self, number: int) -> Tool | None:
        for tool in self.tools:
            if tool.number == number:
                return tool
        return None

    def axis(self, number: int) -> Axis | None:
        for axis in self.axes:
            if axis.number == number:
                return axis
        return None


def _get(table: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str, source: str,
         default: Any = None) -> Any:
    if key not in table:
        if default is None:
            raise NckConfigError("missing", path=source, field=f"{where}{key}")
        return default
    value = table[key]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise NckConfigError(f"expected {getattr(kind, '__name__', kind)}, got {value!r}", path=source,
                             field=f"{where}{key}")
    return value


_KNOWN_KEYS: dict[str, frozenset[str]] = {
    "": frozenset({"name", "ipo_cycle_s", "pdu_size_max", "max_amq", "channels", "connection_access_level",
                   "passwords", "settings", "axis", "sensor", "plc", "initial", "var", "tools", "tool",
                   "work_offsets", "opcua", "drives", "drive", "program", "nck_io"}),
    # every setting the dataclass has (a new setting needs no second list)
    "settings.": frozenset(setting.name for setting in fields(Settings)),
    "axis": frozenset({"number", "name", "travel_mm", "rotary", "spindle", "referenced", "position_mm",
                       "tool_temp_comp_component", "recording", "thermal_um_per_K"}),
    "sensor": frozenset({"name", "temperature_C", "plc_input", "raw_offset", "raw_per_C", "profile",
                         "heat_spindle_K_per_krpm", "heat_axes_K_per_m_min", "heat_time_constant_s",
                         "response"}),
    "program.": frozenset(setting.name for setting in fields(ProgramSettings)),
    "plc.": frozenset({"data_blocks"}),
    "tools.": frozenset({"cutting_edge_params", "active_t", "active_d", "ori_length_components"}),
    "tool": frozenset({"number", "ident", "edges"}),
    "edge": frozenset(EDGE_PARAMETERS),
    "drives.": frozenset(setting.name for setting in fields(DriveSettings)),
    "drive": frozenset(setting.name for setting in fields(Drive)),
}


def _check_keys(table: Any, kind: str, where: str, source: str, line: int | None = None) -> None:
    """A mistyped key would silently fall back to its default: refuse it, naming the known ones."""
    if not isinstance(table, dict):
        raise NckConfigError("expected a table", path=source, line=line, field=where.rstrip(".") or "(top level)")
    unknown = sorted(set(table) - _KNOWN_KEYS[kind])
    if unknown:
        raise NckConfigError(f"unknown key (known: {', '.join(sorted(_KNOWN_KEYS[kind]))})", path=source,
                             line=line, field=f"{where}{unknown[0]}")


def _header_line(text: str, header: str) -> int | None:
    """The line of a table header (``[work_offsets]``), so an error in the table can name it."""
    lines = row_lines(text, header)
    return lines[0] if lines else None


def _whole(value: object, low: int, high: int, what: str, source: str, line: int | None, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise NckConfigError(f"expected {what} {low}..{high}, got {value!r}", path=source, line=line, field=where)
    return value


def _tool(table: Any, index: int, params: int, source: str, line: int | None) -> Tool:
    where = f"tool[{index}]."
    _check_keys(table, "tool", where, source, line)
    if "number" not in table:
        raise NckConfigError("missing (the T number)", path=source, line=line, field=f"{where}number")
    number = _whole(table["number"], 1, MAX_T_NUMBER, "a T number", source, line, f"{where}number")
    ident = table.get("ident", "")
    if not isinstance(ident, str) or len(ident.encode("ascii", "replace")) > TOOL_IDENT_BYTES:
        raise NckConfigError(f"expected a tool name of up to {TOOL_IDENT_BYTES} characters, got {ident!r}",
                             path=source, line=line, field=f"{where}ident")
    edges_raw = table.get("edges", [])
    if not isinstance(edges_raw, list) or len(edges_raw) > MAX_EDGES_PER_TOOL:
        raise NckConfigError(f"expected a list of up to {MAX_EDGES_PER_TOOL} cutting edges (D1, D2, ...)",
                             path=source, line=line, field=f"{where}edges")
    edges: list[tuple[float, ...]] = []
    for number_d, edge in enumerate(edges_raw, 1):
        edge_where = f"{where}edges[{number_d - 1}]."
        _check_keys(edge, "edge", edge_where, source, line)
        values = [0.0] * params
        for key, value in edge.items():
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise NckConfigError(f"expected a number, got {value!r}", path=source, line=line,
                                     field=f"{edge_where}{key}")
            if EDGE_PARAMETERS[key] > params:
                raise NckConfigError(f"{key} is edge parameter {EDGE_PARAMETERS[key]}, but [tools] "
                                     f"cutting_edge_params is {params}", path=source, line=line,
                                     field=f"{edge_where}{key}")
            values[EDGE_PARAMETERS[key] - 1] = float(value)
        edges.append(tuple(values))
    return Tool(number=number, ident=ident, edges=tuple(edges))


def _tools(data: dict[str, Any], text: str, source: str) -> tuple[ToolSettings, tuple[Tool, ...]]:
    settings_table = data.get("tools", {})
    line = _header_line(text, "[tools]")
    _check_keys(settings_table, "tools.", "tools.", source, line)
    params = _whole(settings_table.get("cutting_edge_params", STANDARD_EDGE_PARAMS), STANDARD_EDGE_PARAMS,
                    MAX_EDGE_PARAMS, "a number of cutting edge parameters", source, line, "tools.cutting_edge_params")
    tool_rows = data.get("tool", [])
    if not isinstance(tool_rows, list):
        raise NckConfigError("expected [[tool]] tables", path=source, field="tool")
    tool_lines = row_lines(text, "[[tool]]")
    tools: list[Tool] = []
    for index, row in enumerate(tool_rows):
        row_line = tool_lines[index] if index < len(tool_lines) else None
        tool = _tool(row, index, params, source, row_line)
        if any(other.number == tool.number for other in tools):
            raise NckConfigError(f"T{tool.number} is declared twice", path=source, line=row_line,
                                 field=f"tool[{index}].number")
        tools.append(tool)
    active_t = _whole(settings_table.get("active_t", 0), 0, MAX_T_NUMBER, "a T number (0: none)", source, line,
                      "tools.active_t")
    active_d = _whole(settings_table.get("active_d", 0), 0, MAX_EDGES_PER_TOOL, "a D number (0: none)", source,
                      line, "tools.active_d")
    active = next((tool for tool in tools if tool.number == active_t), None)
    if active_t and active is None:
        raise NckConfigError(f"no [[tool]] with number {active_t}", path=source, line=line, field="tools.active_t")
    if active_d and (active is None or active_d > len(active.edges)):
        edges = 0 if active is None else len(active.edges)
        raise NckConfigError(f"T{active_t} has {edges} cutting edge(s), so no D{active_d}", path=source, line=line,
                             field="tools.active_d")
    components = settings_table.get("ori_length_components", list(DEFAULT_ORI_LENGTH_COMPONENTS))
    if not isinstance(components, list) or sorted(components) != [1, 2, 3]:
        raise NckConfigError("expected the tool length components along X, Y, Z: a list of 1, 2, 3 in some "
                             "order, e.g. [3, 2, 1]", path=source, line=line, field="tools.ori_length_components")
    return ToolSettings(params, active_t, active_d, (components[0], components[1], components[2])), tuple(tools)


def _work_offsets(table: Any, axes: tuple[Axis, ...], text: str, source: str) -> WorkOffsets:
    line = _header_line(text, "[work_offsets]")
    if not isinstance(table, dict):
        raise NckConfigError("expected a table", path=source, line=line, field="work_offsets")
    names = {axis.name.upper(): axis.number for axis in axes}
    active_name = table.get("active", "G500")
    if not isinstance(active_name, str) or active_name.upper() not in SETTABLE_FRAMES:
        raise NckConfigError(f"expected a settable frame G500, G54..G57 or G505..G599, got {active_name!r}",
                             path=source, line=line, field="work_offsets.active")
    shifts: dict[int, dict[int, float]] = {}
    for frame_name, per_axis in table.items():
        if frame_name == "active":
            continue
        if frame_name.upper() not in SETTABLE_FRAMES:
            raise NckConfigError("unknown key (known: active, G500, G54..G57, G505..G599)", path=source,
                                 line=line, field=f"work_offsets.{frame_name}")
        if not isinstance(per_axis, dict):
            raise NckConfigError("expected { <machine axis name> = <shift in mm> }", path=source, line=line,
                                 field=f"work_offsets.{frame_name}")
        frame: dict[int, float] = {}
        for axis_name, value in per_axis.items():
            where = f"work_offsets.{frame_name}.{axis_name}"
            if axis_name.upper() not in names:
                raise NckConfigError(f"no machine axis {axis_name!r} (axes: {', '.join(a.name for a in axes)})",
                                     path=source, line=line, field=where)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise NckConfigError(f"expected a shift in mm, got {value!r}", path=source, line=line, field=where)
            frame[names[axis_name.upper()]] = float(value)
        shifts[SETTABLE_FRAMES[frame_name.upper()]] = frame
    count = max([DEFAULT_SETTABLE_FRAMES, SETTABLE_FRAMES[active_name.upper()] + 1,
                 *(index + 1 for index in shifts)])
    return WorkOffsets(active=SETTABLE_FRAMES[active_name.upper()], count=count, shifts_mm=shifts)


def _axis(table: dict[str, Any], index: int, source: str) -> Axis:
    where = f"axis[{index}]."
    _check_keys(table, "axis", where, source)
    number = _get(table, "number", int, where, source)
    if not 1 <= number <= 31:
        raise NckConfigError("a machine axis number is 1..31 (the NCK unit)", path=source, field=f"{where}number")
    travel = table.get("travel_mm", [-1.0e6, 1.0e6])
    if (not isinstance(travel, list) or len(travel) != 2
            or not all(isinstance(v, int | float) for v in travel) or travel[0] > travel[1]):
        raise NckConfigError("expected [min, max] in mm", path=source, field=f"{where}travel_mm")
    rotary = _get(table, "rotary", bool, where, source, False)
    position = _get(table, "position_mm", float, where, source, 0.0 if travel[0] <= 0.0 <= travel[1]
                    else float(travel[0]))
    name = _get(table, "name", str, where, source)
    spindle = _get(table, "spindle", bool, where, source, False)
    default_component = None if rotary or spindle else TOOL_TEMP_COMP_COMPONENTS.get(name[:1].upper())
    component = table.get("tool_temp_comp_component", default_component)
    if component is not None and (isinstance(component, bool) or component not in (1, 2, 3)):
        raise NckConfigError("expected 1, 2 or 3 (the SD42960 component acting on this axis)", path=source,
                             field=f"{where}tool_temp_comp_component")
    recording = table.get("recording", name[:1].upper() if name[:1].isalpha() else "")
    if not isinstance(recording, str) or (recording and not recording.isidentifier()):
        raise NckConfigError("expected the axis letter of a recording, e.g. \"Z\"", path=source,
                             field=f"{where}recording")
    thermal = table.get("thermal_um_per_K", {})
    if not isinstance(thermal, dict) or not all(isinstance(k, str) and isinstance(v, int | float)
                                                  and not isinstance(v, bool) and math.isfinite(v)
                                                  for k, v in thermal.items()):
        raise NckConfigError("expected { <sensor name> = <µm per K> }", path=source, field=f"{where}thermal_um_per_K")
    return Axis(number=number, name=name, recording=recording,
                thermal_um_per_K={str(k): float(v) for k, v in thermal.items()},
                travel_min_mm=float(travel[0]), travel_max_mm=float(travel[1]), rotary=rotary,
                spindle=spindle, referenced=_get(table, "referenced", bool, where, source, True),
                position_mm=position, tool_temp_comp_component=component)


def _sensor(table: dict[str, Any], index: int, source: str) -> Sensor:
    where = f"sensor[{index}]."
    _check_keys(table, "sensor", where, source)
    profile_raw = table.get("profile", [])
    profile: list[tuple[float, float]] = []
    if not isinstance(profile_raw, list):
        raise NckConfigError("expected a list of [t_s, temperature_C]", path=source, field=f"{where}profile")
    for point in profile_raw:
        if not (isinstance(point, list) and len(point) == 2 and all(isinstance(v, int | float) for v in point)):
            raise NckConfigError(f"bad point {point!r}", path=source, field=f"{where}profile")
        profile.append((float(point[0]), float(point[1])))
    if any(b[0] <= a[0] for a, b in zip(profile, profile[1:], strict=False)):
        raise NckConfigError("times must increase", path=source, field=f"{where}profile")
    plc_input = table.get("plc_input")
    if plc_input is not None and (not isinstance(plc_input, str) or not plc_input.upper().startswith("PIW")
                                  or not plc_input[3:].isdigit()):
        raise NckConfigError("expected 'PIW<byte address>'", path=source, field=f"{where}plc_input")
    if plc_input is not None and int(plc_input[3:]) > PLC_AREA_BYTES - 2:
        raise NckConfigError(f"{plc_input}: the input area has bytes 0..{PLC_AREA_BYTES - 1}, so PIW0..PIW{PLC_AREA_BYTES - 2}",
                             path=source, field=f"{where}plc_input")
    return Sensor(name=_get(table, "name", str, where, source),
                  temperature_C=_get(table, "temperature_C", float, where, source, 20.0),
                  plc_input=plc_input.upper() if plc_input else None,
                  raw_offset=_get(table, "raw_offset", float, where, source, 0.0),
                  raw_per_C=_get(table, "raw_per_C", float, where, source, 276.48),
                  profile=tuple(profile),
                  heat_spindle_K_per_krpm=_positive(table, "heat_spindle_K_per_krpm", 1.0, where, source, None,
                                                    low=-1000.0, high=1000.0),
                  heat_axes_K_per_m_min=_positive(table, "heat_axes_K_per_m_min", 0.2, where, source, None,
                                                  low=-1000.0, high=1000.0),
                  heat_time_constant_s=_positive(table, "heat_time_constant_s", 600.0, where, source, None),
                  response=parse_terms(table.get("response", []), where, source))


def parse_machine(text: str, source: str = "<string>") -> Machine:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise NckConfigError(f"not valid TOML: {exc}", path=source) from None
    _check_keys(data, "", "", source)
    settings_table = data.get("settings", {})
    _check_keys(settings_table, "settings.", "settings.", source)
    settings = Settings(
        compensation_sign=_get(settings_table, "compensation_sign", int, "settings.", source, -1),
        tc_requires_referenced=_get(settings_table, "tc_requires_referenced", bool, "settings.", source, False),
        r_parameter_line_offset=_get(settings_table, "r_parameter_line_offset", int, "settings.", source, 1),
        limit_violation_return_code=_get(settings_table, "limit_violation_return_code", int, "settings.",
                                         source, 0x05),
        szl_unknown_id_error=_get(settings_table, "szl_unknown_id_error", int, "settings.", source, 0xD401),
        szl_unknown_index_error=_get(settings_table, "szl_unknown_index_error", int, "settings.", source,
                                     0xD402),
        userdata_not_served_error=_get(settings_table, "userdata_not_served_error", int, "settings.", source,
                                       0x8104),
        unsupported_function_error=_get(settings_table, "unsupported_function_error", int, "settings.", source,
                                        0x8104),
        szl_index0_python_snap7=_get(settings_table, "szl_index0_python_snap7", bool, "settings.", source, True),
        c840_refuse_p0_at_zero=_get(settings_table, "c840_refuse_p0_at_zero", bool, "settings.", source, False),
        program_store_bytes=_get(settings_table, "program_store_bytes", int, "settings.", source, 3 * 1024 * 1024),
        nc_download_window=_get(settings_table, "nc_download_window", int, "settings.", source, 8),
    )
    if not 1 <= settings.nc_download_window <= 255:
        raise NckConfigError("expected 1..255 telegrams", path=source, field="settings.nc_download_window")
    if settings.program_store_bytes < 0:
        raise NckConfigError("expected a size in bytes >= 0", path=source, field="settings.program_store_bytes")
    for name in ("szl_unknown_id_error", "szl_unknown_index_error", "userdata_not_served_error",
                 "unsupported_function_error"):
        if not 0x0001 <= getattr(settings, name) <= 0xFFFF:
            raise NckConfigError("expected an error code 0x0001..0xFFFF", path=source, field=f"settings.{name}")
    if settings.compensation_sign not in (-1, 1):
        raise NckConfigError("expected -1 or 1", path=source, field="settings.compensation_sign")
    axes = tuple(_axis(t, i, source) for i, t in enumerate(data.get("axis", [])))
    numbers = [a.number for a in axes]
    if len(set(numbers)) != len(numbers):
        raise NckConfigError("two axes with one number", path=source, field="axis.number")
    sensors = tuple(_sensor(t, i, source) for i, t in enumerate(data.get("sensor", [])))
    for index, sensor in enumerate(sensors):
        for number, term in enumerate(sensor.response):
            if term.input == SENSOR and all(other.name != term.sensor for other in sensors):
                raise NckConfigError(f"no [[sensor]] named {term.sensor!r} (sensors: {', '.join(s.name for s in sensors)})",
                                     path=source, field=f"sensor[{index}].response[{number}].sensor")
    for index, axis in enumerate(axes):
        for name in axis.thermal_um_per_K:
            if all(sensor.name != name for sensor in sensors):
                raise NckConfigError(f"no [[sensor]] named {name!r} (sensors: {', '.join(s.name for s in sensors)})",
                                     path=source, field=f"axis[{index}].thermal_um_per_K")
    plc = data.get("plc", {})
    _check_keys(plc, "plc.", "plc.", source)
    blocks_raw = plc.get("data_blocks", {})
    data_blocks: dict[int, int] = {}
    for key, size in blocks_raw.items():
        if not str(key).isdigit() or not isinstance(size, int) or not 1 <= size <= 65535:
            raise NckConfigError(f"DB {key} = {size!r}: expected a DB number = size in bytes",
                                 path=source, field="plc.data_blocks")
        data_blocks[int(key)] = size
    initial: dict[str, dict[int, Any]] = {}
    for name, per_unit in data.get("initial", {}).items():
        if not isinstance(per_unit, dict):
            raise NckConfigError("expected { unit = value }", path=source, field=f"initial.{name}")
        initial[name.upper()] = {int(unit): value for unit, value in per_unit.items()}
    tool_settings, tools = _tools(data, text, source)
    drive_settings, drives = _drives(data, axes, sensors, text, source)
    work_offsets = _work_offsets(data.get("work_offsets", {}), axes, text, source)
    passwords = data.get("passwords", {})
    if not all(isinstance(v, int) and 0 <= v <= 7 for v in passwords.values()):
        raise NckConfigError("each password maps to an access level 0..7", path=source, field="passwords")
    return Machine(
        name=_get(data, "name", str, "", source, "unnamed machine"), source=source,
        ipo_cycle_s=_get(data, "ipo_cycle_s", float, "", source, 0.004),
        pdu_size_max=_get(data, "pdu_size_max", int, "", source, 960),
        max_amq=_get(data, "max_amq", int, "", source, 8),
        channels=_get(data, "channels", int, "", source, 1),
        connection_access_level=_get(data, "connection_access_level", int, "", source, 7),
        passwords=dict(passwords), settings=settings, axes=axes, sensors=sensors,
        data_blocks=data_blocks, initial=initial,
        variables=machine_table(data["var"], source, text) if "var" in data else (),
        tools=tools, tool_settings=tool_settings, work_offsets=work_offsets,
        opcua=_opcua_table(data.get("opcua", {}), source),
        drives=drives, drive_settings=drive_settings,
        program=_program_settings(data.get("program", {}), text, source),
        nck_io=parse_nck_io(data.get("nck_io", {}), source),
    )


def _program_settings(table: Any, text: str, source: str) -> ProgramSettings:
    line = _header_line(text, "[program]")
    _check_keys(table, "program.", "program.", source, line)
    defaults = ProgramSettings()
    flags = {}
    for key in ("wait_for_spindle", "optional_stop", "inch_basic_system"):
        value = table.get(key, getattr(defaults, key))
        if not isinstance(value, bool):
            raise NckConfigError(f"expected true or false, got {value!r}", path=source, line=line,
                                 field=f"program.{key}")
        flags[key] = value
    alarms = {key: _whole(table.get(key, getattr(defaults, key)), 1, 999999, "an alarm number", source, line,
                          f"program.{key}")
              for key in ("start_refused_alarm", "mode_refused_alarm", "travel_alarm")}
    repeated = table.get("repeated_g_group", defaults.repeated_g_group)
    if repeated not in REPEATED_G_GROUP_CHOICES:
        raise NckConfigError(f"expected one of {', '.join(map(repr, REPEATED_G_GROUP_CHOICES))}, got {repeated!r}",
                             path=source, line=line, field="program.repeated_g_group")
    return ProgramSettings(
        repeated_g_group=repeated,
        cycle_s=_positive(table, "cycle_s", defaults.cycle_s, "program.", source, line, high=3600.0),
        max_blocks_per_cycle=_whole(table.get("max_blocks_per_cycle", defaults.max_blocks_per_cycle), 1, 10**7,
                                    "a number of blocks", source, line, "program.max_blocks_per_cycle"),
        spindle_accel_rev_s2=_positive(table, "spindle_accel_rev_s2", defaults.spindle_accel_rev_s2, "program.",
                                       source, line),
        **flags, **alarms)


def _positive(table: dict[str, Any], key: str, default: float, where: str, source: str, line: int | None,
              *, low: float = 0.0, high: float = math.inf, allow_low: bool = False) -> float:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) \
            or not (low <= value if allow_low else low < value) or value > high:
        raise NckConfigError(f"expected a number {'>=' if allow_low else '>'} {low:g}"
                             f"{'' if high == math.inf else f' and <= {high:g}'}, got {value!r}",
                             path=source, line=line, field=f"{where}{key}")
    return float(value)


def _drive(table: Any, index: int, axes: tuple[Axis, ...], sensors: tuple[Sensor, ...], source: str,
           line: int | None) -> Drive:
    where = f"drive[{index}]."
    _check_keys(table, "drive", where, source, line)
    if "number" not in table:
        raise NckConfigError("missing (the drive number, the unit of area V)", path=source, line=line,
                             field=f"{where}number")
    number = _whole(table["number"], 1, 31, "a drive number", source, line, f"{where}number")
    axis_ref = table.get("axis")
    axis: Axis | None = None
    if axis_ref is not None:
        axis = next((a for a in axes if a.number == axis_ref or (isinstance(axis_ref, str)
                                                                 and a.name.upper() == axis_ref.upper())), None)
        if axis is None or isinstance(axis_ref, bool):
            raise NckConfigError(f"no machine axis {axis_ref!r} (axes: {', '.join(a.name for a in axes)})",
                                 path=source, line=line, field=f"{where}axis")
    sensor = table.get("motor_sensor")
    if sensor is not None and (not isinstance(sensor, str) or all(s.name != sensor for s in sensors)):
        raise NckConfigError(f"no [[sensor]] named {sensor!r} (sensors: {', '.join(s.name for s in sensors)})",
                             path=source, line=line, field=f"{where}motor_sensor")
    defaults = SPINDLE_DRIVE if axis is not None and axis.spindle else FEED_DRIVE
    values = {key: _positive(table, key, float(default), where, source, line,
                             allow_low=key in ("magnetizing_current_A", "standstill_load_pct", "speed_load_pct"),
                             high=1000.0 if key.endswith("_pct") else math.inf)
              for key, default in defaults.items()}
    return Drive(number=number, axis=None if axis is None else axis.number, motor_sensor=sensor, **values)


def _drives(data: dict[str, Any], axes: tuple[Axis, ...], sensors: tuple[Sensor, ...], text: str,
            source: str) -> tuple[DriveSettings, tuple[Drive, ...]]:
    table = data.get("drives", {})
    line = _header_line(text, "[drives]")
    _check_keys(table, "drives.", "drives.", source, line)
    defaults = DriveSettings()
    settings = DriveSettings(
        dc_link_V=_positive(table, "dc_link_V", defaults.dc_link_V, "drives.", source, line),
        ambient_C=_positive(table, "ambient_C", defaults.ambient_C, "drives.", source, line, low=-50.0,
                            allow_low=True, high=100.0),
        motor_rise_K=_positive(table, "motor_rise_K", defaults.motor_rise_K, "drives.", source, line,
                               allow_low=True),
        power_unit_rise_K=_positive(table, "power_unit_rise_K", defaults.power_unit_rise_K, "drives.", source,
                                    line, allow_low=True),
        efficiency=_positive(table, "efficiency", defaults.efficiency, "drives.", source, line, high=1.0),
        infeed_efficiency=_positive(table, "infeed_efficiency", defaults.infeed_efficiency, "drives.", source,
                                    line, high=1.0),
        unmeasured_C=_positive(table, "unmeasured_C", defaults.unmeasured_C, "drives.", source, line,
                               low=-1000.0, allow_low=True),
        answer_transport_size=table.get("answer_transport_size", defaults.answer_transport_size),
    )
    if settings.answer_transport_size not in (0x07, 0x09) or isinstance(settings.answer_transport_size, bool):
        raise NckConfigError(f"expected 0x09 (octet string) or 0x07 (REAL), got {settings.answer_transport_size!r}",
                             path=source, line=line, field="drives.answer_transport_size")
    rows = data.get("drive")
    if rows is None:
        # One drive per machine axis, drive n driving axis n (inferred: MD30110 CTRLOUT_MODULE_NR as
        # commissioned in axis order).
        return settings, tuple(Drive(number=axis.number, axis=axis.number,
                                     **(SPINDLE_DRIVE if axis.spindle else FEED_DRIVE))  # type: ignore[arg-type]
                               for axis in axes)
    if not isinstance(rows, list):
        raise NckConfigError("expected [[drive]] tables", path=source, field="drive")
    drive_lines = row_lines(text, "[[drive]]")
    drives: list[Drive] = []
    for index, row in enumerate(rows):
        row_line = drive_lines[index] if index < len(drive_lines) else None
        drive = _drive(row, index, axes, sensors, source, row_line)
        if any(other.number == drive.number for other in drives):
            raise NckConfigError(f"drive {drive.number} is declared twice", path=source, line=row_line,
                                 field=f"drive[{index}].number")
        drives.append(drive)
    return settings, tuple(drives)


def _opcua_table(table: object, source: str) -> dict[str, Any]:
    if not isinstance(table, dict):
        raise NckConfigError("expected a table", path=source, field="opcua")
    return dict(table)


def machine_text(path: str | Path | None = None) -> tuple[str, str]:
    """The text of the machine file ``path`` (or of the built-in default machine) and its source name."""
    if path is None:
        text = resources.files("nckemu.emulator.machine").joinpath("machines/default.toml").read_text("utf-8")
        return text, "default.toml (built in)"
    return read_text(path, "a machine is TOML text"), str(path)


def load_machine(path: str | Path | None = None) -> Machine:
    """The machine in ``path``, or the built-in default machine."""
    return parse_machine(*machine_text(path))


# The axis machine data that say how fast a program's moves are, as `machine show` lists them.
AXIS_DYNAMICS = (("MD32000", "MAX_AX_VELO"), ("MD32060", "POS_AX_VELO"), ("MD32300", "MAX_AX_ACCEL"))
# A catalogue row has one unit, the linear axis' one; a rotary axis' value is in these (the planner
# takes MD32000/MD32060 as degrees/min, and MD32300 as 1000 degrees/s² per unit: UNCONFIRMED).
ROTARY_UNITS = {"mm/min": "deg/min", "m/s^2": "rev/s^2"}


def axis_dynamics(machine: Machine, axis: int) -> dict[str, tuple[float, str]]:
    """MD32000, MD32060 and MD32300 of ``axis`` at power-on: the file's [initial] value (by number or
    name), else the catalogue's default; each with its unit (a rotary axis': :data:`ROTARY_UNITS`)."""
    specs = {spec.name: spec for spec in (machine.variables or load_table())}
    found: dict[str, tuple[float, str]] = {}
    declared = machine.axis(axis)
    rotary = declared is not None and declared.rotary
    for number, name in AXIS_DYNAMICS:
        spec = specs.get(name)
        if spec is None:  # a machine whose own [[var]] table leaves the row out
            continue
        per_unit = machine.initial.get(number) or machine.initial.get(name) or {}
        unit = ROTARY_UNITS.get(spec.unit, spec.unit) if rotary else spec.unit
        found[number] = (float(per_unit.get(axis, spec.default)), unit)  # type: ignore[arg-type]
    return found
