"""Typed addresses: the vocabulary every layer shares (no bytes here; codecs are in s7.py).

An NCK variable is addressed as on the wire with syntax ID 0x82 (Wireshark: "NCK"): area (3 bits)
and unit (5 bits), column, line, module (block type) and line count. PLC memory is addressed with
S7ANY (syntax ID 0x10).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum


class SyntaxId(IntEnum):
    S7ANY = 0x10
    NCK = 0x82
    NCK_M = 0x83  # metric units
    NCK_I = 0x84  # inch units
    DRIVEESANY = 0xA2
    DBREAD = 0xB0


NCK_SYNTAX_IDS = frozenset({SyntaxId.NCK, SyntaxId.NCK_M, SyntaxId.NCK_I})


class NckArea(IntEnum):
    """NCK areas, the top 3 bits of the area/unit byte (letters as in NCVar selector)."""

    N = 0  # NCK
    B = 1  # mode group
    C = 2  # channel
    A = 3  # axis
    T = 4  # tool
    V = 5  # feed drive
    H = 6  # main drive (Wireshark labels it "M - Main drive")
    M = 7  # MMC


AREA_NAMES_WIRESHARK: dict[int, str] = {
    0: "N - NCK",
    1: "B - Mode group",
    2: "C - Channel",
    3: "A - Axis",
    4: "T - Tool",
    5: "V - Feed drive",
    6: "M - Main drive",
    7: "M - MMC",
}

# Drive areas carry their values big-endian; all other NCK areas little-endian.
BIG_ENDIAN_AREAS = frozenset({NckArea.V, NckArea.H})


class NckType(IntEnum):
    """The NCVar selector's ``typ`` byte. Client-side only: it sizes and decodes, it is never sent."""

    BOOL = 0x01
    BYTE = 0x03  # also CHAR
    WORD = 0x04
    INT = 0x05
    DWORD = 0x06
    DINT = 0x07
    REAL4 = 0x08
    REAL8 = 0x0F
    INT64 = 0x12
    STRING = 0x13

    @property
    def size_bytes(self) -> int | None:
        """Bytes per value; None for STRING, whose size is the NCVar selector's ``laenge``."""
        return _TYPE_SIZES[self]


_TYPE_SIZES: dict[NckType, int | None] = {
    NckType.BOOL: 1,
    NckType.BYTE: 1,
    NckType.WORD: 2,
    NckType.INT: 2,
    NckType.DWORD: 4,
    NckType.DINT: 4,
    NckType.REAL4: 4,
    NckType.REAL8: 8,
    NckType.INT64: 8,
    NckType.STRING: None,
}


@dataclass(frozen=True, slots=True)
class NckAddress:
    """One NCK item as sent on the wire (10 bytes: ``12 08 82 AU COL COL LIN LIN MOD CNT``)."""

    area: int
    unit: int
    column: int
    line: int
    module: int
    line_count: int = 1
    syntax_id: int = SyntaxId.NCK

    def __post_init__(self) -> None:
        for name, value, top in (
            ("area", self.area, 7), ("unit", self.unit, 31), ("column", self.column, 0xFFFF),
            ("line", self.line, 0xFFFF), ("module", self.module, 0xFF),
            ("line_count", self.line_count, 0xFF), ("syntax_id", self.syntax_id, 0xFF),
        ):
            if not 0 <= value <= top:
                raise ValueError(f"NckAddress.{name} = {value} is outside 0..{top}")

    @classmethod
    def from_wire(cls, syntax_id: int, area_unit: int, column: int, line: int, module: int,
                  line_count: int) -> NckAddress:
        """From fields unpacked off the wire: in range by construction, so not checked again."""
        address = object.__new__(cls)
        set_field = object.__setattr__
        set_field(address, "area", area_unit >> 5)
        set_field(address, "unit", area_unit & 0x1F)
        set_field(address, "column", column)
        set_field(address, "line", line)
        set_field(address, "module", module)
        set_field(address, "line_count", line_count)
        set_field(address, "syntax_id", syntax_id)
        return address

    @property
    def area_unit(self) -> int:
        """The packed byte, ``area << 5 | unit`` (NCVar selector: bereich_u_einheit)."""
        return (self.area << 5) | self.unit

    @classmethod
    def from_area_unit(cls, area_unit: int, column: int, line: int, module: int,
                       line_count: int = 1, syntax_id: int = SyntaxId.NCK) -> NckAddress:
        return cls(area_unit >> 5, area_unit & 0x1F, column, line, module, line_count, syntax_id)

    def __str__(self) -> str:
        area = NckArea(self.area).name
        return (f"NCK {area}{self.unit} col {self.column} line {self.line} "
                f"module 0x{self.module:02X} x{self.line_count}")


class S7Area(IntEnum):
    """S7ANY memory areas (byte 8 of an S7ANY item)."""

    SYSINFO = 0x03
    SYSFLAGS = 0x05
    ANAIN = 0x06
    ANAOUT = 0x07
    P = 0x80  # peripheral (direct I/O, e.g. PIW 420)
    I = 0x81  # inputs (PE)  # noqa: E741
    Q = 0x82  # outputs (PA)
    M = 0x83  # flags / markers (MK)
    DB = 0x84
    DI = 0x85  # instance DB
    L = 0x86  # local data
    V = 0x87
    C = 0x1C  # counters
    T = 0x1D  # timers


class S7TransportSize(IntEnum):
    """Parameter-item transport sizes of S7ANY items."""

    BIT = 0x01
    BYTE = 0x02
    CHAR = 0x03
    WORD = 0x04
    INT = 0x05
    DWORD = 0x06
    DINT = 0x07
    REAL = 0x08
    COUNTER = 0x1C
    TIMER = 0x1D


@dataclass(frozen=True, slots=True)
class S7AnyAddress:
    """An S7ANY item (syntax ID 0x10): ``12 0A 10 TS CNT CNT DB DB AREA ADDR ADDR ADDR``."""

    transport_size: int
    count: int
    db_number: int
    area: int
    byte_address: int
    bit_address: int = 0

    def __post_init__(self) -> None:
        for name, value, top in (
            ("transport_size", self.transport_size, 0xFF), ("count", self.count, 0xFFFF),
            ("db_number", self.db_number, 0xFFFF), ("area", self.area, 0xFF),
            ("byte_address", self.byte_address, 0x1FFFFF), ("bit_address", self.bit_address, 7),
        ):
            if not 0 <= value <= top:
                raise ValueError(f"S7AnyAddress.{name} = {value} is outside 0..{top}")


@dataclass(frozen=True, slots=True)
class UnsupportedAddress:
    """An item whose envelope parsed but whose syntax ID we do not serve (answered per item)."""

    var_spec: int
    syntax_id: int
    raw: bytes


Address = NckAddress | S7AnyAddress | UnsupportedAddress
