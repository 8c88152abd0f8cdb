"""Fixtures the interop tests share: a real emulator on 127.0.0.1 with a free port."""

from __future__ import annotations

import logging
from collections.abc import Iterator

import pytest
import snap7

from nckemu.emulator.runner import EmulatorThread


@pytest.fixture
def emulator() -> Iterator[EmulatorThread]:
    """The built-in default machine; a test module may override it (e.g. with other limits)."""
    with EmulatorThread() as emu:
        yield emu


@pytest.fixture
def collector(emulator: EmulatorThread) -> Iterator[snap7.Client]:
    """python-snap7 with an 828D collector's TSAPs (IOT and LSC): calling 0x0400, called 0x0D04
    (connection type 0x0D, rack 0, slot 4 in python-snap7's encoding)."""
    logging.getLogger("snap7").setLevel(logging.WARNING)
    client = snap7.Client()
    client.local_tsap = 0x0400
    client.connection_type = 0x0D
    client.connect("127.0.0.1", 0, 4, emulator.port)
    yield client
    client.disconnect()
