"""How a companion model's variable is fed from the machine (``Feed``), and its entry among the face's
monitored items (``FedMonitored``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from asyncua import ua
from asyncua.server.address_space import NodeData


@dataclass
class Feed:
    """How a fed variable gets its value: ``reader()`` gives a raw value (cheap to compare), ``variant``
    turns it into the value; ``realm`` is the SINUMERIK realm whose Read right it needs (None: anyone)."""

    reader: Callable[[], object]
    variant: Callable[[object], ua.Variant]
    realm: str | None = None
    # PLC memory it reads, (area, DB number, first byte, end byte): PLC writes there capture it at write
    # time; None: an NC value (NC writes capture it)
    plc: tuple[int, int, int, int] | None = None


class FedMonitored:
    """A monitored fed variable, in the shape the face's capture and push expect (``face._Monitored``)."""

    __slots__ = ("node", "name", "reader", "raw", "nc", "block", "first_byte", "end_byte", "_variant")

    def __init__(self, node: NodeData, feed: Feed) -> None:
        self.node, self.name, self.reader, self._variant = node, None, feed.reader, feed.variant
        try:
            self.raw: object = feed.reader()
        except Exception:  # read errors are the client's to see on its reads
            self.raw = None
        self.nc = feed.plc is None   # NC writes capture it
        self.block: tuple[int, int] | None = None
        self.first_byte = self.end_byte = 0
        if feed.plc is not None:     # PLC writes to these bytes capture it
            area, db, self.first_byte, self.end_byte = feed.plc
            self.block = (area, db)

    def to_variant(self, raw: object) -> ua.Variant:
        return self._variant(raw)
