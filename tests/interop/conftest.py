"""Fixtures the interop tests share: a real emulator on 127.0.0.1 with a free port."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from nckemu.emulator.runner import EmulatorThread


@pytest.fixture
def emulator() -> Iterator[EmulatorThread]:
    """The built-in default machine; a test module may override it (e.g. with other limits)."""
    with EmulatorThread() as emu:
        yield emu
