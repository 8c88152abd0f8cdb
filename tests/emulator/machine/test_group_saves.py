"""Retained writes saved off the event loop (machine/saves.py): an acknowledgement leaves only after
the file holding it was written; other clients are served while a save is under way; many writes
share one save; a failed save raises the alarm and still answers."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

import pytest

from nckemu.clients.async_client import AsyncNckClient
from nckemu.emulator.faces.s7.server import EmulatorServer
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.state import RetainedStore

SLOW_SAVE_S = 0.4


def slow_disk(monkeypatch: pytest.MonkeyPatch, seen: list[bytes] | None = None,
              fail: bool = False) -> None:
    original = RetainedStore._replace

    def replace(self: RetainedStore, data: bytes) -> None:
        time.sleep(SLOW_SAVE_S)  # in the saving thread: the event loop goes on
        if fail:
            raise OSError(28, "No space left on device")
        original(self, data)
        if seen is not None:
            seen.append(data)

    monkeypatch.setattr(RetainedStore, "_replace", replace)


async def test_an_acknowledged_write_is_on_disk_and_others_are_served_meanwhile(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    state = tmp_path / "state.json"
    slow_disk(monkeypatch)
    emulator = Emulator(state_path=state)
    server = await EmulatorServer(emulator, port=0).start()
    try:
        async with AsyncNckClient("127.0.0.1", server.port) as writer, \
                AsyncNckClient("127.0.0.1", server.port) as reader:
            started = time.perf_counter()
            write = asyncio.create_task(writer.put({"R5": 12.5}))
            reads = []
            while not write.done():
                asked = time.perf_counter()
                await reader.get("SD43900[AX4]")
                reads.append(time.perf_counter() - asked)
            await write
            acknowledged_after_s = time.perf_counter() - started
            on_disk = state.read_text()
    finally:
        await server.stop()
    assert acknowledged_after_s >= SLOW_SAVE_S, "the answer waited for the save"
    assert len(reads) >= 5 and max(reads) < SLOW_SAVE_S / 2, "the other client was served meanwhile"
    assert "12.5" in on_disk


async def test_many_writes_share_saves_and_each_is_on_disk_when_acknowledged(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    state = tmp_path / "state.json"
    written: list[bytes] = []
    slow_disk(monkeypatch, written)
    emulator = Emulator(state_path=state)
    server = await EmulatorServer(emulator, port=0).start()
    checked: list[bool] = []

    async def client(number: int) -> None:
        async with AsyncNckClient("127.0.0.1", server.port) as nck:
            for step in range(3):
                value = 1000.0 + number * 10.0 + step + 0.125
                await nck.put({f"R{number}": value})
                checked.append(any(f"{value}".encode() in data for data in written))

    try:
        await asyncio.gather(*(client(n) for n in range(8)))
    finally:
        await server.stop()
    assert checked == [True] * 24, "every acknowledged value was in a file written before the answer"
    assert emulator.saves.saves < 24, f"{emulator.saves.saves} saves for 24 writes: they were grouped"


async def test_a_failed_save_raises_the_alarm_and_still_answers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    state = tmp_path / "state.json"
    slow_disk(monkeypatch, fail=True)
    emulator = Emulator(state_path=state)
    server = await EmulatorServer(emulator, port=0).start()
    try:
        async with AsyncNckClient("127.0.0.1", server.port) as nck:
            await asyncio.wait_for(nck.put({"R1": 3.25}), 10)
            value, alarms = await nck.get("R1", "numAlarms")
            alarm = emulator.persist_alarm
    finally:
        monkeypatch.undo()
        await server.stop()  # its last save succeeds: the alarm goes
    assert value == 3.25 and alarms >= 1 and alarm is not None and "No space left" in alarm
    assert emulator.persist_alarm is None
