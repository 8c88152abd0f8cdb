"""SINUMERIK 840C temperature-compensation user DB, handed to the NC by DB41 function 9.

Eight data words per axis (S5 data word n is bytes 2n..2n+1 of an S7 DB, big-endian):
  DW n      length in words, always 7 (KF)
  DW n+1    left byte DL: activation flags U (position independent) and A (position dependent);
            right byte DR: axis number 1..30
  DW n+2/3  K_TCabs, 32-bit signed, measuring-system units
  DW n+4/5  tan(beta), 32-bit signed with weight 2^-31 (30 degrees -> 0x49E69D16)
  DW n+6/7  P0, 32-bit signed, measuring-system units
The sources do not settle which word of a pair comes first nor which DL bits U and A are:
``C840Layout`` makes both parameters (default: high word first, as the 880 figure labels it and S5
double words are; U = bit 15 and A = bit 14, U left of A as the figures show).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from .errors import NckProtocolError

USER_DB_WORDS = 8
USER_DB_BYTES = 2 * USER_DB_WORDS
LENGTH_WORDS = 7
MAX_UNITS = 1_073_741_823
TAN_BETA_SCALE = 2**31 - 1
TAN_BETA_MIN = -(2**31)


class C840FormatError(NckProtocolError):
    """A user DB the 840C would refuse; ``data_word`` is the offending word (n + k)."""

    def __init__(self, message: str, data_word: int) -> None:
        super().__init__(f"DW n+{data_word}: {message}" if data_word else f"DW n: {message}")
        self.data_word = data_word


@dataclass(frozen=True)
class C840Layout:
    high_word_first: bool = True
    u_bit: int = 15
    a_bit: int = 14
    resolution_mm: float = 0.001

    def __post_init__(self) -> None:
        if not (8 <= self.u_bit <= 15 and 8 <= self.a_bit <= 15) or self.u_bit == self.a_bit:
            raise ValueError("U and A are two different bits of the left byte DL (bits 8..15)")
        if self.resolution_mm <= 0:
            raise ValueError("resolution_mm must be positive")


@dataclass(frozen=True)
class TempCompUserDb:
    axis: int
    position_independent: bool
    position_dependent: bool
    k_tcabs_units: int
    tan_beta_raw: int
    p0_units: int

    @classmethod
    def from_engineering(cls, axis: int, k_tcabs_mm: float, tan_beta: float, p0_mm: float,
                         position_independent: bool = True, position_dependent: bool = True,
                         layout: C840Layout = C840Layout()) -> TempCompUserDb:
        if abs(tan_beta) > 1.0:
            raise C840FormatError(f"|tan beta| = {abs(tan_beta)} > 1", 4)
        return cls(axis, position_independent, position_dependent,
                   round(k_tcabs_mm / layout.resolution_mm), round(tan_beta * TAN_BETA_SCALE),
                   round(p0_mm / layout.resolution_mm))

    def k_tcabs_mm(self, layout: C840Layout = C840Layout()) -> float:
        return self.k_tcabs_units * layout.resolution_mm

    @property
    def tan_beta(self) -> float:
        # 0x80000000 is exactly -1 (weight 2^-31); +1 is 0x7FFFFFFF, one unit short (issue 14 2.10).
        if self.tan_beta_raw == TAN_BETA_MIN:
            return -1.0
        return self.tan_beta_raw / TAN_BETA_SCALE

    def p0_mm(self, layout: C840Layout = C840Layout()) -> float:
        return self.p0_units * layout.resolution_mm


def _split(value: int, high_first: bool) -> tuple[int, int]:
    raw = value & 0xFFFFFFFF
    high, low = raw >> 16, raw & 0xFFFF
    return (high, low) if high_first else (low, high)


def _join(first: int, second: int, high_first: bool) -> int:
    high, low = (first, second) if high_first else (second, first)
    raw = (high << 16) | low
    return raw - (1 << 32) if raw & 0x80000000 else raw


def build_user_db(db: TempCompUserDb, layout: C840Layout = C840Layout()) -> bytes:
    if not 1 <= db.axis <= 30:
        raise C840FormatError(f"axis {db.axis} outside 1..30", 1)
    for value, word in ((db.k_tcabs_units, 2), (db.p0_units, 6)):
        if abs(value) > MAX_UNITS:
            raise C840FormatError(f"{value} outside +-{MAX_UNITS}", word)
    if not TAN_BETA_MIN <= db.tan_beta_raw <= TAN_BETA_SCALE:
        raise C840FormatError("|tan beta| > 1", 4)
    flags = (db.position_independent << layout.u_bit) | (db.position_dependent << layout.a_bit)
    words = [LENGTH_WORDS, flags | db.axis]
    for value in (db.k_tcabs_units, db.tan_beta_raw, db.p0_units):
        words.extend(_split(value, layout.high_word_first))
    return struct.pack(">8H", *words)


def parse_user_db(data: bytes, layout: C840Layout = C840Layout()) -> TempCompUserDb:
    if len(data) < USER_DB_BYTES:
        raise C840FormatError(f"user DB needs {USER_DB_BYTES} bytes, got {len(data)}",
                              len(data) // 2)
    words = struct.unpack(">8H", data[:USER_DB_BYTES])
    if words[0] != LENGTH_WORDS:
        raise C840FormatError(f"length word is {words[0]}, expected 7", 0)
    flag_mask = (1 << layout.u_bit) | (1 << layout.a_bit)
    dl_bits = words[1] & 0xFF00
    if dl_bits & ~flag_mask:
        raise C840FormatError(f"flag bits 0x{dl_bits & ~flag_mask:04X} set outside U and A", 1)
    axis = words[1] & 0xFF
    if not 1 <= axis <= 30:
        raise C840FormatError(f"axis number {axis} outside 1..30", 1)
    k_units = _join(words[2], words[3], layout.high_word_first)
    tan_raw = _join(words[4], words[5], layout.high_word_first)
    p0_units = _join(words[6], words[7], layout.high_word_first)
    if abs(k_units) > MAX_UNITS:
        raise C840FormatError(f"K_TCabs {k_units} outside +-{MAX_UNITS}", 2)
    if abs(p0_units) > MAX_UNITS:
        raise C840FormatError(f"P0 {p0_units} outside +-{MAX_UNITS}", 6)
    return TempCompUserDb(axis, bool(words[1] >> layout.u_bit & 1), bool(words[1] >> layout.a_bit & 1),
                          k_units, tan_raw, p0_units)
