"""Run an emulator server on a background event loop: for sync code, tests and benchmarks."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable, Coroutine
from concurrent.futures import Future
from pathlib import Path
from typing import Any, TypeVar

from nckemu.emulator.faces.s7.server import EmulatorServer, ServerLimits
from nckemu.emulator.faces.s7.session import SessionLimits
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import Machine

T = TypeVar("T")


class EmulatorThread:
    """``with EmulatorThread() as emu: snap7.Client().connect(emu.host, 0, 4, emu.port)``."""

    def __init__(self, machine: Machine | str | Path | None = None, *, host: str = "127.0.0.1",
                 port: int = 0, state_path: str | Path | None = None,
                 record_path: str | Path | None = None, limits: ServerLimits | None = None,
                 session_limits: SessionLimits | None = None, emulator: Emulator | None = None) -> None:
        self.emulator = emulator or Emulator(machine, state_path=state_path)
        self.host = host
        self.server = EmulatorServer(self.emulator, host=host, port=port, limits=limits,
                                     session_limits=session_limits, record_path=record_path)
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._run, name="nckemu-server", daemon=True)
        self._started = threading.Event()
        self._error: BaseException | None = None

    @property
    def port(self) -> int:
        return self.server.port

    @property
    def nck(self) -> Any:
        return self.emulator.nck

    @property
    def plc(self) -> Any:
        return self.emulator.plc

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self.server.start())
        except BaseException as exc:  # reported to the starting thread
            self._error = exc
            self._started.set()
            return
        self._started.set()
        self._loop.run_forever()
        self._loop.run_until_complete(self._loop.shutdown_asyncgens())
        self._loop.close()

    def start(self) -> EmulatorThread:
        self._thread.start()
        self._started.wait()
        if self._error is not None:
            raise self._error
        return self

    def call(self, func: Callable[[], T]) -> T:
        """Run ``func`` on the server's loop (model access without racing the server)."""
        future: Future[T] = Future()

        def run() -> None:
            try:
                future.set_result(func())
            except BaseException as exc:
                future.set_exception(exc)

        self._loop.call_soon_threadsafe(run)
        return future.result(timeout=30)

    def run(self, coroutine: Coroutine[Any, Any, T]) -> T:
        """Await ``coroutine`` on the server's loop (start another face, e.g. the live page, beside it)."""
        return asyncio.run_coroutine_threadsafe(coroutine, self._loop).result(timeout=30)

    def stop(self) -> None:
        if not self._thread.is_alive():
            return
        stopped = asyncio.run_coroutine_threadsafe(self.server.stop(), self._loop)
        stopped.result(timeout=30)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=30)

    def __enter__(self) -> EmulatorThread:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
