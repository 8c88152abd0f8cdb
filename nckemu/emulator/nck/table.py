"""The NCK variable table (``variables.toml``): one source of truth per variable."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from functools import cache
from importlib import resources

from nckemu.protocol.addresses import NckAddress, NckArea, NckType
from nckemu.protocol.errors import NckConfigError

READ_ONLY = -1


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
    read_level: int = 7
    write_level: int = READ_ONLY
    retained: bool = False
    effective: str = "immediate"
    computed: bool = False
    description: str = ""

    @property
    def read_only(self) -> bool:
        return self.write_level == READ_ONLY


def _spec(row: dict[str, object], source: str, index: int) -> VariableSpec:
    try:
        return VariableSpec(
            name=str(row["name"]), number=str(row["number"]), module=int(row["module"]),  # type: ignore[arg-type]
            column=int(row["column"]),  # type: ignore[arg-type]
            areas=frozenset(NckArea[a].value for a in row["areas"]),  # type: ignore[attr-defined]
            nck_type=NckType[str(row["type"])], lines=int(row.get("lines", 1)),  # type: ignore[arg-type]
            string_length=int(row["length"]) if "length" in row else None,  # type: ignore[arg-type]
            unit=str(row.get("unit", "")),
            minimum=float(row["min"]) if "min" in row else None,  # type: ignore[arg-type]
            maximum=float(row["max"]) if "max" in row else None,  # type: ignore[arg-type]
            default=row.get("default", "" if row["type"] == "STRING" else 0),
            read_level=int(row.get("read_level", 7)),  # type: ignore[arg-type]
            write_level=int(row.get("write_level", READ_ONLY)),  # type: ignore[arg-type]
            retained=bool(row.get("retained", False)), effective=str(row.get("effective", "immediate")),
            computed=row.get("source") == "computed", description=str(row.get("description", "")),
        )
    except (KeyError, ValueError, TypeError) as exc:
        raise NckConfigError(f"bad variable row: {exc!r}", path=source, field=f"var[{index}]") from None


@cache
def load_table() -> tuple[VariableSpec, ...]:
    source = "nckemu/emulator/nck/variables.toml"
    text = resources.files("nckemu.emulator.nck").joinpath("variables.toml").read_text("utf-8")
    rows = tomllib.loads(text).get("var", [])
    return tuple(_spec(row, source, index) for index, row in enumerate(rows))


@cache
def table_index() -> dict[tuple[int, int], VariableSpec]:
    """(module, column) -> spec."""
    return {(spec.module, spec.column): spec for spec in load_table()}


def find_by_name(name: str) -> VariableSpec | None:
    """By Siemens number (``SD43900``, ``MD32750``) or name (``TEMP_COMP_ABS_VALUE``)."""
    key = name.upper()
    for spec in load_table():
        if spec.number.upper() == key or spec.name.upper() == key:
            return spec
    return None


KNOWN_MODULES = frozenset(spec.module for spec in load_table())


R_PARAMETER_LINE_OFFSET = 1


def display_name(spec: VariableSpec, address: NckAddress) -> str:
    """``SD43900 TEMP_COMP_ABS_VALUE[AX4]``, ``R5[C1]``, ``MD32700 ENC_COMP_ENABLE[AX4,l2]``."""
    count = f",x{address.line_count}" if address.line_count > 1 else ""
    if spec.name == "R":
        return f"R{address.line - R_PARAMETER_LINE_OFFSET}[C{address.unit}{count}]"
    where = f"AX{address.unit}" if address.area == NckArea.A else f"{NckArea(address.area).name}{address.unit}"
    line = f",l{address.line}" if spec.lines > 1 or address.line != 1 else ""
    number = "" if spec.number.startswith("NCKEMU_") or not spec.number[:2].isalpha() else f"{spec.number} "
    return f"{number}{spec.name}[{where}{line}{count}]"
