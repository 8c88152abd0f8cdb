"""Model values <-> OPC UA variants for parsed SINUMERIK node names (no asyncua server state here).

NC values come from ``NckModel.read``/``write`` with the highest access level: on the OPC UA face the
realm rights of the session decide, not the key switch. PLC values are big-endian S7 memory.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from typing import Any

from asyncua import ua

from nckemu.catalogue.node_ids import NcNodeName, NodeName, PlcNodeName
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.nck.access import HIGHEST_LEVEL, AccessContext
from nckemu.errors import NckError, NckNodeIdError, NckObjectDoesNotExist
from nckemu.protocol.addresses import NckType, S7Area

NC_VARIANTS = {
    NckType.BOOL: ua.VariantType.Boolean, NckType.BYTE: ua.VariantType.Byte, NckType.WORD: ua.VariantType.UInt16,
    NckType.INT: ua.VariantType.Int16, NckType.DWORD: ua.VariantType.UInt32, NckType.DINT: ua.VariantType.Int32,
    NckType.REAL4: ua.VariantType.Float, NckType.REAL8: ua.VariantType.Double, NckType.INT64: ua.VariantType.Int64,
    NckType.STRING: ua.VariantType.String,
}
PLC_VARIANTS = {"BOOL": ua.VariantType.Boolean, "BYTE": ua.VariantType.Byte, "WORD": ua.VariantType.UInt16,
                "INT": ua.VariantType.Int16, "DWORD": ua.VariantType.UInt32, "DINT": ua.VariantType.Int32,
                "REAL": ua.VariantType.Float, "STRING": ua.VariantType.String}
_PLC_FORMATS = {"BYTE": "B", "WORD": "H", "INT": "h", "DWORD": "I", "DINT": "i", "REAL": "f"}
PLC_AREAS = {"I": S7Area.I, "Q": S7Area.Q, "M": S7Area.M, "DB": S7Area.DB}
_INTEGER_RANGES = {ua.VariantType.Byte: (0, 0xFF), ua.VariantType.UInt16: (0, 0xFFFF),
                   ua.VariantType.Int16: (-0x8000, 0x7FFF), ua.VariantType.UInt32: (0, 0xFFFFFFFF),
                   ua.VariantType.Int32: (-0x80000000, 0x7FFFFFFF),
                   ua.VariantType.Int64: (-(1 << 63), (1 << 63) - 1)}
_CTX = AccessContext(level=HIGHEST_LEVEL, client="opcua")


class UaStatus(Exception):
    """An OPC UA status code to answer (by name, as ``ua.StatusCodes``)."""

    def __init__(self, name: str, why: str = "") -> None:
        super().__init__(why or name)
        self.name = name

    @property
    def code(self) -> ua.StatusCode:
        return ua.StatusCode(getattr(ua.StatusCodes, self.name))


def variant_type(name: NodeName) -> ua.VariantType:
    if isinstance(name, NcNodeName):
        return NC_VARIANTS[name.spec.nck_type]
    return PLC_VARIANTS[name.kind]


def read_value(emulator: Emulator, name: NodeName) -> ua.Variant:
    """The current value as a variant (an array for a range); raises ``UaStatus``."""
    try:
        values = _read_nc(emulator, name) if isinstance(name, NcNodeName) else _read_plc(emulator, name)
    except NckObjectDoesNotExist as exc:
        raise UaStatus("BadAttributeIdInvalid", str(exc)) from None
    except NckNodeIdError as exc:
        raise UaStatus(exc.ua_status, str(exc)) from None
    except NckError as exc:
        raise UaStatus("BadAttributeIdInvalid", str(exc)) from None
    return _variant(name, values)


def _variant(name: NodeName, values: list[object]) -> ua.Variant:
    kind = variant_type(name)
    if kind == ua.VariantType.Boolean:
        values = [bool(v) for v in values]
    elif kind in (ua.VariantType.Double, ua.VariantType.Float):
        values = [float(v) for v in values]  # type: ignore[arg-type]
    elif kind != ua.VariantType.String:
        values = [int(v) for v in values]  # type: ignore[call-overload]
    if name.array:
        return ua.Variant(list(values), kind, is_array=True)
    return ua.Variant(values[0], kind)


def raw_reader(emulator: Emulator, name: NodeName) -> Callable[[], object]:
    """A function returning the value's raw form now (bytes of PLC memory, the NC lines): cheap to
    compare, so the sampler builds a variant only for what changed (``variant_from_raw``)."""
    if isinstance(name, NcNodeName):
        read, address = emulator.nck.read, name.address
        return lambda: read(address, _CTX)
    if name.kind in ("BOOL", "STRING"):
        return lambda: _read_plc(emulator, name)
    return emulator.plc.reader(PLC_AREAS[name.area], name.db, name.byte, name.size_bytes)


def variant_from_raw(name: NodeName, raw: object) -> ua.Variant:
    """The variant of what ``raw_reader`` returned."""
    if isinstance(name, PlcNodeName) and isinstance(raw, bytes | bytearray):
        values: list[object] = list(struct.unpack(f">{name.count}{_PLC_FORMATS[name.kind]}", raw))
    else:
        values = list(raw)  # type: ignore[call-overload]
    return _variant(name, values)


def _read_nc(emulator: Emulator, name: NcNodeName) -> list[object]:
    return emulator.nck.read(name.address, _CTX)


def _plc_string(emulator: Emulator, area: int, name: PlcNodeName) -> list[object]:
    head = emulator.plc.read(area, name.db, name.byte, 2)
    length = min(head[0], head[1])
    return [bytes(emulator.plc.read(area, name.db, name.byte + 2, length)).decode("latin-1")]


def _read_plc(emulator: Emulator, name: PlcNodeName) -> list[object]:
    area = PLC_AREAS[name.area]
    if name.kind == "BOOL":
        return [emulator.plc.read_bit(area, name.db, name.byte, name.bit or 0)]
    if name.kind == "STRING":
        return _plc_string(emulator, area, name)
    data = emulator.plc.read(area, name.db, name.byte, name.size_bytes)
    return list(struct.unpack(f">{name.count}{_PLC_FORMATS[name.kind]}", data))


def _python_values(name: NodeName, variant: ua.Variant | None) -> list[Any]:
    if variant is None or variant.Value is None:
        raise UaStatus("BadTypeMismatch", "no value")
    value = variant.Value
    count = name.count
    values = list(value) if isinstance(value, list | tuple) else [value]
    if bool(name.array) != isinstance(value, list | tuple) or len(values) != count:
        raise UaStatus("BadTypeMismatch", f"expected {'an array of ' + str(count) if name.array else 'a scalar'}")
    kind = variant_type(name)
    checked: list[Any] = []
    for item in values:
        if kind == ua.VariantType.String:
            if not isinstance(item, str):
                raise UaStatus("BadTypeMismatch", "expected a string")
            checked.append(item)
        elif kind == ua.VariantType.Boolean:
            if not isinstance(item, bool | int):
                raise UaStatus("BadTypeMismatch", "expected a boolean")
            checked.append(bool(item))
        elif isinstance(item, bool) or not isinstance(item, int | float):
            raise UaStatus("BadTypeMismatch", "expected a number")
        elif kind in (ua.VariantType.Double, ua.VariantType.Float):
            if not math.isfinite(item):
                raise UaStatus("BadOutOfRange", "not a finite number")
            checked.append(float(item))
        else:
            if item != int(item):
                raise UaStatus("BadTypeMismatch", "expected a whole number")
            low, high = _INTEGER_RANGES[kind]
            if not low <= int(item) <= high:
                raise UaStatus("BadOutOfRange", f"{item} outside {low}..{high}")
            checked.append(int(item))
    return checked


def write_value(emulator: Emulator, name: NodeName, variant: ua.Variant | None) -> bool:
    """Write through the model (the S7 face's path); True when retained data changed. Raises ``UaStatus``."""
    values = _python_values(name, variant)
    try:
        if isinstance(name, NcNodeName):
            spec = name.spec
            if spec.read_only:
                raise UaStatus("BadNotWritable", f"{spec.name} is read only")
            for value in values:
                if isinstance(value, int | float) and (
                        (spec.minimum is not None and value < spec.minimum)
                        or (spec.maximum is not None and value > spec.maximum)):
                    raise UaStatus("BadOutOfRange", f"{value} outside {spec.minimum}..{spec.maximum}")
            return emulator.nck.write(name.address, values, _CTX)
        _write_plc(emulator, name, values)
        return False
    except NckObjectDoesNotExist as exc:
        raise UaStatus("BadAttributeIdInvalid", str(exc)) from None
    except NckError as exc:
        raise UaStatus("BadOutOfRange", str(exc)) from None


def _write_plc(emulator: Emulator, name: PlcNodeName, values: list[Any]) -> None:
    area = PLC_AREAS[name.area]
    if name.kind == "BOOL":
        emulator.plc.write_bit(area, name.db, name.byte, name.bit or 0, bool(values[0]))
    elif name.kind == "STRING":
        maximum = emulator.plc.read(area, name.db, name.byte, 1)[0]
        data = values[0].encode("latin-1", "replace")
        if len(data) > maximum:
            raise UaStatus("BadOutOfRange", f"string longer than its {maximum} characters")
        emulator.plc.write(area, name.db, name.byte + 1, bytes([len(data)]) + data)
    else:
        emulator.plc.write(area, name.db, name.byte, struct.pack(f">{name.count}{_PLC_FORMATS[name.kind]}", *values))
