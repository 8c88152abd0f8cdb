"""A controller's PLC inputs, mirrored for a PLC program that runs elsewhere (awlsim).

A PIW read in the PLC cycle must not wait on the network. The mirror answers from its copy and
refreshes every input range the program has read in the background, once per cycle; only the very
first read of a range waits for the controller.
"""

from __future__ import annotations

import concurrent.futures
import logging
from typing import Any

from nckemu.errors import NckError
from nckemu.protocol.addresses import S7Area

log = logging.getLogger(__name__)


class InputMirror:
    def __init__(self, client: Any, timeout_s: float = 5.0) -> None:
        self.client = client
        self.timeout_s = timeout_s
        self._values: dict[tuple[int, int], bytes] = {}
        self._refresh: concurrent.futures.Future[list[bytes]] | None = None
        self._refreshing: list[tuple[int, int]] = []
        self.failures = 0

    def read(self, offset: int, size: int) -> bytes:
        key = (offset, size)
        value = self._values.get(key)
        if value is None:
            try:
                value = self.client.plc_read(S7Area.I, 0, offset, size)
            except (NckError, concurrent.futures.TimeoutError) as exc:
                log.warning("input bytes %d..%d: %s; the program sees zeros", offset, offset + size - 1, exc)
                self.failures += 1
                value = bytes(size)
            self._values[key] = value
        return value

    def refresh(self) -> None:
        """Take the last background read if it has finished, and start the next one."""
        if self._refresh is not None:
            if not self._refresh.done():
                return
            try:
                for key, value in zip(self._refreshing, self._refresh.result(), strict=True):
                    self._values[key] = value
            except NckError as exc:
                self.failures += 1
                log.warning("input refresh failed (%s); the program keeps the last values", exc)
            self._refresh = None
        if self._values:
            self._refreshing = list(self._values)
            self._refresh = self.client.submit(self._read_all(self._refreshing))

    async def _read_all(self, keys: list[tuple[int, int]]) -> list[bytes]:
        return [await self.client.async_client.plc_read(S7Area.I, 0, offset, size) for offset, size in keys]
