"""The NCK variable catalogue (``variables.toml``): one source of truth per variable.

What the controller's address space *is* (name, number, module, column, type, limits, access levels),
shared by the clients, the trace tools and the emulator. Rows are checked when the table loads, as
pymodbus's ``SimData`` checks itself: an unknown key, a wrong type or a clash is one error naming the
file, the row's line and the field, never a silently read-only variable.
"""

from __future__ import annotations

import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import cache
from importlib import resources

from nckemu.errors import NckConfigError
from nckemu.protocol.addresses import NckAddress, NckArea, NckType

READ_ONLY = -1
LOWEST_ACCESS_LEVEL = 7
EFFECTIVENESS = ("immediate", "power_on", "new_conf", "reset")
BUILTIN_SOURCE = "nckemu/catalogue/variables.toml"

# Every key a row may carry; anything else is a typo that would otherwise be ignored.
ROW_KEYS = frozenset({
    "name", "number", "module", "column", "areas", "type", "lines", "length", "unit", "min", "max",
    "default", "read_level", "write_level", "retained", "effective", "source", "description", "path",
    "columns", "aliases",
})
REQUIRED_KEYS = ("name", "number", "module", "column", "areas", "type")


@dataclass(frozen=True)
class VariableSpec:
    name: str
    number: str            # "SD43900", "MD32750", "R", ...
    module: int
    column: int
    areas: frozenset[int]
    nck_type: NckType
    lines: int = 1
    string_length: int | None = None
    unit: str = ""
    minimum: float | None = None
    maximum: float | None = None
    default: object = 0
    read_level: int = LOWEST_ACCESS_LEVEL
    write_level: int = READ_ONLY
    retained: bool = False
    effective: str = "immediate"
    # A named value source of the emulator ("axes.actual_position"); None: the value is stored.
    source: str | None = None
    description: str = ""
    # The BTSS / NC-Var-Selector path ("/Channel/State/actParts"); "" when no source names it.
    path: str = ""
    # How many columns from ``column`` on the variable occupies: > 1 where the column is an index, as
    # the T number of the tool offsets (module TO: column = T number); its value source gets the column.
    columns: int = 1
    # Other paths the controller serves the same value under, line for line (a Siemens BTSS path of a row
    # served first as nckemu's own /Nckemu/.. id): names that read and write this row.
    aliases: tuple[str, ...] = ()

    @property
    def read_only(self) -> bool:
        return self.write_level == READ_ONLY

    @property
    def computed(self) -> bool:
        return self.source is not None


def _integer(row: Mapping[str, object], key: str, low: int, high: int, default: int | None = None) -> int:
    value = row.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{key} must be a whole number, not {value!r}")
    if not low <= value <= high:
        raise ValueError(f"{key} {value} outside {low}..{high}")
    return value


def _number(row: Mapping[str, object], key: str) -> float | None:
    value = row.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{key} must be a number, not {value!r}")
    return float(value)


def _spec(row: Mapping[str, object]) -> VariableSpec:
    unknown = sorted(set(row) - ROW_KEYS)
    if unknown:
        raise KeyError(unknown[0], f"unknown key (known: {', '.join(sorted(ROW_KEYS))})")
    for key in REQUIRED_KEYS:
        if key not in row:
            raise KeyError(key, "missing")
    type_name = str(row["type"])
    if type_name not in NckType.__members__:
        raise KeyError("type", f"{type_name!r} is not one of {', '.join(NckType.__members__)}")
    nck_type = NckType[type_name]
    areas = row["areas"]
    if not isinstance(areas, list) or not areas or any(str(a) not in NckArea.__members__ for a in areas):
        raise KeyError("areas", f"{areas!r} is not a list of NCK areas ({', '.join(NckArea.__members__)})")
    try:
        length = _integer(row, "length", 1, 255) if "length" in row else None
        if nck_type == NckType.STRING and length is None:
            raise KeyError("length", "a STRING needs its length in bytes")
        effective = str(row.get("effective", "immediate"))
        if effective not in EFFECTIVENESS:
            raise KeyError("effective", f"{effective!r} is not one of {', '.join(EFFECTIVENESS)}")
        default = row.get("default", "" if nck_type == NckType.STRING else 0)
        lines = _integer(row, "lines", 1, 0xFFFF, 1)
        column = _integer(row, "column", 0, 0xFFFF)
        columns = _integer(row, "columns", 1, 0xFFFF - column + 1, 1)
        if isinstance(default, list) and len(default) != lines:
            raise KeyError("default", f"a list default needs one value per line ({lines}), not {len(default)}")
        source = row.get("source")
        if source is not None and (not isinstance(source, str) or not source):
            raise KeyError("source", "must name a value source such as \"axes.actual_position\"")
        if columns > 1 and source is None:
            raise KeyError("columns", "a variable over several columns needs a value source (it gets the column)")
        aliases = row.get("aliases", [])
        if not isinstance(aliases, list) or not all(isinstance(a, str) and a.startswith("/") for a in aliases):
            raise KeyError("aliases", "a list of paths such as \"/Channel/MachineAxis/actToolBasePos\"")
        return VariableSpec(
            name=str(row["name"]), number=str(row["number"]),
            module=_integer(row, "module", 0, 0xFF), column=column, columns=columns,
            areas=frozenset(NckArea[str(a)].value for a in areas), nck_type=nck_type,
            lines=lines, string_length=length,
            unit=str(row.get("unit", "")), minimum=_number(row, "min"), maximum=_number(row, "max"),
            default=tuple(default) if isinstance(default, list) else default,
            read_level=_integer(row, "read_level", 0, LOWEST_ACCESS_LEVEL, LOWEST_ACCESS_LEVEL),
            write_level=_integer(row, "write_level", READ_ONLY, LOWEST_ACCESS_LEVEL, READ_ONLY),
            retained=bool(row.get("retained", False)), effective=effective,
            source=source, description=str(row.get("description", "")), path=str(row.get("path", "")),
            aliases=tuple(aliases),
        )
    except ValueError as exc:
        field = str(exc).split(" ", 1)[0]
        raise KeyError(field, str(exc)) from None


def row_lines(text: str, header: str = "[[var]]") -> list[int]:
    """The 1-based line of each ``[[var]]`` header, so an error can name the row's line."""
    return [number for number, line in enumerate(text.splitlines(), 1) if line.strip() == header]


def _keys(spec: VariableSpec) -> list[tuple[int, int, int]]:
    return [(spec.module, column, area) for area in sorted(spec.areas)
            for column in range(spec.column, spec.column + spec.columns)]


def build_table(rows: Iterable[Mapping[str, object]], source: str, lines: list[int] | None = None,
                base: Iterable[VariableSpec] = ()) -> tuple[VariableSpec, ...]:
    """Checked specs from TOML rows; ``base`` rows may be overridden by name (a machine file mirroring
    its controller), a new row that takes another's (module, column, area) or name is a clash. One
    module and column may hold different variables in different areas (S column 3: the mode group's
    opMode in area B, the channel's feed override in area C)."""
    specs: dict[str, VariableSpec] = {spec.name.upper(): spec for spec in base}
    base_names = set(specs)
    addresses = {key: spec.name for spec in specs.values() for key in _keys(spec)}
    seen: set[str] = set()
    for index, row in enumerate(rows):
        line = lines[index] if lines and index < len(lines) else None
        try:
            spec = _spec(row)
        except KeyError as exc:
            field, why = (exc.args + ("",))[:2]
            raise NckConfigError(f"variable row {index + 1}: {why}", path=source, line=line,
                                 field=str(field)) from None
        key = spec.name.upper()
        if key in seen:
            raise NckConfigError(f"{spec.name} is declared twice", path=source, line=line, field="name")
        seen.add(key)
        old = specs.get(key)
        if old is not None and key not in base_names:
            raise NckConfigError(f"{spec.name} is declared twice", path=source, line=line, field="name")
        if old is not None:
            for old_key in _keys(old):
                addresses.pop(old_key, None)
        for address in _keys(spec):
            holder = addresses.get(address)
            if holder is not None and holder.upper() != key:
                raise NckConfigError(f"{spec.name}: module 0x{spec.module:02X} column {address[1]} area "
                                     f"{NckArea(address[2]).name} is already {holder}", path=source, line=line,
                                     field="column")
        specs[key] = spec
        addresses.update((address, spec.name) for address in _keys(spec))
    return tuple(specs.values())


@cache
def load_table() -> tuple[VariableSpec, ...]:
    """The built-in catalogue."""
    text = resources.files("nckemu.catalogue").joinpath("variables.toml").read_text("utf-8")
    try:
        rows = tomllib.loads(text).get("var", [])
    except tomllib.TOMLDecodeError as exc:
        raise NckConfigError(str(exc), path=BUILTIN_SOURCE) from None
    return build_table(rows, BUILTIN_SOURCE, row_lines(text))


def machine_table(rows: object, source: str, text: str = "") -> tuple[VariableSpec, ...]:
    """The catalogue of a machine file: the built-in rows, with the file's ``[[var]]`` rows added or
    overriding built-in rows by name (same format as ``variables.toml``). ``text`` is the file's
    text, so an error names the row's line."""
    if not isinstance(rows, list) or not all(isinstance(row, dict) for row in rows):
        raise NckConfigError("expected [[var]] tables", path=source, field="var")
    return build_table(rows, source, row_lines(text), base=load_table())


def index_by_address(specs: Iterable[VariableSpec]) -> dict[tuple[int, int, int], VariableSpec]:
    """(module, column, area) -> spec."""
    return {key: spec for spec in specs for key in _keys(spec)}


def spec_at(address: NckAddress) -> VariableSpec | None:
    """The built-in catalogue's variable at an address (module, column and area), or None."""
    return table_index().get((address.module, address.column, address.area))


@cache
def table_index() -> dict[tuple[int, int, int], VariableSpec]:
    """(module, column, area) -> spec of the built-in catalogue."""
    return index_by_address(load_table())


@cache
def _by_name() -> dict[str, VariableSpec]:
    index: dict[str, VariableSpec] = {}
    for spec in load_table():
        index.setdefault(spec.number.upper(), spec)
        index.setdefault(spec.name.upper(), spec)
    return index


def find_by_name(name: str) -> VariableSpec | None:
    """By Siemens number (``SD43900``, ``MD32750``) or name (``TEMP_COMP_ABS_VALUE``)."""
    return _by_name().get(name.upper())


KNOWN_MODULES = frozenset(spec.module for spec in load_table())


# R parameter n is BTSS line n + 1, as every array's NC index i is line i + 1 (docs/assumptions.md: the
# sources disagree on R parameters; the machine file's settings.r_parameter_line_offset records it).
R_PARAMETER_LINE_OFFSET = 1

# Rows whose lines are not array entries but machine axes or spindles, by the BTSS module that says so:
# SMA/SEMA (state data of machine axes) and SSP (spindles). NC syntax names such a line by its axis or
# spindle, ``actToolBasePos[AX4]`` and ``actSpeed[SP1]``, besides the index (``actToolBasePos[3]``).
LINE_KINDS: dict[int, str] = {0x74: "machine axis", 0x71: "machine axis", 0x72: "spindle"}
LINE_PREFIXES: dict[str, str] = {"machine axis": "AX", "spindle": "SP"}


def line_kind(spec: VariableSpec) -> str | None:
    """"machine axis", "spindle", or None where a line is an array entry (an axis variable's axis is
    its unit, not its line)."""
    if spec.lines <= 1 or NckArea.A in spec.areas:
        return None
    return LINE_KINDS.get(spec.module)


def short_name(spec: VariableSpec) -> str:
    """What NC syntax calls a row: its SD/MD number (``SD43900``), else its name (``actSpeed``)."""
    number = spec.number.upper()
    if number[:2] in ("SD", "MD") and number[2:].isdigit():
        return spec.number
    return spec.name


def display_name(spec: VariableSpec, address: NckAddress) -> str:
    """The canonical NC-syntax name of an address, which the parser reads back to the same address:
    ``SD43900 TEMP_COMP_ABS_VALUE[AX4]``, ``R5[C1]``, ``MD32700 ENC_COMP_ENABLE[1,AX4]`` (an array's
    index first, counted from 0 as in part programs), ``SMA2 actToolBasePos[AX4,C1]`` and
    ``SSP2 actSpeed[SP1,C1]`` (a line that is a machine axis or a spindle), ``TO1 cuttEdgeParam[2,T1,col7]``
    (the column is an index: the T number), ``x5`` for five lines. A line outside the row (a trace's) is
    written as the wire line, ``l0``."""
    count = address.line_count
    in_range = address.line >= 1 and address.line + count - 1 <= spec.lines
    where = f"AX{address.unit}" if address.area == NckArea.A else f"{NckArea(address.area).name}{address.unit}"
    tail = [f"col{address.column}"] if spec.columns > 1 else []
    if count > 1:
        tail.append(f"x{count}")
    if spec.name == "R" and in_range:
        return f"R{address.line - R_PARAMETER_LINE_OFFSET}[{','.join([where, *tail])}]"
    kind = line_kind(spec)
    if not in_range or (spec.lines == 1 and address.line != 1):
        index = [f"l{address.line}"]
    elif kind is not None:
        index = [f"{LINE_PREFIXES[kind]}{address.line}"]
    elif spec.lines > 1:
        index = [str(address.line - 1)]
    else:
        index = []
    number = "" if spec.number.startswith("NCKEMU_") or not spec.number[:2].isalpha() \
        or spec.number == spec.name else f"{spec.number} "
    return f"{number}{spec.name}[{','.join([*index, where, *tail])}]"
