"""NCK values on the wire: answers carry ``FF 09 len`` and writes ``00 09 len`` (octet string).

Values are little-endian in the areas N, B, C, A, T and M, big-endian in the drive areas V and H;
a line count of N is one item of N values back to back. Strings are fixed-length fields padded
with NUL and have no S7 STRING header.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Sequence

from .addresses import BIG_ENDIAN_AREAS, NckType
from .errors import NckTypeInconsistent

NCK_TRANSPORT_SIZE = 0x09

_FORMATS: dict[NckType, str] = {
    NckType.BOOL: "B",
    NckType.BYTE: "B",
    NckType.WORD: "H",
    NckType.INT: "h",
    NckType.DWORD: "I",
    NckType.DINT: "i",
    NckType.REAL4: "f",
    NckType.REAL8: "d",
    NckType.INT64: "q",
}
_STRUCTS: dict[tuple[NckType, bool, int], struct.Struct] = {}


def _codec(nck_type: NckType, big_endian: bool, count: int) -> struct.Struct:
    key = (nck_type, big_endian, count)
    codec = _STRUCTS.get(key)
    if codec is None:
        codec = struct.Struct((">" if big_endian else "<") + _FORMATS[nck_type] * count)
        if len(_STRUCTS) < 4096:
            _STRUCTS[key] = codec
    return codec


def value_size(nck_type: NckType, string_length: int | None = None) -> int:
    if nck_type == NckType.STRING:
        if string_length is None or string_length <= 0:
            raise NckTypeInconsistent("a STRING needs its length (the NCVar selector's laenge)")
        return string_length
    size = NckType(nck_type).size_bytes
    assert size is not None
    return size


def _coerce(nck_type: NckType, value: object) -> object:
    if nck_type in (NckType.REAL4, NckType.REAL8):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise NckTypeInconsistent(f"{value!r} is not a number for {nck_type.name}")
        return float(value)
    if nck_type == NckType.BOOL:
        return 1 if value else 0
    if isinstance(value, bool) or not isinstance(value, int):
        raise NckTypeInconsistent(f"{value!r} is not an integer for {nck_type.name}")
    return value


_REAL8_LE = struct.Struct("<d")


def encode_nck_values(nck_type: NckType, values: Sequence[object], *, area: int,
                      string_length: int | None = None, answer: bool = False) -> bytes:
    """The item's bytes. ``answer``: the controller's read answer, where text is shown as the
    control shows it, never refused: a character outside its code page (Latin-1) becomes '?', text
    longer than the field is cut at the field's end. A client's write (``answer`` False) refuses both,
    so a value is never sent other than it was given."""
    if nck_type == NckType.REAL8 and len(values) == 1 and area not in BIG_ENDIAN_AREAS:
        value = values[0]
        if isinstance(value, float):  # the hot path: one REAL8 in an N/B/C/A/T/M area
            return _REAL8_LE.pack(value)
    nck_type = NckType(nck_type)
    if nck_type == NckType.STRING:
        size = value_size(nck_type, string_length)
        parts = []
        for value in values:
            if isinstance(value, str):
                try:
                    raw = value.encode("latin-1", errors="replace" if answer else "strict")
                except UnicodeEncodeError as exc:
                    raise NckTypeInconsistent(f"{value!r}: {exc.object[exc.start:exc.end]!r} is not in the "
                                              "control's character set (Latin-1)") from None
            else:
                raw = bytes(value)  # type: ignore[arg-type]
            if len(raw) > size:
                if not answer:
                    raise NckTypeInconsistent(f"string of {len(raw)} bytes in a field of {size}")
                raw = raw[:size]
            parts.append(raw.ljust(size, b"\x00"))
        return b"".join(parts)
    codec = _codec(nck_type, area in BIG_ENDIAN_AREAS, len(values))
    try:
        return codec.pack(*(_coerce(nck_type, value) for value in values))
    except (struct.error, OverflowError) as exc:
        raise NckTypeInconsistent(f"value out of range for {nck_type.name}: {exc}") from None


def decode_nck_values(nck_type: NckType, data: bytes, *, area: int, line_count: int = 1,
                      string_length: int | None = None) -> list[object]:
    nck_type = NckType(nck_type)
    size = value_size(nck_type, string_length)
    if line_count < 1 or len(data) != size * line_count:
        raise NckTypeInconsistent(f"{len(data)} bytes for {line_count} value(s) of {size} bytes "
                                  f"({nck_type.name})")
    if nck_type == NckType.STRING:
        return [data[i:i + size].split(b"\x00", 1)[0].decode("latin-1") for i in range(0, len(data), size)]
    values = list(_codec(nck_type, area in BIG_ENDIAN_AREAS, line_count).unpack(data))
    if nck_type == NckType.BOOL:
        return [bool(v) for v in values]
    return values


def nck_value_reader(nck_type: NckType, *, area: int, line_count: int = 1,
                     string_length: int | None = None) -> Callable[[bytes], object]:
    """A function of the item's bytes giving what ``decode_nck_values`` gives (one value alone, else the
    list), built once for a variable that is read many times; wrong lengths raise as there."""
    nck_type = NckType(nck_type)
    size = value_size(nck_type, string_length)
    if nck_type in (NckType.STRING, NckType.BOOL) or line_count < 1:
        def general(data: bytes) -> object:
            values = decode_nck_values(nck_type, data, area=area, line_count=line_count,
                                       string_length=string_length)
            return values[0] if len(values) == 1 else values
        return general
    codec = _codec(nck_type, area in BIG_ENDIAN_AREAS, line_count)
    expected = size * line_count

    def read(data: bytes) -> object:
        if len(data) != expected:
            raise NckTypeInconsistent(f"{len(data)} bytes for {line_count} value(s) of {size} bytes "
                                      f"({nck_type.name})")
        values = codec.unpack(data)
        return values[0] if line_count == 1 else list(values)
    return read


def nck_value_format(nck_type: NckType, *, area: int, line_count: int = 1) -> tuple[str, bool] | None:
    """The struct code and byte order (True: big-endian) of one numeric value, for decoders that unpack
    many items at once; None where ``nck_value_reader`` does more than unpack (strings, BOOL, arrays)."""
    if line_count != 1 or nck_type in (NckType.STRING, NckType.BOOL) or nck_type not in _FORMATS:
        return None
    return _FORMATS[nck_type], area in BIG_ENDIAN_AREAS


def is_finite(value: object) -> bool:
    return not isinstance(value, float) or math.isfinite(value)
