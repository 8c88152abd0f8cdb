"""The retained-state file on a disk that fills up: a short write is finished or refused, never left
as a truncated file in place of the good one (found by the full-disk test of issue 34)."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

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


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.permutations(list(range(1, 9))))
def test_the_newest_snapshot_stays_whatever_order_the_writes_end_in(tmp_path: Path, order: list[int]) -> None:
    """The loop and the saving thread may write in either order: an older snapshot never replaces a
    newer one."""
    store = RetainedStore(tmp_path / "state.json")
    for sequence in order:
        store.write(RetainedStore.encode({"sequence": sequence}), sequence)
        assert store.load() == {"sequence": max(order[:order.index(sequence) + 1])}


def test_a_value_json_cannot_spell_is_a_config_error_not_a_crash(tmp_path: Path) -> None:
    from nckemu.errors import NckConfigError

    with pytest.raises(NckConfigError, match="cannot be written as JSON"):
        RetainedStore.encode({"r": [float("nan")]})
