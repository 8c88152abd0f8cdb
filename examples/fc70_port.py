"""Seed 000's FC70 on a PC: read PIW 420, compute the compensation, PUT it once a simulated minute.

The Z axis (machine axis 4) grows 0.3 mm per 10 K above 30 degC and compensation is position
independent (MD32750 = 1), as in the application note. The program runs against an in-process
emulator on simulated time: two hours of a bed-temperature ramp from 30 to 50 degC take a second.

Run: .venv/bin/python examples/fc70_port.py
"""

from __future__ import annotations

import struct
import sys
from pathlib import Path

import snap7

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from nckemu.clients import FbPut, NckClient  # noqa: E402
from nckemu.emulator.machine.clock import SimulatedClock  # noqa: E402
from nckemu.emulator.machine.core import Emulator  # noqa: E402
from nckemu.emulator.runner import EmulatorThread  # noqa: E402

RAW_PER_C = 276.48  # the default machine's PT100 input: 0..27648 = 0..100 degC
Z = "AX4"


def compensation_mm(temperature_C: float) -> float:
    """FC70's arithmetic: nothing up to 30 degC, then 0.3 mm per 10 K."""
    return 0.0 if temperature_C <= 30.0 else (temperature_C - 30.0) / 10.0 * 0.3


def run(minutes: int = 120, verbose: bool = True) -> list[tuple[float, float, float]]:
    clock = SimulatedClock()
    emulator = Emulator(clock=clock)
    rows = []
    with EmulatorThread(emulator=emulator) as emu, NckClient("127.0.0.1", emu.port) as nck:
        nck.login("EVENING")  # MD32750 needs access level 2
        nck.put({f"MD32750[{Z}]": 1})
        nck.pi_service("_N_NCKRES", "/NC")  # power on: MD32750 takes effect
        plc = snap7.Client()
        plc.connect("127.0.0.1", 0, 2, emu.port)
        put = FbPut(nck)
        addresses = [f"SD43900[{Z}]", f"SD43910[{Z}]", f"SD43920[{Z}]"]
        for minute in range(minutes + 1):
            bed_C = 30.0 + 20.0 * minute / minutes
            emu.call(lambda t=bed_C: emulator.nck.set_sensor_temperature("bed", t))
            raw = struct.unpack(">h", plc.read_area(snap7.type.Area.PE, 0, 420, 2))[0]
            temperature_C = raw / RAW_PER_C
            values = [compensation_mm(temperature_C), 0.0, 0.0]
            outputs = put.cycle(Req=True, NumVar=3, Addr=addresses, SD=values)
            while not (outputs.Done or outputs.Error):  # PLC cycles until FB3 reports
                outputs = put.cycle(Req=False, NumVar=3, Addr=addresses, SD=values)
            if outputs.Error:
                raise RuntimeError(f"FB3 PUT failed, State = W#16#{outputs.State:04X}")
            emu.call(lambda: clock.advance(60.0))
            (applied_mm,) = nck.get(f"NCKEMU_TC_VALUE[{Z}]")
            rows.append((temperature_C, values[0], applied_mm))
            if verbose and minute % 30 == 0:
                print(f"t = {minute:3d} min  bed {temperature_C:5.2f} degC  PUT K0 = {values[0]:.4f} mm  "
                      f"Z compensation {applied_mm:.4f} mm")
        plc.disconnect()
    return rows


if __name__ == "__main__":
    run()
