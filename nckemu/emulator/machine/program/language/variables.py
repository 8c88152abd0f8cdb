"""Typed program variables (DEF INT/REAL/BOOL/STRING/CHAR/AXIS), scalars and arrays up to three
dimensions, and the conversions an assignment makes."""

from __future__ import annotations

from typing import Any

from ..motions import ProgramAlarm
from .alarms import ALARM_INDEX, ALARM_TYPE
from .expressions import number, round_half_away, to_text, truth

TYPES = ("INT", "REAL", "BOOL", "STRING", "CHAR", "AXIS")
MAX_STRING_CHARS = 200
MAX_ARRAY_ELEMENTS = 1_000_000


def default_value(kind: str) -> Any:
    if kind == "INT":
        return 0
    if kind == "REAL":
        return 0.0
    if kind == "BOOL":
        return False
    return ""


def convert(kind: str, value: Any, name: str) -> Any:
    """``value`` as a variable of type ``kind`` holds it (REAL -> INT rounds half away from zero)."""
    if kind == "REAL":
        if value.__class__ is float:
            return value
        return float(number(value))
    if kind == "INT":
        if value.__class__ is int:
            return value
        value = number(value)
        return value if value.__class__ is int else round_half_away(value)
    if kind == "BOOL":
        if value.__class__ is str:
            raise ProgramAlarm(ALARM_TYPE, f"{name}: a STRING is not a BOOL")
        return truth(value)
    if kind == "STRING":
        return to_text(value)
    if kind == "CHAR":
        if value.__class__ is str:
            return value[:1]
        return chr(int(number(value)) & 0xFF)
    if kind == "AXIS":
        return to_text(value).upper()
    raise ProgramAlarm(ALARM_TYPE, f"{name}: type {kind} not supported")


class Variable:
    """One DEF'd name: a scalar (``dims`` empty) or a row-major array."""

    __slots__ = ("name", "kind", "dims", "value")

    def __init__(self, name: str, kind: str, dims: tuple[int, ...] = ()) -> None:
        self.name = name
        self.kind = kind
        self.dims = dims
        if dims:
            size = 1
            for dim in dims:
                size *= dim
            if size > MAX_ARRAY_ELEMENTS or size <= 0:
                raise ProgramAlarm(ALARM_INDEX, f"{name}: array size {dims} not allowed")
            self.value: Any = [default_value(kind)] * size
        else:
            self.value = default_value(kind)

    def flat_index(self, indices: tuple[Any, ...]) -> int:
        if not self.dims:
            raise ProgramAlarm(ALARM_INDEX, f"{self.name} is not an array")
        if len(indices) != len(self.dims):
            raise ProgramAlarm(ALARM_INDEX, f"{self.name} has {len(self.dims)} index(es)")
        flat = 0
        for index, dim in zip(indices, self.dims, strict=True):
            if index.__class__ is str:
                raise ProgramAlarm(ALARM_INDEX, f"{self.name}[{index}]: an index is a number")
            position = number(index)
            if position.__class__ is float:
                position = round_half_away(position)
            if not 0 <= position < dim:
                raise ProgramAlarm(ALARM_INDEX, f"{self.name}: index {position} outside 0..{dim - 1}")
            flat = flat * dim + position
        return flat

    def get(self, indices: tuple[Any, ...] = ()) -> Any:
        if not indices:
            if self.dims:
                raise ProgramAlarm(ALARM_INDEX, f"{self.name} is an array: give an index")
            return self.value
        return self.value[self.flat_index(indices)]

    def set(self, indices: tuple[Any, ...], value: Any) -> None:
        converted = convert(self.kind, value, self.name)
        if not indices:
            if self.dims:
                raise ProgramAlarm(ALARM_INDEX, f"{self.name} is an array: give an index")
            self.value = converted
        else:
            self.value[self.flat_index(indices)] = converted

    def fill(self, indices: tuple[Any, ...], values: list[Any], repeat: bool) -> None:
        """SET(...) from ``indices`` on (or REP(x) to the end)."""
        if not self.dims:
            if len(values) != 1:
                raise ProgramAlarm(ALARM_INDEX, f"{self.name} is not an array")
            self.set((), values[0])
            return
        start = self.flat_index(indices) if indices else 0
        size = len(self.value)
        if repeat:
            converted = convert(self.kind, values[0], self.name)
            for position in range(start, size):
                self.value[position] = converted
            return
        if start + len(values) > size:
            raise ProgramAlarm(ALARM_INDEX, f"{self.name}: {len(values)} values do not fit")
        for offset, item in enumerate(values):
            self.value[start + offset] = convert(self.kind, item, self.name)
