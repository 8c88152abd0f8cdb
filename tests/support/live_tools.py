"""Helpers of the living-machine tests: a synthetic recording, a `nckemu serve` subprocess, one
python-snap7 poll of PIW 420, SD43900[AX4], actToolBasePos and the NCK's clock in one job."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import snap7

from nckemu.catalogue.names import as_variable
from nckemu.protocol import s7
from nckemu.protocol.addresses import S7AnyAddress
from nckemu.protocol.values import decode_nck_values

ROOT = Path(__file__).resolve().parents[2]
MACHINE = ROOT / "fixtures/machines/loop_mill.toml"
PROGRAM = ROOT / "fixtures/plc/tc_z.awl"   # K0 = 0.3 mm per 10 K of bed above 30 degC, FB3 once a minute
AREA_P = 0x80
TRANSPORT_WORD = 0x04


def write_recording(path: Path, hours: float = 3.0, step_s: float = 60.0) -> Path:
    """Bed 25 -> 45 degC with a wiggle, spindle warming and turning, Z travelling: PIW 420, SD43900, the
    spindle speed and Z move."""
    lines = ["t_s,temp_bed_C,temp_spindle_C,spindle_rpm,pos_Z_mm,err_Z_um"]
    rows = int(hours * 3600 / step_s) + 1
    for i in range(rows):
        t = i * step_s
        bed = 25.0 + 20.0 * t / (hours * 3600) + 0.5 * math.sin(t / 600.0)
        spindle = 20.0 + 3.0 * t / (hours * 3600)
        z = -500.0 + 300.0 * math.sin(t / 900.0)
        rpm = 0.0 if (t // 1200) % 2 == 0 else 6000.0   # twenty minutes at rest, twenty at 6000 rpm
        lines.append(f"{t:g},{bed:.4f},{spindle:.4f},{rpm:g},{z:.3f},{10.0 * (bed - 30.0):.3f}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@dataclass
class Served:
    process: subprocess.Popen[str]
    ready: dict[str, object]

    @property
    def port(self) -> int:
        return int(self.ready["port"])  # type: ignore[call-overload]


@contextmanager
def serve(*arguments: str, timeout_s: float = 60.0) -> Iterator[Served]:
    """`nckemu serve --port 0 --json ARGUMENTS` until the block ends; its ready line parsed."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen([sys.executable, "-m", "nckemu", "serve", "--port", "0", "--json", *arguments],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    try:
        assert process.stdout is not None
        deadline = time.monotonic() + timeout_s
        line = ""
        while time.monotonic() < deadline:
            line = process.stdout.readline()
            if not line or '"port"' in line:
                break
        if not line:
            raise AssertionError(f"serve did not start: {process.stderr.read() if process.stderr else ''}")
        yield Served(process, json.loads(line))
    finally:
        process.terminate()
        try:
            process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


SYS_TIME = as_variable("sysTimeUdword")
SD43900 = as_variable("SD43900[AX4]")
ACT_POS_Z = as_variable("actToolBasePos[3,C1]")  # line 4: machine axis 4 (the index counts from 0)
TC_Z = as_variable("NCKEMU_TC_VALUE[AX4]")
PIW420 = S7AnyAddress(TRANSPORT_WORD, 1, 0, AREA_P, 420)


@dataclass(frozen=True)
class Poll:
    """One job: the NCK's clock before and after (simulated seconds), and what was read between."""

    before_s: float
    after_s: float
    piw420: int
    sd43900_mm: float
    act_z_mm: float
    tc_z_mm: float


def poll(client: snap7.Client, ref: int = 1) -> Poll:
    variables = (SYS_TIME, None, SD43900, ACT_POS_Z, TC_Z, SYS_TIME)
    addresses = tuple(PIW420 if v is None else v.address for v in variables)
    request = s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, ref, s7.build_read_var_request(s7.ReadVarRequest(addresses))))
    answer = s7.parse_pdu(bytes(client.iso_exchange_buffer(bytearray(request))))
    items = s7.parse_read_var_response(answer.parameter, answer.data).items
    assert all(item.return_code == 0xFF for item in items), [item.return_code for item in items]
    values = []
    for variable, item in zip(variables, items, strict=True):
        if variable is None:
            values.append(int.from_bytes(item.data[:2], "big", signed=True))
        else:
            values.append(decode_nck_values(variable.nck_type, item.data, area=variable.address.area,
                                            line_count=1)[0])
    return Poll(values[0] / 1000.0, values[5] / 1000.0, values[1], values[2], values[3], values[4])
