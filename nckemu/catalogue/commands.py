"""``nckemu vars``: list the NCK variable catalogue (built in, or with a machine file's ``[[var]]`` rows)."""

from __future__ import annotations

import argparse
import fnmatch
import json
import tomllib
from collections.abc import Iterable

from nckemu.errors import NckConfigError, NckError
from nckemu.protocol.addresses import NckArea, NckType

from .edges import EDGE_PARAMETER_UNITS, TOOL_OFFSETS, units_text
from .grammar import NcNodeName, PlcNodeName, index_ranges, node_paths, parse_name
from .table import READ_ONLY, VariableSpec, load_table, machine_table

EXAMPLE = """\
A pattern is matched against names and numbers (case-insensitive): with * ? [ as a glob, else as a part
of them. A pattern starting with / is matched against the BTSS paths and OPC UA node ids instead, and
a whole name in any form (R4, SD43900[AX4], /Channel/Parameter/R[u1,5]) lists its row. --machine adds
or overrides variables with a machine file's [[var]] rows.

Each row shows its valid names in NC syntax (indices count from 0: R0..R99, MD10000[0..30]) and in BTSS
(lines count from 1: /Channel/Parameter/R[u1,1..100]); R4 is /Channel/Parameter/R[u1,5]. AXn names an
axis, SPn a spindle (docs/addresses.md).

examples:
  nckemu vars
  nckemu vars 'act*'
  nckemu vars NCKEMU
  nckemu vars /Channel/State --json
  nckemu vars '/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]'
  nckemu vars --machine fixtures/machines/extra_vars.toml
"""


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    parser = subparsers.add_parser(
        "vars", help="list the NCK variable catalogue", epilog=EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="List the NCK variables the emulator serves and clients name: name, number, address "
                    "(area, module, column, lines), type, unit, limits, access levels and value source.")
    parser.add_argument("pattern", nargs="?", default="",
                        help="glob or part of a name or number, a path starting with /, or a whole name "
                             "in any form (default: all)")
    parser.add_argument("--machine", help="machine TOML whose [[var]] rows add or override variables")
    parser.add_argument("--json", action="store_true", help="print a JSON list")
    parser.set_defaults(func=run_vars)


def machine_file_table(path: str) -> tuple[VariableSpec, ...]:
    """The catalogue with the ``[[var]]`` rows of the machine file at ``path`` (read here as data, so the
    catalogue needs no emulator)."""
    try:
        with open(path, encoding="utf-8") as handle:
            text = handle.read()
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=path) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise NckConfigError(f"not valid TOML: {exc}", path=path) from None
    return machine_table(data.get("var", []), path, text)


def pattern_row(pattern: str, specs: tuple[VariableSpec, ...]) -> VariableSpec | None:
    """The row a whole name names (``R4``, ``SD43900[AX4]``, ``/Channel/Parameter/R[u1,10]``), or None
    for a pattern that is no such name; PLC memory is refused (it has no catalogue row)."""
    if any(char in pattern for char in "*?") or not pattern.strip():
        return None
    try:
        name = parse_name(pattern, specs)
    except NckError:
        return None
    if isinstance(name, PlcNodeName):
        raise NckConfigError(f"{pattern!r} is PLC memory ({name}): it has no catalogue row; nckemu get/put "
                             "read and write it")
    return name.spec if isinstance(name, NcNodeName) else None


def matches(spec: VariableSpec, pattern: str) -> bool:
    """Names and numbers only; a pattern starting with / is matched against the paths and node ids."""
    if not pattern:
        return True
    texts = node_paths(spec) + [spec.path] if pattern.startswith("/") else [spec.name, spec.number]
    lowered = pattern.lower()
    if any(char in pattern for char in "*?["):
        return any(fnmatch.fnmatchcase(text.lower(), lowered) for text in texts if text)
    return any(lowered in text.lower() for text in texts if text)


def describe(spec: VariableSpec) -> dict[str, object]:
    """One catalogue row as plain data (the ``--json`` form); ``names``: its valid names as ranges, NC
    syntax (indices from 0), BTSS and OPC UA (lines from 1; an /NC/ id takes the NC index)."""
    ranges = index_ranges(spec)
    return {
        "name": spec.name, "number": spec.number, "path": spec.path, "opcua": node_paths(spec)[0],
        "areas": [NckArea(area).name for area in sorted(spec.areas)],
        "module": spec.module, "column": spec.column, "columns": spec.columns, "lines": spec.lines,
        "type": NckType(spec.nck_type).name,
        "bytes": spec.string_length if spec.nck_type == NckType.STRING else NckType(spec.nck_type).size_bytes,
        "unit": spec.unit, "min": spec.minimum, "max": spec.maximum,
        "read_level": spec.read_level, "write_level": None if spec.read_only else spec.write_level,
        "source": spec.source or "stored", "retained": spec.retained, "effective": spec.effective,
        "description": spec.description,
        "names": {"nc": ranges.nc, "nc_index": ranges.nc_index or ranges.nc, "btss": ranges.btss,
                  "opcua": ranges.node_id},
        **({"parameter_units": {f"P{number}": unit for number, unit in sorted(EDGE_PARAMETER_UNITS.items())}}
           if spec.name == TOOL_OFFSETS else {}),
    }


def _limits(row: dict[str, object]) -> str:
    if row["min"] is None and row["max"] is None:
        return ""
    return f"{row['min'] if row['min'] is not None else ''}..{row['max'] if row['max'] is not None else ''}"


def format_table(specs: Iterable[VariableSpec]) -> str:
    header = ("name", "number", "NC (index from 0)", "BTSS (line from 1)", "address", "type", "unit", "limits",
              "r/w", "source")
    rows = [header]
    for spec in specs:
        row = describe(spec)
        ranges = index_ranges(spec)
        columns = f"..{spec.column + spec.columns - 1}" if spec.columns > 1 else ""
        address = f"{'/'.join(row['areas'])} 0x{spec.module:02X} col {spec.column}{columns}"  # type: ignore[arg-type]
        kind = f"{row['type']}({row['bytes']})" if spec.nck_type == NckType.STRING else str(row["type"])
        write = "-" if spec.write_level == READ_ONLY else str(spec.write_level)
        nc = f"{ranges.nc} = [{ranges.nc_index.split('[', 1)[1]}" if ranges.nc_index else ranges.nc
        rows.append((spec.name, spec.number, nc, ranges.btss, address, kind, spec.unit, _limits(row),
                     f"{spec.read_level}/{write}", str(row["source"])))
    widths = [max(len(row[i]) for row in rows) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
                     for row in rows)


def _searchable(pattern: str, named: VariableSpec) -> bool:
    """A plain word (letters and digits) that is not the row's own name or number: searched as well."""
    word = pattern.strip()
    return word.isalnum() and word.lower() not in (named.name.lower(), named.number.lower())


def run_vars(args: argparse.Namespace) -> int:
    specs = machine_file_table(args.machine) if args.machine else load_table()
    # A catalogue number given whole (r0032: a drive parameter on every drive object that has it) lists
    # its rows before the grammar reads it as a name (R0032 would be R parameter 32).
    numbered = [spec for spec in specs if spec.number.lower() == args.pattern.strip().lower()]
    named = None if numbered else pattern_row(args.pattern, specs)
    chosen = numbered or ([named] if named is not None else [spec for spec in specs if matches(spec, args.pattern)])
    if named is not None and _searchable(args.pattern, named):
        # a name that is also the start of other rows' numbers (r00: R parameter 0, and the drive
        # parameters r0021, r0035, ...): the row it names, then every name and number containing it
        chosen = [spec for spec in specs if spec is named or matches(spec, args.pattern)]
    if args.json:
        print(json.dumps([describe(spec) for spec in chosen], indent=1))
        return 0
    if not chosen:
        where = "path or node id" if args.pattern.startswith("/") else "name or number"
        raise NckConfigError(f"no NCK variable {where} matches {args.pattern!r}")
    print(format_table(chosen))
    if any(spec.name == TOOL_OFFSETS for spec in chosen):
        print(f"{TOOL_OFFSETS}: Tn the TO unit, colN the tool, index (D-1)*numCuttEdgeParams + P-1; units by "
              f"parameter P: {units_text()}; the others (type, edge position, H number, teeth) have none")
    print(f"{len(chosen)} of {len(specs)} variables; NC syntax counts indices from 0 (R4 = BTSS line 5), "
          f"AXn is an axis, SPn a spindle; r/w = access level to read / write (0 highest, 7 lowest, - read only)")
    return 0
