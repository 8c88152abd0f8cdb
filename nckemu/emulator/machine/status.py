"""What a served machine is doing now, as one JSON-able dict (the live page, tests, logs).

Read from the model directly (no S7 job): axes with their commanded and actual positions and the
temperature compensation (SD43900/43910/43920 as written, the value applied), sensors with their PLC
words, the drives' motor and power unit temperatures (r0035, r0037[0]) with their load and power, spindles, channel 1's run state and parts, alarms, and the clients a face lists (the S7
connections with their job counts). Layers above the emulator add their parts through
``Emulator.status_sections``.
"""

from __future__ import annotations

from typing import Any, Protocol

from nckemu.emulator.machine.clock import LiveClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.nck.channel_states import PROG_ABORTED
from nckemu.errors import NckError
from nckemu.protocol.addresses import S7Area

_CHANNEL_STATUS = {0: "reset", 1: "active", 2: "interrupted"}
_PROGRAM_STATUS = {1: "interrupted", 2: "stopped", 3: "running", 4: "waiting", 5: "aborted"}
_OP_MODES = {0: "JOG", 1: "MDA", 2: "AUTOMATIC"}  # opMode of the mode group (catalogue/variables.toml)


def _value(read: Any, *args: Any) -> float | None:
    try:
        return float(read(*args))
    except (NckError, TypeError, ValueError):
        return None


class ClientList(Protocol):
    """A face that knows its connected clients (the S7 server: peer and jobs sent, one dict each)."""

    def clients(self) -> list[dict[str, object]]: ...


def machine_status(emulator: Emulator, server: ClientList | None = None) -> dict[str, Any]:
    nck, machine, clock = emulator.nck, emulator.machine, emulator.clock
    store = nck.store
    axes = []
    for axis in machine.axes:
        entry: dict[str, Any] = {"number": axis.number, "name": axis.name, "spindle": axis.spindle}
        if not axis.spindle:
            entry.update({
                "position_mm": _value(nck.axis_position_mm, axis.number),
                "actual_mm": _value(nck.actual_position_mm, axis.number),
                "tc_mm": _value(nck.tc_value_mm, axis.number),
                "sd43900_mm": _value(store.stored_value, "TEMP_COMP_ABS_VALUE", axis.number),
                "sd43910": _value(store.stored_value, "TEMP_COMP_SLOPE", axis.number),
                "sd43920_mm": _value(store.stored_value, "TEMP_COMP_REF_POSITION", axis.number),
                "md32750": _value(store.active_value, "TEMP_COMP_TYPE", axis.number),
            })
        axes.append(entry)
    sensors = []
    for sensor in machine.sensors:
        entry = {"name": sensor.name, "temperature_C": _value(nck.sensor_temperature_C, sensor.name),
                 "plc_input": sensor.plc_input, "raw": None}
        if sensor.plc_input:
            word = emulator.plc.read(S7Area.P, 0, int(sensor.plc_input[3:]), 2)
            entry["raw"] = int.from_bytes(word, "big", signed=True)
        sensors.append(entry)
    try:
        drives = nck.drives.temperatures_C(nck)
    except NckError:
        drives = []
    channel = nck.channels.get(1)
    channel_state: dict[str, Any] = {}
    spindles = []
    if channel is not None:
        state = channel.state
        mode_value = state.mode
        channel_state = {"mode": _OP_MODES.get(mode_value, str(mode_value)),
                         "status": _CHANNEL_STATUS.get(state.status, str(state.status)),
                         "program": ("ended" if state.program_status == PROG_ABORTED and channel.ended_normally
                                     else _PROGRAM_STATUS.get(state.program_status, str(state.program_status))),
                         "actual_parts": state.actual_parts, "total_parts": state.total_parts,
                         "net_time_s": channel.net_time_s,
                         # the part program (issue 41): selected, the block running and its line
                         "selected": channel.selected, "block_program": state.program,
                         "line": state.line_number, "block": state.block_text, "message": state.message,
                         "block_number": state.block_number, "blocks": channel.run.blocks if channel.run else 0,
                         # the last complete run's net time less this run's (Channel.time_left_s); None
                         # until one run of the program has ended
                         "time_left_s": channel.time_left_s, "last_run_s": channel.last_run_s}
        spindles = [{"number": number, "rpm": channel.spindle_speed_rpm(number)} for number in state.spindles]
    clients = server.clients() if server is not None else []
    document: dict[str, Any] = {
        "machine": machine.name, "t_s": clock.now_s(),
        "speed": clock.speed if isinstance(clock, LiveClock) else 1.0,
        "axes": axes, "sensors": sensors, "drives": drives, "spindles": spindles, "channel": channel_state,
        "alarms": list(nck.alarms), "clients": clients,
    }
    for name, section in emulator.status_sections.items():
        document[name] = section()
    return document
