"""The user's STL program drives the channel (issue 41): FB4 PI_SERV selects a part program, DB21.DBX7.1
starts it, DB21.DBB35 tells the program it runs and ends, all on the emulator's clock."""

from __future__ import annotations

import asyncio

from nckemu.emulator.faces.s7.server import EmulatorServer
from nckemu.emulator.machine.clock import LiveClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.nck.channel import CHAN_RESET
from nckemu.plcsim.live import LiveMachine
from tests.conftest import FIXTURES

PROGRAM = FIXTURES / "plc" / "select_start.awl"
SHORT = FIXTURES / "programs" / "SHORT.MPF"


async def test_stl_program_selects_through_fb4_and_starts_through_db21() -> None:
    emulator = Emulator(clock=LiveClock())
    emulator.nck.programs.write("/_N_MPF_DIR/_N_SHORT_MPF", SHORT.read_bytes())
    channel = emulator.nck.channels[1]
    changes: list[str] = []
    channel.on_change.append(changes.append)
    server = EmulatorServer(emulator, port=0)
    await server.start()
    live = LiveMachine(emulator, plc=PROGRAM, speed=100.0, server=server, cycle_s=0.5)
    try:
        await live.start()
        assert live.runner is not None
        for _ in range(200):
            await asyncio.sleep(0.05)
            if live.runner.flags()[30] & 0x02:
                break
        flags = live.runner.flags()[30]
    finally:
        await live.stop()
        await server.stop()
    assert changes == ["selected", "started", "ended"]
    assert channel.selected == "/_N_MPF_DIR/_N_SHORT_MPF" and channel.state.status == CHAN_RESET
    assert flags & 0x03 == 0x03, "the program saw DB21.DBX35.0 (running) and then DBX35.7 (reset)"
    assert channel.state.actual_parts == 1.0
    assert live.runner.log.pi_calls[0].values["service"] == "_N_SELECT"
