"""A machine from TOML: axes, sensors, PLC data blocks, initial data and settings for open facts.

One machine per file; the built-in default machine is ``machines/default.toml`` in this package.
Every problem is reported as an ``NckConfigError`` naming the file and the field.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any

from nckemu.catalogue.table import VariableSpec, machine_table
from nckemu.errors import NckConfigError

from .plc.memory import AREA_BYTES


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


# The default allocation of SD42960's components to geometry axes, by the first letter of the axis name.
TOOL_TEMP_COMP_COMPONENTS = {"Z": 1, "Y": 2, "X": 3}


@dataclass(frozen=True)
class Sensor:
    name: str
    temperature_C: float = 20.0
    plc_input: str | None = None
    raw_offset: float = 0.0
    raw_per_C: float = 276.48
    # (t_s, temperature_C) points; linear in between, end values held.
    profile: tuple[tuple[float, float], ...] = ()

    def raw_value(self, temperature_C: float) -> int:
        raw = round(self.raw_offset + self.raw_per_C * temperature_C)
        return max(-32768, min(32767, raw))


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
                   "passwords", "settings", "axis", "sensor", "plc", "initial", "var"}),
    # every setting the dataclass has (a new setting needs no second list)
    "settings.": frozenset(setting.name for setting in fields(Settings)),
    "axis": frozenset({"number", "name", "travel_mm", "rotary", "spindle", "referenced", "position_mm",
                       "tool_temp_comp_component", "recording"}),
    "sensor": frozenset({"name", "temperature_C", "plc_input", "raw_offset", "raw_per_C", "profile"}),
    "plc.": frozenset({"data_blocks"}),
}


def _check_keys(table: Any, kind: str, where: str, source: str) -> None:
    """A mistyped key would silently fall back to its default: refuse it, naming the known ones."""
    if not isinstance(table, dict):
        raise NckConfigError("expected a table", path=source, field=where.rstrip(".") or "(top level)")
    unknown = sorted(set(table) - _KNOWN_KEYS[kind])
    if unknown:
        raise NckConfigError(f"unknown key (known: {', '.join(sorted(_KNOWN_KEYS[kind]))})", path=source,
                             field=f"{where}{unknown[0]}")


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
    return Axis(number=number, name=name, recording=recording,
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
    if plc_input is not None and int(plc_input[3:]) > AREA_BYTES - 2:
        raise NckConfigError(f"{plc_input}: the input area has bytes 0..{AREA_BYTES - 1}, so PIW0..PIW{AREA_BYTES - 2}",
                             path=source, field=f"{where}plc_input")
    return Sensor(name=_get(table, "name", str, where, source),
                  temperature_C=_get(table, "temperature_C", float, where, source, 20.0),
                  plc_input=plc_input.upper() if plc_input else None,
                  raw_offset=_get(table, "raw_offset", float, where, source, 0.0),
                  raw_per_C=_get(table, "raw_per_C", float, where, source, 276.48),
                  profile=tuple(profile))


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
    )
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
    )


def load_machine(path: str | Path | None = None) -> Machine:
    """The machine in ``path``, or the built-in default machine."""
    if path is None:
        text = resources.files("nckemu.emulator").joinpath("machines/default.toml").read_text("utf-8")
        return parse_machine(text, "default.toml (built in)")
    path = Path(path)
    try:
        text = path.read_text("utf-8")
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=str(path)) from None
    except UnicodeDecodeError:
        raise NckConfigError("not a text file (a machine is TOML text in UTF-8)", path=str(path)) from None
    return parse_machine(text, str(path))
