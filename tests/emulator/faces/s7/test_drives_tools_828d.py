"""Drives and tools as an 828D answers them (issue 32): the reads of LSC, the libsiemenscnc 828D collector,
as fixed request frames, answered on the default machine and on an 828D lathe with the documented values.

The facts behind the bytes (our own frames; no code taken from the source):
  LSC   siemens_828d_new.c request tables: every job is 29 bytes, PDU reference 0x0014 (0x0021 for the
        tool compensation X), followed by a 7-byte empty DT (``03 00 00 07 02 F0 00``) it calls "sync".
        Drive parameters: area V, unit 1 + driver index (``0xA1 + driver``), column = parameter number,
        line = index + 1 ("the subscript is one more than the real value"), module 0x82; the control unit
        (module 0x80) and the "power supply module" (0x81) at unit 1. Decoded as a big-endian REAL4.
        Tool data: C/S (0x7F) column 0x1B6 H number (an integer of up to 4 bytes), 0x71 / 0x73 tool
        compensation X / Z (REAL8); tool list area T (0x81), column = tool row, line = 0x1A / 0x22 +
        35 * (edge - 1) for the H number / number of teeth, module TO (0x14).
Expected values are the emulator's documented defaults (nckemu/emulator/machine/nck/drives.py,
machines/default.toml, fixtures/machines/lathe_828d.toml).
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.faces.s7.session import ServerSession, SessionLimits
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.errors import NckAccessDenied
from nckemu.protocol.addresses import NckAddress, NckArea

LATHE = Path(__file__).resolve().parents[4] / "fixtures" / "machines" / "lathe_828d.toml"
CR_LSC = bytes.fromhex("03 00 00 16 11 E0 00 00 00 48 00 C1 02 04 00 C2 02 0D 04 C0 01 0A")
SETUP_LSC = bytes.fromhex("03 00 00 19 02 F0 80 32 01 00 00 00 01 00 08 00 00 F0 00 00 64 00 64 03 C0")
SYNC_LSC = bytes.fromhex("03 00 00 07 02 F0 00")
# Three of LSC's jobs as it sends them (the others are built by ``lsc_job`` and checked against these).
R0026_DRIVE1 = bytes.fromhex("03 00 00 1D 02 F0 80 32 01 00 00 00 14 00 0C 00 00 04 01 12 08 82 A1 00 1A 00 01 82 01")
H_NUMBER = bytes.fromhex("03 00 00 1D 02 F0 80 32 01 00 00 00 14 00 0C 00 00 04 01 12 08 82 41 01 B6 00 01 7F 01")
TOOL_X = bytes.fromhex("03 00 00 1D 02 F0 80 32 01 00 00 00 21 00 0C 00 00 04 01 12 08 82 41 00 71 00 01 7F 01")


def lsc_job(area_unit: int, column: int, line: int, module: int, ref: int = 0x14) -> bytes:
    return (bytes.fromhex("03 00 00 1D 02 F0 80 32 01 00 00") + struct.pack(">H", ref)
            + bytes.fromhex("00 0C 00 00 04 01 12 08 82") + struct.pack(">BHHBB", area_unit, column, line, module, 1))


def drive_job(driver: int, parameter: int, index: int = 0, module: int = 0x82) -> bytes:
    """LSC's siemenscnc_read_s_r_p_param (driver 0 = unit 1) and its control unit / power unit reads."""
    return lsc_job(0xA1 + driver, parameter, index + 1, module)


def session_for(emulator: Emulator) -> ServerSession:
    session = ServerSession(Dispatcher.for_machine(emulator), limits=SessionLimits(pdu_size_max=960, max_amq=8))
    (cc,) = session.receive(CR_LSC)
    (setup,) = session.receive(SETUP_LSC)
    assert len(cc) == 22 and len(setup) == 27
    return session


def ask(session: ServerSession, job: bytes) -> tuple[int, int, bytes]:
    """One LSC job with its trailing sync DT: one answer frame, one item (rc, transport size, data)."""
    (answer,) = session.receive(job + SYNC_LSC)
    assert answer[8] == 3 and answer[17:19] == b"\x00\x00" and answer[19:21] == b"\x04\x01", answer.hex()
    rc, ts, length = answer[21], answer[22], struct.unpack(">H", answer[23:25])[0]
    assert len(answer) == 25 + length
    return rc, ts, answer[25:]


def real4(session: ServerSession, job: bytes) -> float:
    rc, ts, data = ask(session, job)
    assert (rc, ts, len(data)) == (0xFF, 0x09, 4), (rc, ts, data)
    return struct.unpack(">f", data)[0]   # big-endian, as LSC swaps it


def real8(session: ServerSession, job: bytes) -> float:
    rc, ts, data = ask(session, job)
    assert (rc, ts, len(data)) == (0xFF, 0x09, 8)
    return struct.unpack("<d", data)[0]


@pytest.fixture
def default_machine() -> Emulator:
    return Emulator(clock=SimulatedClock())


@pytest.fixture
def lathe() -> Emulator:
    return Emulator(LATHE, clock=SimulatedClock())


def test_the_helper_builds_lscs_own_frames() -> None:
    assert drive_job(0, 26) == R0026_DRIVE1
    assert lsc_job(0x41, 0x1B6, 1, 0x7F) == H_NUMBER
    assert lsc_job(0x41, 0x71, 1, 0x7F, ref=0x21) == TOOL_X


def test_drive_reads_on_the_default_machine(default_machine: Emulator) -> None:
    session = session_for(default_machine)
    # drive 1 drives X1 standing still: 2 % load (holding), 4 A rated, 1.5 kW rated, 90 % efficiency
    assert real4(session, R0026_DRIVE1) == 600.0
    assert real4(session, drive_job(0, 30)) == pytest.approx(0.08)
    assert real4(session, drive_job(0, 32)) == pytest.approx(1.5 * 0.1 * 0.02 ** 2)
    assert real4(session, drive_job(0, 35)) == pytest.approx(25.0 + 60.0 * 0.02 ** 2)
    # r0037: [0] inverter = ambient + 30 K x the current's share of rated; [2] (rectifier) has no sensor
    assert real4(session, drive_job(0, 37, 0)) == pytest.approx(25.0 + 30.0 * 0.02)
    assert real4(session, drive_job(0, 37, 2)) == -200.0
    # the control unit's sampling times and the infeed's power (what the four drives draw / 0.95)
    assert real4(session, drive_job(0, 115, 0, module=0x80)) == 125.0
    drives_kW = sum(default_machine.nck.drives.power_kW(default_machine.nck, n) for n in (1, 2, 3, 4))
    assert real4(session, drive_job(0, 32, 0, module=0x81)) == pytest.approx(drives_kW / 0.95)
    # the spindle is drive 3: turning at 4000 rpm it carries 15 % x 4000/8000 of load
    default_machine.nck.set_spindle_speed(1, 4000.0)
    load = 15.0 * 0.5
    assert real4(session, drive_job(2, 81)) == pytest.approx(load)
    assert real4(session, drive_job(2, 30)) == pytest.approx(20.0 * load / 100)
    assert real4(session, drive_job(2, 27)) == pytest.approx((1.5 ** 2 + 7.0 ** 2) ** 0.5)  # Iq with Id 7 A
    assert real4(session, drive_job(2, 32)) == pytest.approx(7.5 * 0.075 * 0.5 / 0.9 + 7.5 * 0.1 * 0.075 ** 2)
    assert real4(session, drive_job(2, 21)) == 4000.0


def test_tool_reads_on_the_default_machine(default_machine: Emulator) -> None:
    session = session_for(default_machine)
    # T1 D1 is active: H number 1; under G17 a milling tool's L1 (125 - 0.02) lies along Z, L3 (0) along X
    rc, ts, h = ask(session, H_NUMBER)
    assert (rc, ts, struct.unpack("<i", h)) == (0xFF, 0x09, (1,))
    assert real8(session, TOOL_X) == 0.0
    assert real8(session, lsc_job(0x41, 0x73, 1, 0x7F)) == pytest.approx(124.98)
    # the tool list: T1 (column 1) edge 1 lines 26 (H number) and 34 (teeth)
    assert real8(session, lsc_job(0x81, 1, 0x1A, 0x14)) == 1.0
    assert real8(session, lsc_job(0x81, 1, 0x22, 0x14)) == 4.0


def test_drive_and_tool_reads_on_an_828d_lathe(lathe: Emulator) -> None:
    session = session_for(lathe)
    # drive 1 is the spindle (as LSC numbers them): r0035 is the spindle motor's sensor
    assert real4(session, drive_job(0, 35)) == 32.0
    lathe.nck.set_sensor_temperature("spindle_motor", 41.5)
    assert real4(session, drive_job(0, 35)) == 41.5
    assert real4(session, R0026_DRIVE1) == 540.0
    assert real4(session, drive_job(0, 30)) == 0.0          # standing: no torque
    assert real4(session, drive_job(0, 27)) == 9.0          # the induction motor's magnetizing current
    assert real4(session, drive_job(1, 30)) == pytest.approx(3.0 * 0.02)
    assert real4(session, drive_job(0, 32, 0, module=0x81)) > 0.0
    # ISO tool data: H number 1, length 1 (32.5 + 0.01) along X, length 2 (48 - 0.02) along Z
    rc, _ts, h = ask(session, H_NUMBER)
    assert (rc, struct.unpack("<i", h)) == (0xFF, (1,))
    assert real8(session, TOOL_X) == pytest.approx(32.51)
    assert real8(session, lsc_job(0x41, 0x73, 1, 0x7F)) == pytest.approx(47.98)
    assert real8(session, lsc_job(0x81, 2, 0x1A, 0x14)) == 2.0
    assert real8(session, lsc_job(0x81, 2, 0x22, 0x14)) == 3.0


def test_spindle_load_moves_power(lathe: Emulator) -> None:
    session = session_for(lathe)
    lathe.nck.set_spindle_speed(1, 3000.0)
    turning = real4(session, drive_job(0, 32))
    lathe.nck.set_drive_load(1, 60.0)
    cutting = real4(session, drive_job(0, 32))
    assert 0.0 < turning < cutting == pytest.approx(11.0 * 0.6 * 0.5 / 0.9 + 11.0 * 0.1 * 0.36)


def test_bad_input_answers_the_item_error_and_the_session_goes_on(lathe: Emulator) -> None:
    session = session_for(lathe)
    assert ask(session, drive_job(7, 35))[0] == 0x0A                 # drive 8: the machine has 3
    assert ask(session, drive_job(0, 37, 20))[0] == 0x05             # r0037 has indices 0..19
    assert ask(session, drive_job(0, 35, 1))[0] == 0x05              # r0035 is not an array
    assert ask(session, drive_job(1, 115, 0, module=0x80))[0] == 0x0A  # the control unit is at unit 1
    assert ask(session, drive_job(0, 9999))[0] == 0x0A              # no such parameter
    # a write to an r-parameter: access to the object not allowed; the session still reads
    write = (bytes.fromhex("03 00 00 25 02 F0 80 32 01 00 00 00 15 00 0C 00 08 05 01 12 08 82 A1 00 23 00 01 82 01")
             + bytes.fromhex("00 09 00 04") + struct.pack(">f", 20.0))
    (answer,) = session.receive(write)
    assert answer[19:22] == bytes([0x05, 0x01, 0x03])
    assert real4(session, drive_job(0, 35)) == 32.0


def test_p_parameters_obey_access_levels(lathe: Emulator) -> None:
    threshold = NckAddress(NckArea.V, 1, 604, 1, 0x82)
    with pytest.raises(NckAccessDenied):
        lathe.nck.write(threshold, [110.0], AccessContext(level=3))
    lathe.nck.write(threshold, [110.0], AccessContext(level=2))
    assert lathe.nck.read(threshold, AccessContext(level=7)) == [110.0]
    # each drive keeps its own; r-parameters refuse even the highest level
    assert lathe.nck.read(NckAddress(NckArea.V, 2, 604, 1, 0x82), AccessContext(level=7)) == [120.0]
    with pytest.raises(NckAccessDenied):
        lathe.nck.write(NckAddress(NckArea.V, 1, 35, 1, 0x82), [1.0], AccessContext(level=0))


def test_drive_answers_may_carry_transport_size_real(tmp_path: Path) -> None:
    text = LATHE.read_text(encoding="utf-8").replace("[drives]\n", "[drives]\nanswer_transport_size = 0x07\n")
    machine = tmp_path / "lathe_ts7.toml"
    machine.write_text(text, encoding="utf-8")
    session = session_for(Emulator(machine, clock=SimulatedClock()))
    rc, ts, data = ask(session, R0026_DRIVE1)
    assert (rc, ts, struct.unpack(">f", data)) == (0xFF, 0x07, (540.0,))
    assert ask(session, H_NUMBER)[1] == 0x09       # the other areas keep 0x09
