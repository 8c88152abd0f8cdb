"""Readable NCK variable names to typed addresses, through the catalogue.

Accepted forms (case-insensitive):
  SD43900[AX4]   MD32750[AX4]   TEMP_COMP_ABS_VALUE[u4]   $SA_TEMP_COMP_ABS_VALUE[AX4]
  MD32700[1,AX4]   (array index first, 0-based, as in part programs: line = index + 1)
  R5  R[5]  R[5,C1]   (R parameter 5 of channel 1; line = 5 + r_parameter_line_offset)
  NAME[u4,l2]  NAME[u4,l2,x3]   (explicit unit, line and line count)
  cuttEdgeParam[2,T1,col5]   (column for a variable over several columns: here T5, line 3, TO unit 1)
  /Channel/State/progStatus[u1]   /NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]   /Channel/Parameter/R[u1,1,5]
                             (SINUMERIK OPC UA node ids, parsed by ``node_ids``: the OPC UA face's parser)
A ``Variable`` carries the address and how to decode the value (the NCVar selector's typ/laenge).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from nckemu.errors import NckConfigError
from nckemu.protocol.addresses import NckAddress, NckArea, NckType

from .node_ids import NcNodeName, parse_node_id
from .table import R_PARAMETER_LINE_OFFSET, display_name, find_by_name, spec_at

_NAME = re.compile(r"^\$?(?:(?:S|M)[ACN]_)?(?P<name>[A-Z_][A-Z0-9_]*?)(?:\[(?P<index>[^\]]*)\])?$", re.IGNORECASE)
_R_SHORT = re.compile(r"^R(?P<number>\d+)$", re.IGNORECASE)


@dataclass(frozen=True)
class Variable:
    """An NCK address with the type and length used to decode it (never sent)."""

    address: NckAddress
    nck_type: NckType
    length: int | None = None
    name: str = ""
    unit_of_measure: str = ""

    def __str__(self) -> str:
        return self.name or str(self.address)


def variable_for_address(address: NckAddress) -> Variable:
    """The type of a raw address from the variable table (REAL8 if the table does not know it)."""
    spec = spec_at(address)
    if spec is None:
        return Variable(address, NckType.REAL8, None, str(address))
    return Variable(address, spec.nck_type, spec.string_length, display_name(spec, address), spec.unit)


def variable_for_node_id(text: str) -> Variable:
    """A SINUMERIK OPC UA node id of an NC variable to a ``Variable`` (PLC ids are refused)."""
    name = parse_node_id(text)
    if not isinstance(name, NcNodeName):
        raise NckConfigError(f"{text!r} is PLC memory: read it over OPC UA, or as a DB/M/I/Q address over S7")
    spec, address = name.spec, name.address
    return Variable(address, spec.nck_type, spec.string_length, display_name(spec, address), spec.unit)


def parse_variable(text: str) -> Variable:
    """A readable name or an OPC UA node id (see the module docstring) to a ``Variable``."""
    source = text.strip()
    if source.startswith("/"):
        return variable_for_node_id(source)
    short = _R_SHORT.match(source)
    if short:
        source = f"R[{short['number']}]"
    match = _NAME.match(source)
    if match is None:
        raise NckConfigError(f"{text!r} is not a variable name like SD43900[AX4]")
    spec = find_by_name(match["name"]) or find_by_name(f"{match['name']}")
    if spec is None:
        raise NckConfigError(f"unknown NCK variable {match['name']!r} in {text!r}")
    area = min(spec.areas)
    unit, line, count, column = 1, 1, 1, spec.column
    for part in [p.strip() for p in (match["index"] or "").split(",") if p.strip()]:
        lower = part.lower()
        if lower.startswith("col") and lower[3:].isdigit():
            column = int(lower[3:])
            if not spec.column <= column < spec.column + spec.columns:
                raise NckConfigError(f"{text!r}: {spec.name} has columns {spec.column}.."
                                     f"{spec.column + spec.columns - 1}")
        elif lower.startswith("ax") and lower[2:].isdigit():
            unit, area = int(lower[2:]), NckArea.A
        elif lower.startswith("u") and lower[1:].isdigit():
            unit = int(lower[1:])
        elif lower.startswith("l") and lower[1:].isdigit():
            line = int(lower[1:])
        elif lower.startswith("x") and lower[1:].isdigit():
            count = int(lower[1:])
        elif lower[0] in "cnbt" and lower[1:].isdigit():
            unit = int(lower[1:])
        elif part.lstrip("-").isdigit():
            index = int(part)
            line = index + (R_PARAMETER_LINE_OFFSET if spec.name == "R" else 1)
        else:
            raise NckConfigError(f"{text!r}: cannot read index part {part!r}")
    if area not in spec.areas:
        raise NckConfigError(f"{spec.number} {spec.name} is not an axis variable: {text!r}")
    try:
        address = NckAddress(area, unit, column, line, spec.module, count)
    except ValueError as exc:
        raise NckConfigError(f"{text!r}: {exc}") from None
    return Variable(address, spec.nck_type, spec.string_length, display_name(spec, address), spec.unit)


def as_variable(item: object) -> Variable:
    """Accept a Variable, a readable name, an NckAddress, or an NCVar-selector DB entry."""
    if isinstance(item, Variable):
        return item
    if isinstance(item, str):
        return parse_variable(item)
    if isinstance(item, NckAddress):
        return variable_for_address(item)
    address = getattr(item, "address", None)
    nck_type = getattr(item, "nck_type", None)
    if isinstance(address, NckAddress) and nck_type is not None:
        length = getattr(item, "length", None)
        return Variable(address, NckType(nck_type), length if NckType(nck_type) == NckType.STRING else None,
                        str(getattr(item, "name", "")) or str(address))
    raise TypeError(f"not an NCK variable: {item!r}")


def with_overrides(variable: Variable, unit: int | None = None, column: int | None = None,
                   line: int | None = None) -> Variable:
    """Unit/Column/Line given to GET/PUT override the address DB's entry, as on the real blocks."""
    if unit is None and column is None and line is None:
        return variable
    address = variable.address
    replaced = NckAddress(address.area, address.unit if unit is None else unit,
                          address.column if column is None else column,
                          address.line if line is None else line, address.module, address.line_count,
                          address.syntax_id)
    return Variable(replaced, variable.nck_type, variable.length, variable.name, variable.unit_of_measure)
