"""The retained-state file on a disk that fills up: a short write is finished or refused, never left
as a truncated file in place of the good one (found by the full-disk test of issue 34)."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path
from typing import Any

import pytest

from nckemu.emulator.machine.state import RetainedStore


def test_short_writes_are_finished(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real_write = os.write
    monkeypatch.setattr(os, "write", lambda fd, data: real_write(fd, bytes(data[:7])))  # 7 bytes a call
    store = RetainedStore(tmp_path / "state.json")
    store.save({"values": list(range(100))})
    assert store.load() == {"values": list(range(100))}


def test_a_full_disk_leaves_the_old_file_and_no_temporary(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    store = RetainedStore(tmp_path / "state.json")
    store.save({"kept": 1})
    real_write = os.write
    calls: list[int] = []

    def filling(fd: int, data: Any) -> int:
        calls.append(len(data))
        if len(calls) == 1:
            return real_write(fd, bytes(data[:10]))  # what fits
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "write", filling)
    with pytest.raises(OSError):
        store.save({"kept": 2, "big": "x" * 1000})
    monkeypatch.undo()
    assert json.loads((tmp_path / "state.json").read_text()) == {"kept": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.json"]
