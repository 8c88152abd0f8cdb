"""NckClient: the synchronous façade. One background event loop runs AsyncNckClient; every method
posts a coroutine to it and waits (the pattern of asyncua's sync module), so there is one copy of the
protocol code."""

from __future__ import annotations

import asyncio
import concurrent.futures
import threading
from collections.abc import Coroutine, Iterable, Mapping
from typing import Any, TypeVar

from nckemu.errors import NckConnectionError, NckTimeoutError
from nckemu.protocol import s7

from .async_client import AsyncNckClient, ItemResult

T = TypeVar("T")


class ClientLoop:
    """A daemon thread running one event loop; several clients may share one (``loop=``)."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, name="nckemu-client", daemon=True)
        self._thread.start()

    def run(self, coroutine: Coroutine[Any, Any, T], timeout_s: float | None = None) -> T:
        """Run ``coroutine`` on the loop and wait for it, at most ``timeout_s`` (the async client's own
        job timeout answers first; this one guards against a loop that no longer runs)."""
        if not self.loop.is_running() or self.loop.is_closed():
            coroutine.close()
            raise NckConnectionError("the client's event loop is not running (closed client?)")
        future = asyncio.run_coroutine_threadsafe(coroutine, self.loop)
        try:
            return future.result(timeout_s)
        except concurrent.futures.TimeoutError:
            future.cancel()
            raise NckTimeoutError(f"no result within {timeout_s} s") from None

    def stop(self) -> None:
        if self.loop.is_running():
            self.loop.call_soon_threadsafe(self.loop.stop)
            self._thread.join(timeout=5)
        if not self.loop.is_running():
            self.loop.close()


class NckClient:
    """``with NckClient("127.0.0.1", port=1102) as nck: nck.put({"SD43900[AX4]": 0.3})``."""

    def __init__(self, host: str, port: int = 102, *, rack: int = 0, slot: int = 4, timeout_s: float = 5.0,
                 plc_real32: bool = False, loop: ClientLoop | None = None) -> None:
        self._own_loop = loop is None
        self._thread = loop or ClientLoop()
        # Longer than any one job may take (connect plus a job, each bounded by timeout_s).
        self._wait_s = 3 * timeout_s + 5.0
        self._async = self._thread.run(self._make(host, port, rack, slot, timeout_s, plc_real32), self._wait_s)

    @staticmethod
    async def _make(host: str, port: int, rack: int, slot: int, timeout_s: float,
                    plc_real32: bool) -> AsyncNckClient:
        # Created on the loop thread: its asyncio.Lock belongs to that loop.
        return AsyncNckClient(host, port, rack=rack, slot=slot, timeout_s=timeout_s, plc_real32=plc_real32)

    @property
    def async_client(self) -> AsyncNckClient:
        return self._async

    @property
    def connected(self) -> bool:
        return self._async.connected

    def connect(self) -> NckClient:
        self._call(self._async.connect())
        return self

    def disconnect(self) -> None:
        self._call(self._async.disconnect())

    def reconnect(self) -> None:
        self._call(self._async.reconnect())

    def close(self) -> None:
        try:
            self.disconnect()
        finally:
            if self._own_loop:
                self._thread.stop()

    def __enter__(self) -> NckClient:
        try:
            return self.connect()
        except BaseException:
            self.close()  # a failed connect must not leak the loop thread
            raise

    def __exit__(self, *exc: object) -> None:
        self.close()

    def get(self, *items: object) -> list[Any]:
        return self._call(self._async.get(*items))

    def get_items(self, *items: object) -> list[ItemResult]:
        return self._call(self._async.get_items(*items))

    def put(self, values: Mapping[object, Any] | Iterable[tuple[object, Any]]) -> None:
        self._call(self._async.put(values))

    def put_items(self, values: Mapping[object, Any] | Iterable[tuple[object, Any]]) -> list[ItemResult]:
        return self._call(self._async.put_items(values))

    def pi_service(self, service: str, *arguments: str) -> None:
        self._call(self._async.pi_service(service, *arguments))

    def login(self, password: str) -> None:
        self._call(self._async.login(password))

    def db_read(self, db_number: int, start: int, size: int) -> bytes:
        return self._call(self._async.db_read(db_number, start, size))

    def db_write(self, db_number: int, start: int, data: bytes) -> None:
        self._call(self._async.db_write(db_number, start, data))

    def plc_read(self, area: int, db_number: int, start: int, size: int) -> bytes:
        return self._call(self._async.plc_read(area, db_number, start, size))

    def exchange(self, parameter: bytes, data: bytes = b"") -> s7.S7Pdu:
        return self._call(self._async.exchange(parameter, data))

    def _call(self, coroutine: Coroutine[Any, Any, T]) -> T:
        return self._thread.run(coroutine, self._wait_s)

    def submit(self, coroutine: Coroutine[Any, Any, T]) -> concurrent.futures.Future[T]:
        """Start a call without waiting (for PLC-cycle code that must not block)."""
        return asyncio.run_coroutine_threadsafe(coroutine, self._thread.loop)
