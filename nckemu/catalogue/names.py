"""Names as users type them to typed addresses, through the one grammar (``grammar``, docs/addresses.md).

NCK variables in NC syntax (indices from 0), BTSS (lines from 1) or as SINUMERIK OPC UA node ids:
  SD43900[AX4]  $SA_TEMP_COMP_ABS_VALUE[AX4]  MD32700[1,AX4]  R4  MD10000[1]  actToolBasePos[AX4]
  /Channel/Parameter/R[u1,5]  R[u1,1,#5]  TEMP_COMP_ABS_VALUE[u4]  ns=2;s=/Channel/State/progStatus[u1]
become a ``Variable`` (the address and how to decode the value: the NCVar selector's typ/laenge);
PLC memory as S7 tools write it (``DB130.DBW0``, ``M5.0``, ``PIW420``, ``DB2.DBD0:REAL``) or as an OPC UA
``/Plc/`` id becomes a ``PlcVariable``, which the clients read and write with S7ANY items.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

from nckemu.errors import NckConfigError, NckNodeIdError
from nckemu.protocol.addresses import NckAddress, NckType, S7AnyAddress, S7TransportSize

from .grammar import NcNodeName, PlcNodeName, parse_name
from .table import display_name, spec_at

PlcVariable = PlcNodeName


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


def _variable(name: NcNodeName) -> Variable:
    spec, address = name.spec, name.address
    return Variable(address, spec.nck_type, spec.string_length, display_name(spec, address), spec.unit)


def parse_item(text: str) -> Variable | PlcVariable:
    """Any name a user may type (see the module docstring): an NCK ``Variable`` or a ``PlcVariable``."""
    try:
        name = parse_name(text)
    except NckNodeIdError as exc:
        raise NckConfigError(str(exc)) from None
    return _variable(name) if isinstance(name, NcNodeName) else name


def parse_variable(text: str) -> Variable:
    """An NCK variable's name in any form (see the module docstring); PLC memory is refused."""
    item = parse_item(text)
    if not isinstance(item, Variable):
        raise NckConfigError(f"{text!r} is PLC memory, not an NCK variable: nckemu get/put and the clients' "
                             "get/put read and write it (S7ANY), as does the OPC UA face (/Plc/...)")
    return item


def variable_for_node_id(text: str) -> Variable:
    """A SINUMERIK OPC UA node id of an NC variable to a ``Variable`` (PLC ids are refused)."""
    return parse_variable(text)


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


def as_item(item: object) -> Variable | PlcVariable:
    """``as_variable``, and PLC memory: a ``PlcVariable`` or its S7 / ``/Plc/`` name."""
    if isinstance(item, PlcNodeName):
        return item
    if isinstance(item, str):
        return parse_item(item)
    return as_variable(item)


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


# ---------------------------------------------------------------------------------------------- PLC values
_PLC_FORMATS = {"BYTE": "B", "WORD": "H", "INT": "h", "DWORD": "I", "DINT": "i", "REAL": "f"}
PLC_RANGES = {"BYTE": (0, 0xFF), "WORD": (0, 0xFFFF), "INT": (-0x8000, 0x7FFF), "DWORD": (0, 0xFFFFFFFF),
              "DINT": (-0x80000000, 0x7FFFFFFF)}
STRING_HEADER = 2  # an S7 string: maximum length, length, then the characters


def plc_address(variable: PlcVariable, string_bytes: int = 0) -> S7AnyAddress:
    """The S7ANY item of PLC memory: one bit, or the bytes (a STRING: ``string_bytes`` from its start)."""
    if variable.kind == "BOOL":
        return S7AnyAddress(S7TransportSize.BIT, 1, variable.db, variable.s7_area, variable.byte, variable.bit or 0)
    size = max(1, string_bytes) if variable.kind == "STRING" else variable.size_bytes
    return S7AnyAddress(S7TransportSize.BYTE, size, variable.db, variable.s7_area, variable.byte)


def plc_decode(variable: PlcVariable, data: bytes) -> object:
    """The value of what an S7ANY read of ``plc_address(variable)`` answered (a list for an array)."""
    if variable.kind == "BOOL":
        return bool(data[:1] and data[0] & 1)
    if variable.kind == "STRING":
        if len(data) < STRING_HEADER:
            return ""
        length = min(data[0], data[1], len(data) - STRING_HEADER)
        return data[STRING_HEADER:STRING_HEADER + length].decode("latin-1")
    values = list(struct.unpack(f">{variable.count}{_PLC_FORMATS[variable.kind]}", data[:variable.size_bytes]))
    return values if variable.array else values[0]


def plc_encode(variable: PlcVariable, values: Sequence[object]) -> bytes:
    """Bytes to write (BOOL: 1 or 0; numbers big-endian); a value outside its type is refused, naming
    the type's range. A STRING is encoded by the client, which first reads its maximum length."""
    if variable.kind == "BOOL":
        return b"\x01" if values[0] else b"\x00"
    if len(values) != variable.count:
        raise NckConfigError(f"{variable}: {len(values)} values for {variable.count} elements")
    checked: list[object] = []
    for value in values:
        if variable.kind == "REAL":
            checked.append(float(value))  # type: ignore[arg-type]
            continue
        low, high = PLC_RANGES[variable.kind]
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise NckConfigError(f"{variable}: {value!r} is not a {variable.kind} ({low}..{high})")
        checked.append(value)
    return struct.pack(f">{variable.count}{_PLC_FORMATS[variable.kind]}", *checked)
