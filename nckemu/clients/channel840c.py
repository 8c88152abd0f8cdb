"""Channel840C: write a temperature-compensation user DB and start DB41 function 9 (840C/880).

The DB41 handshake is the emulator's documented assumption (``nckemu.protocol.db41``); the user
DB layout is ``nckemu.protocol.c840`` with its word-order and flag-bit settings.
"""

from __future__ import annotations

import asyncio
import time

from nckemu.errors import NckError, NckTimeoutError
from nckemu.protocol import c840, db41

from .async_client import AsyncNckClient


class Channel840CError(NckError):
    """The NC refused a command-channel job; ``error_number`` is what DB41 reported."""

    def __init__(self, error_number: int) -> None:
        try:
            text = db41.ChannelError(error_number).name.lower().replace("_", " ")
        except ValueError:
            text = "unknown error"
        super().__init__(f"840C command channel: error {error_number} ({text})")
        self.error_number = error_number


class Channel840C:
    """Per axis: ``await Channel840C(client, user_db=131).send(axis=3, k_tcabs_mm=..., ...)``."""

    def __init__(self, client: AsyncNckClient, *, user_db: int = 131, data_word: int = 0,
                 layout: c840.C840Layout | None = None, timeout_s: float = 5.0, poll_s: float = 0.01) -> None:
        self.client = client
        self.user_db = user_db
        self.data_word = data_word
        self.layout = layout or c840.C840Layout()
        self.timeout_s = timeout_s
        self.poll_s = poll_s

    async def send(self, axis: int, k_tcabs_mm: float, tan_beta: float, p0_mm: float,
                   position_independent: bool = True, position_dependent: bool = True) -> None:
        user = c840.TempCompUserDb.from_engineering(axis, k_tcabs_mm, tan_beta, p0_mm, position_independent,
                                                    position_dependent, self.layout)
        await self.send_user_db(c840.build_user_db(user, self.layout))

    async def send_user_db(self, user_db_bytes: bytes) -> None:
        await self.client.db_write(self.user_db, 2 * self.data_word, user_db_bytes)
        # Clear DONE/ERROR of the previous job, then raise REQUEST with the job's parameters.
        await self.client.db_write(db41.CHANNEL_DB, 0, db41.build_request(self.user_db, self.data_word,
                                                                           request=False))
        await self.client.db_write(db41.CHANNEL_DB, 0, db41.build_request(self.user_db, self.data_word))
        deadline = time.monotonic() + self.timeout_s
        while True:
            status = db41.parse_status(await self.client.db_read(db41.CHANNEL_DB, 0, db41.CHANNEL_BYTES))
            if status.error:
                raise Channel840CError(status.error_number)
            if status.done:
                return
            if time.monotonic() > deadline:
                raise NckTimeoutError(f"DB41 function 9: no acknowledgement within {self.timeout_s} s")
            await asyncio.sleep(self.poll_s)
