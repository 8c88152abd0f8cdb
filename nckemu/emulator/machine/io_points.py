"""The NCK's I/O points as a machine file names them, and what the machine's PLC answers on them.

A part program that waits for its machine (``WHILE $A_IN[24]==0 ... G4 F0.2 ... ENDWHILE`` until the
door is closed) waits for the PLC, which the emulator does not run unless a user's STL program is
loaded. The machine file's ``[nck_io]`` table says what that PLC does for the NCK:

    [nck_io]
    initial = { "$A_IN[22]" = 1 }            # points that read so from power on (air pressure OK)

    [[nck_io.answer]]
    m = 48                                   # when the channel outputs M48 (close the guard) ...
    set = { "$A_IN[10]" = 1, "$A_IN[9]" = 0 }
    after_s = 2.0                            # ... the PLC sets these that long after

    [[nck_io.answer]]
    out = 5                                  # when a program sets $A_OUT[5] to 1 ...
    value = 1
    set = { "$A_DBB[30]" = 1 }

Points are ``$A_IN[n]``, ``$A_INA[n]`` (inputs, n from 1) and the PLC-NCK data area's ``$A_DBB[i]``,
``$A_DBW[i]``, ``$A_DBD[i]``, ``$A_DBR[i]`` (byte offset i), the names a program reads. This module
is the vocabulary the machine file and the NCK's I/O (nck/nck_io.py) share.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from typing import Any

from nckemu.errors import NckConfigError

DIGITAL_POINTS = 64
ANALOG_POINTS = 8
DATA_BYTES = 1024
DATA_LAYOUT = {"$A_DBB": ">B", "$A_DBW": ">h", "$A_DBD": ">i", "$A_DBR": ">f"}
# what the PLC may set: the NCK's inputs and the data area (the outputs are the program's)
SETTABLE = frozenset({"$A_IN", "$A_INA", *DATA_LAYOUT})
_POINT = re.compile(r"\s*(\$A_[A-Z]+)\s*\[\s*(\d+)\s*\]\s*", re.IGNORECASE)

Point = tuple[str, int, float]   # ("$A_IN", 24, 1.0)


def point_range(name: str) -> tuple[int, int]:
    """The indices ``name[i]`` has: 1..points for the inputs and outputs, byte offsets for the data area."""
    layout = DATA_LAYOUT.get(name)
    if layout is not None:
        return 0, DATA_BYTES - struct.calcsize(layout)
    return 1, ANALOG_POINTS if name in ("$A_INA", "$A_OUTA") else DIGITAL_POINTS


@dataclass(frozen=True)
class PlcAnswer:
    """One ``[[nck_io.answer]]``: its trigger (an M function ``m``, or ``$A_OUT[out]`` set to ``value``),
    the points it sets and how long after the trigger."""

    sets: tuple[Point, ...]
    after_s: float = 0.0
    m: int | None = None
    out: int | None = None
    value: float = 1.0


@dataclass(frozen=True)
class NckIoSettings:
    initial: tuple[Point, ...] = ()
    answers: tuple[PlcAnswer, ...] = ()


def _points(table: Any, field: str, source: str) -> tuple[Point, ...]:
    if not isinstance(table, dict):
        raise NckConfigError('expected a table { "$A_IN[n]" = value, ... }', path=source, field=field)
    points = []
    for key, value in table.items():
        match = _POINT.fullmatch(str(key))
        name = match.group(1).upper() if match else ""
        if name not in SETTABLE:
            raise NckConfigError(f"{key!r}: expected $A_IN[n], $A_INA[n] or $A_DBB/$A_DBW/$A_DBD/$A_DBR[byte]",
                                 path=source, field=field)
        index = int(match.group(2))  # type: ignore[union-attr]
        low, high = point_range(name)
        if not low <= index <= high:
            raise NckConfigError(f"{key!r}: {name} has {low}..{high}", path=source, field=field)
        if isinstance(value, bool):
            value = int(value)
        if not isinstance(value, int | float):
            raise NckConfigError(f"{key!r} = {value!r}: expected a number", path=source, field=field)
        points.append((name, index, float(value)))
    return tuple(points)


def _answer(table: Any, index: int, source: str) -> PlcAnswer:
    where = f"nck_io.answer[{index}]."
    if not isinstance(table, dict):
        raise NckConfigError("expected a table", path=source, field=where.rstrip("."))
    unknown = sorted(set(table) - {"m", "out", "value", "set", "after_s"})
    if unknown:
        raise NckConfigError("unknown key (known: after_s, m, out, set, value)", path=source, field=where + unknown[0])
    m, out = table.get("m"), table.get("out")
    if (m is None) == (out is None):
        raise NckConfigError("an answer has one trigger: m (an M function) or out ($A_OUT[n])", path=source,
                             field=where + "m")
    for key, value, high in (("m", m, 2**31 - 1), ("out", out, DIGITAL_POINTS)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= high):
            raise NckConfigError(f"expected a whole number 0..{high}, got {value!r}", path=source, field=where + key)
    after_s = table.get("after_s", 0.0)
    if isinstance(after_s, bool) or not isinstance(after_s, int | float) or not 0.0 <= after_s <= 86400.0:
        raise NckConfigError(f"expected seconds 0..86400, got {after_s!r}", path=source, field=where + "after_s")
    value = table.get("value", 1)
    if isinstance(value, bool):
        value = int(value)
    if not isinstance(value, int | float):
        raise NckConfigError(f"expected 0 or 1, got {value!r}", path=source, field=where + "value")
    sets = _points(table.get("set", {}), where + "set", source)
    if not sets:
        raise NckConfigError("an answer sets at least one point", path=source, field=where + "set")
    return PlcAnswer(sets, float(after_s), m, out, float(value))


def parse_nck_io(table: Any, source: str) -> NckIoSettings:
    """The machine file's ``[nck_io]`` table (raises NckConfigError naming the field)."""
    if not isinstance(table, dict):
        raise NckConfigError("expected a table", path=source, field="nck_io")
    unknown = sorted(set(table) - {"initial", "answer"})
    if unknown:
        raise NckConfigError("unknown key (known: answer, initial)", path=source, field=f"nck_io.{unknown[0]}")
    answers = table.get("answer", [])
    if not isinstance(answers, list):
        raise NckConfigError("expected [[nck_io.answer]] rows", path=source, field="nck_io.answer")
    return NckIoSettings(_points(table.get("initial", {}), "nck_io.initial", source),
                         tuple(_answer(row, index, source) for index, row in enumerate(answers)))
