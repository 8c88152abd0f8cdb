"""Several client processes at once: nothing lost, nothing torn (the short version of the soak)."""

from __future__ import annotations

from bench.load_consistency import run_load
from nckemu.emulator.runner import EmulatorThread


def test_concurrent_processes_lose_and_tear_nothing() -> None:
    with EmulatorThread() as emu:
        result = run_load(emu.port, clients=6, ops=150)
    assert result["lost"] == 0 and result["torn"] == 0
    assert result["shared_is_a_last_write"] == 1.0
