"""``nckemu vars``: list the NCK variable catalogue (built in, or with a machine file's ``[[var]]`` rows)."""

from __future__ import annotations

import argparse
import fnmatch
import json
import tomllib
from collections.abc import Iterable

from nckemu.errors import NckConfigError, NckError
from nckemu.protocol.addresses import NckArea, NckType

from .node_ids import NcNodeName, node_paths, parse_node_id
from .table import READ_ONLY, VariableSpec, load_table, machine_table

EXAMPLE = """\
A pattern with * ? [ is a glob over names, numbers and BTSS paths (case-insensitive); anything else
matches a part of them. --machine adds or overrides variables with a machine file's [[var]] rows.

examples:
  nckemu vars
  nckemu vars 'act*'
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
                        help="glob or part of a name, number or BTSS path (default: all)")
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


def matches(spec: VariableSpec, pattern: str) -> bool:
    if not pattern:
        return True
    if pattern.startswith("/") and not any(char in pattern for char in "*?"):
        try:  # an OPC UA node id names its row exactly (/Channel/Parameter/R[u1,10] is R)
            name = parse_node_id(pattern)
        except NckError:
            name = None
        if isinstance(name, NcNodeName):
            return name.spec.name == spec.name
    texts = (spec.name, spec.number, *node_paths(spec))
    lowered = pattern.lower()
    if any(char in pattern for char in "*?["):
        return any(fnmatch.fnmatchcase(text.lower(), lowered) for text in texts if text)
    return any(lowered in text.lower() for text in texts if text)


def describe(spec: VariableSpec) -> dict[str, object]:
    """One catalogue row as plain data (the ``--json`` form)."""
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
    }


def _limits(row: dict[str, object]) -> str:
    if row["min"] is None and row["max"] is None:
        return ""
    return f"{row['min'] if row['min'] is not None else ''}..{row['max'] if row['max'] is not None else ''}"


def format_table(specs: Iterable[VariableSpec]) -> str:
    header = ("name", "number", "address", "type", "unit", "limits", "r/w", "source")
    rows = [header]
    for spec in specs:
        row = describe(spec)
        lines = f" l1..{spec.lines}" if spec.lines > 1 else ""
        columns = f"..{spec.column + spec.columns - 1}" if spec.columns > 1 else ""
        address = f"{'/'.join(row['areas'])} 0x{spec.module:02X} col {spec.column}{columns}{lines}"  # type: ignore[arg-type]
        kind = f"{row['type']}({row['bytes']})" if spec.nck_type == NckType.STRING else str(row["type"])
        write = "-" if spec.write_level == READ_ONLY else str(spec.write_level)
        rows.append((spec.name, spec.number, address, kind, spec.unit, _limits(row),
                     f"{spec.read_level}/{write}", str(row["source"])))
    widths = [max(len(row[i]) for row in rows) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
                     for row in rows)


def run_vars(args: argparse.Namespace) -> int:
    specs = machine_file_table(args.machine) if args.machine else load_table()
    chosen = [spec for spec in specs if matches(spec, args.pattern)]
    if args.json:
        print(json.dumps([describe(spec) for spec in chosen], indent=1))
        return 0
    if not chosen:
        raise NckConfigError(f"no NCK variable name, number or BTSS path matches {args.pattern!r}")
    print(format_table(chosen))
    print(f"{len(chosen)} of {len(specs)} variables; r/w = access level to read / write (0 highest, 7 lowest, "
          f"- read only)")
    return 0
