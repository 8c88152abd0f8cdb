"""The time left of a run (the live page's figure): the last complete run's net time of the same text
less this run's, unknown before one run has ended, afresh when the text changes or a run was reset."""

from __future__ import annotations

import pytest

from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.offline import run_offline
from nckemu.emulator.machine.status import machine_status

PATH = "/_N_MPF_DIR/_N_LEFT_MPF"
# 100 s of dwell and a move at feed (its time is whatever the planner says: the run measures it)
TEXT = b"G90 G94\nN10 G4 F40\nN20 G1 X50 F600\nN30 G4 F40\nN40 G0 X0\nM30\n"


def _step_to(emulator: Emulator, t_s: float) -> None:
    emulator.clock.set(t_s)  # type: ignore[attr-defined]
    emulator.step_machine(t_s)


def test_time_left_counts_down_from_the_last_complete_run() -> None:
    emulator = Emulator(clock=SimulatedClock())
    emulator.nck.programs.write(PATH, TEXT)
    channel = emulator.nck.channels[1]
    assert channel.time_left_s is None and channel.last_run_s is None  # nothing runs
    first = run_offline(emulator, PATH)
    assert first.outcome == "ended" and first.net_time_s > 80.0
    now = emulator.clock.now_s()
    channel.start()
    assert channel.last_run_s == pytest.approx(first.net_time_s)
    assert channel.time_left_s == pytest.approx(first.net_time_s)
    _step_to(emulator, now + 30.0)
    assert channel.time_left_s == pytest.approx(first.net_time_s - 30.0)
    document = machine_status(emulator)["channel"]
    assert document["time_left_s"] == pytest.approx(first.net_time_s - 30.0)
    assert document["selected"] == PATH and document["block_program"] == PATH
    assert document["line"] == 2 and document["block_number"] == "N10" and document["block"] == "N10 G4 F40"
    # a reset run is no complete run: the time stays the last complete one's
    channel.reset()
    assert channel.time_left_s is None
    channel.start()
    assert channel.time_left_s == pytest.approx(first.net_time_s)
    channel.reset()
    # another text is another program: unknown until it has ended once
    emulator.nck.programs.write(PATH, TEXT.replace(b"F40", b"F20"))
    channel.start()
    assert channel.time_left_s is None
    _step_to(emulator, emulator.clock.now_s() + 1000.0)
    assert channel.state.status == 0  # ended in reset
    channel.start()
    assert channel.time_left_s == pytest.approx(first.net_time_s - 40.0)


def test_time_left_never_below_zero() -> None:
    emulator = Emulator(clock=SimulatedClock())
    emulator.nck.programs.write(PATH, TEXT)
    channel = emulator.nck.channels[1]
    first = run_offline(emulator, PATH)
    channel.start()
    channel.state.feed_override_pct = 10.0  # this run is slower than the last: it overruns the estimate
    _step_to(emulator, emulator.clock.now_s() + first.net_time_s + 20.0)
    assert channel.state.status == 1 and channel.time_left_s == 0.0
