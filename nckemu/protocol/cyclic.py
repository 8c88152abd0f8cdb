"""Cyclic services (userdata group 2): an HMI subscribes items for cyclic or change-driven transfer,
and the CPU pushes their values under the job ID the subscription's response gave (the sequence
number of the parameter; tshark's "JobID").

Layout as Wireshark's s7comm dissector reads it, checked against the public WinCC/S7-400 capture
(iti ``wincc_s400_production.pcapng``): a subscription's data is the item count (16 bits), the interval
timebase and factor (one byte each) and the items as in a read job (``12 <length> <syntax id> ...``,
fill bytes after odd items); a response or push is the item count (16 bits) and read-answer data
items. WinCC subscribes with DBREAD items (syntax 0xB0): several DB areas in one item, each
``<bytes> <DB number BE16> <start BE16>``.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from .addresses import Address, UnsupportedAddress
from .errors import NckProtocolError, NckTruncatedError
from .s7 import DataItem, build_data_items, build_items, parse_data_items_at, parse_items_to_end

SUBFUNCTION_CYCLIC_TRANSFER = 0x01
SUBFUNCTION_UNSUBSCRIBE = 0x04
SUBFUNCTION_CHANGE_DRIVEN = 0x05
SUBFUNCTION_CHANGE_DRIVEN_MODIFY = 0x07
SUBSCRIBING = frozenset({SUBFUNCTION_CYCLIC_TRANSFER, SUBFUNCTION_CHANGE_DRIVEN, SUBFUNCTION_CHANGE_DRIVEN_MODIFY})
TIMEBASE_NAMES = {0: "0.1 s", 1: "1 s", 2: "10 s"}
SYNTAX_DBREAD = 0xB0


@dataclass(frozen=True, slots=True)
class CyclicSubscription:
    timebase: int
    factor: int
    items: tuple[Address, ...]

    @property
    def interval(self) -> str:
        base = TIMEBASE_NAMES.get(self.timebase, f"timebase {self.timebase}")
        return f"{self.factor} x {base}"


def parse_subscription(data: bytes) -> CyclicSubscription:
    if len(data) < 4:
        raise NckTruncatedError("cyclic subscription shorter than 4 bytes")
    count, timebase, factor = struct.unpack_from(">HBB", data)
    return CyclicSubscription(timebase, factor, parse_items_to_end(data, 4, count))


def build_subscription(subscription: CyclicSubscription) -> bytes:
    return struct.pack(">HBB", len(subscription.items), subscription.timebase, subscription.factor) \
        + build_items(subscription.items)


def parse_cyclic_data(data: bytes) -> tuple[DataItem, ...]:
    """A response's or push's values: item count (16 bits), then read-answer data items."""
    if len(data) < 2:
        raise NckTruncatedError("cyclic data shorter than 2 bytes")
    (count,) = struct.unpack_from(">H", data)
    items, end = parse_data_items_at(data, 2, count)
    if end != len(data):
        raise NckProtocolError(f"{len(data) - end} bytes after the cyclic data's {count} items")
    return items


def build_cyclic_data(items: tuple[DataItem, ...]) -> bytes:
    if len(items) > 0xFFFF:
        raise NckProtocolError("too many cyclic data items")
    return struct.pack(">H", len(items)) + build_data_items(items)


def dbread_areas(address: UnsupportedAddress) -> list[tuple[int, int, int]] | None:
    """(DB number, start byte, byte count) of each area of a DBREAD item; None for other items."""
    raw = address.raw
    if address.syntax_id != SYNTAX_DBREAD or len(raw) < 2 or (len(raw) - 2) != raw[1] * 5:
        return None
    areas = []
    for offset in range(2, len(raw), 5):
        count, db, start = struct.unpack_from(">BHH", raw, offset)
        areas.append((db, start, count))
    return areas


def describe_dbread(address: UnsupportedAddress) -> str | None:
    """``DB68.DBB358 x1, DB68.DBB394 x10`` for a DBREAD item."""
    areas = dbread_areas(address)
    if areas is None:
        return None
    return ", ".join(f"DB{db}.DBB{start} x{count}" for db, start, count in areas)
