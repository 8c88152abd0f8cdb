"""What the dispatcher needs of the NCK and the PLC (as asyncua's ``Node`` needs ``AbstractSession``).

Typed addresses and Python values in, typed errors out; no bytes. ``NckModel`` and ``PlcModel``
implement these; a test or another backend can too.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from datetime import datetime
from typing import Protocol

from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.protocol.addresses import NckAddress, NckType


class NckDatastore(Protocol):
    def variable_type(self, address: NckAddress) -> tuple[NckType, int | None]:
        """Type and string length of the variable at ``address`` (raises the item error if none)."""
        ...

    def read_typed(self, address: NckAddress, ctx: AccessContext) -> tuple[NckType, int | None, list[object]]:
        """Type, string length and the values of ``address.line_count`` lines."""
        ...

    def write(self, address: NckAddress, values: Sequence[object], ctx: AccessContext) -> bool:
        """True when retained data changed (the dispatcher persists before it answers)."""
        ...

    def pi_service(self, service: str, arguments: Sequence[str], ctx: AccessContext) -> None: ...


class PlcDatastore(Protocol):
    def read(self, area: int, db_number: int, start_byte: int, size_bytes: int) -> bytes: ...

    def reader(self, area: int, db_number: int, start_byte: int, size_bytes: int) -> Callable[[], bytes]:
        """A function reading those bytes now, resolved once (the read plans of polled jobs keep it)."""
        ...

    def write(self, area: int, db_number: int, start_byte: int, data: bytes) -> None: ...

    def read_bit(self, area: int, db_number: int, byte: int, bit: int) -> bool: ...

    def write_bit(self, area: int, db_number: int, byte: int, bit: int, value: bool) -> None: ...

    def szl(self, szl_id: int, szl_index: int) -> bytes:
        """The SZL answer's records (raises an NckError when the list is not available)."""
        ...

    def now(self) -> datetime:
        """The PLC's clock (userdata "read clock")."""
        ...

    def block_counts(self) -> dict[int, int]:
        """Blocks by type code (0x38 OB, 0x41 DB, ...) for userdata "list blocks"."""
        ...

    def plc_control(self, action: str) -> None:
        """"start" (PI P_PROGRAM) or "stop" (PLC stop job)."""
        ...
