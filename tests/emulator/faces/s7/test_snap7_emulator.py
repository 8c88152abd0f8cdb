"""Real clients (python-snap7 sync and async, pys7) against the real server on 127.0.0.1."""

from __future__ import annotations

import logging
import struct
from collections.abc import Iterator

import pytest
import snap7

from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol import pi, s7
from nckemu.protocol.addresses import NckAddress

SD43900_AX4 = NckAddress(3, 4, 43900, 1, 0x16)
SD43910_AX4 = NckAddress(3, 4, 43910, 1, 0x16)
SD43920_AX4 = NckAddress(3, 4, 43920, 1, 0x16)


@pytest.fixture
def client(emulator: EmulatorThread) -> Iterator[snap7.Client]:
    logging.getLogger("snap7").setLevel(logging.WARNING)
    c = snap7.Client()
    c.connect("127.0.0.1", 0, 4, emulator.port)
    yield c
    c.disconnect()


def exchange(client: snap7.Client, parameter: bytes, data: bytes = b"", ref: int = 0x100) -> s7.S7Pdu:
    raw = client.iso_exchange_buffer(bytearray(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, ref, parameter, data))))
    return s7.parse_pdu(bytes(raw))


def nck_read(client: snap7.Client, *addresses: NckAddress) -> s7.ReadVarResponse:
    answer = exchange(client, s7.build_read_var_request(s7.ReadVarRequest(addresses)))
    assert (answer.error_class, answer.error_code) == (0, 0)
    return s7.parse_read_var_response(answer.parameter, answer.data)


def nck_write(client: snap7.Client, values: dict[NckAddress, float]) -> tuple[int, ...]:
    request = s7.WriteVarRequest(tuple(values), tuple(
        s7.DataItem(0, 0x09, struct.pack("<d", v)) for v in values.values()))
    answer = exchange(client, *s7.build_write_var_request(request))
    return s7.parse_write_var_response(answer.parameter, answer.data).return_codes


def test_connect_with_nck_slot_and_plc_slot(emulator: EmulatorThread) -> None:
    for slot in (2, 3, 4):
        c = snap7.Client()
        c.connect("127.0.0.1", 0, slot, emulator.port)
        assert c.get_connected()
        c.disconnect()


def test_get_cpu_info(client: snap7.Client) -> None:
    info = client.get_cpu_info()
    assert info.ModuleTypeName


def test_get_cpu_info_names_the_machine_and_its_md18030(emulator: EmulatorThread) -> None:
    """SZL 0x001C carries the machine's own name and serial number (MD18030), as umati Identification;
    a name longer than the field's 24 characters is cut, never spilled into the reserved bytes."""
    machine = emulator.emulator
    serial = machine.serial_number
    machine.name = "a machine with a rather long name"
    client = snap7.Client()
    client.connect("127.0.0.1", 0, 2, emulator.port)
    try:
        info = client.get_cpu_info()
        raw = client.read_szl(0x001C, 0)
    finally:
        client.disconnect()
        machine.name = machine.machine.name
    assert (info.ASName.decode(), info.SerialNumber.decode()) == ("a machine with a rather ", serial)
    assert serial.startswith("NCKEMU") and len(serial) == 20
    first = bytes(b & 0xFF for b in raw.Data[4:38])
    assert first[:2] == b"\x00\x01" and first[26:] == bytes(8)


def test_db_write_then_read(client: snap7.Client) -> None:
    client.db_write(130, 0, bytearray(b"\x12\x34\x56\x78"))
    assert client.db_read(130, 0, 4) == bytearray(b"\x12\x34\x56\x78")


def test_missing_db_is_an_error(client: snap7.Client) -> None:
    with pytest.raises(Exception):  # noqa: B017 - python-snap7 raises its own error type
        client.db_read(4321, 0, 4)


def test_nck_real8_read_via_raw_pdu(client: snap7.Client) -> None:
    answer = nck_read(client, SD43900_AX4)
    assert answer.items[0].return_code == 0xFF and answer.items[0].transport_size == 0x09
    assert struct.unpack("<d", answer.items[0].data) == (0.0,)


def test_seed000_put_then_compensation_at_any_position(emulator: EmulatorThread, client: snap7.Client) -> None:
    """Seed 000: MD32750 = 1 (position independent); K0 = 0.3 mm at 40 °C for Z (axis 4)."""
    emulator.call(lambda: emulator.nck.write(NckAddress(3, 4, 32750, 1, 0x1A), [1], AccessContext(level=0)))
    emulator.call(emulator.emulator.power_on)
    assert nck_write(client, {SD43900_AX4: 0.3, SD43910_AX4: 0.0, SD43920_AX4: 0.0}) == (0xFF, 0xFF, 0xFF)
    assert [struct.unpack("<d", i.data)[0] for i in nck_read(client, SD43900_AX4, SD43920_AX4).items] \
        == [0.3, 0.0]


def test_unknown_items_never_answer_with_other_data(client: snap7.Client) -> None:
    answer = nck_read(client, NckAddress(3, 4, 43900, 1, 0x55), NckAddress(3, 4, 43900, 99, 0x16),
                      NckAddress(3, 4, 0xFFFF, 1, 0x16))
    assert [i.return_code for i in answer.items] == [0x0A, 0x05, 0x0A]
    assert all(i.data == b"" for i in answer.items)


def test_pi_unknown_service_is_refused(client: snap7.Client) -> None:
    answer = exchange(client, pi.build_pi_request(pi.PiServiceRequest("_N_NOSUCH", ("201",))))
    assert answer.error_class != 0


def test_async_client_raw_nck_read(emulator: EmulatorThread) -> None:
    import asyncio

    from snap7.async_client import AsyncClient

    async def run() -> bytes:
        client = AsyncClient()
        await client.connect("127.0.0.1", 0, 4, emulator.port)
        try:
            request = s7.build_pdu(s7.S7Pdu(1, 5, s7.build_read_var_request(s7.ReadVarRequest((SD43900_AX4,)))))
            return bytes(await client.iso_exchange_buffer(bytearray(request)))
        finally:
            await client.disconnect()

    answer = s7.parse_pdu(asyncio.run(run()))
    assert s7.parse_read_var_response(answer.parameter, answer.data).items[0].return_code == 0xFF


def test_pys7_reads_and_writes_a_db(emulator: EmulatorThread) -> None:
    from pyS7 import S7Client

    client = S7Client(address="127.0.0.1", rack=0, slot=2, port=emulator.port)
    client.connect()
    try:
        client.write(["DB130,INT20"], [-7])
        assert client.read(["DB130,INT20"]) == [-7]
    finally:
        client.disconnect()


def test_pys7_cpu_status_and_info(emulator: EmulatorThread) -> None:
    """pys7 asks for SZL 0x0424 (status) and 0x001C (identification), as it would of a real CPU."""
    from pyS7 import S7Client

    client = S7Client(address="127.0.0.1", rack=0, slot=2, port=emulator.port)
    client.connect()
    try:
        assert client.get_cpu_status() == "RUN"
        info = client.get_cpu_info()
        assert (info["module_type_name"], info["hardware_version"], info["firmware_version"]) == \
            ("6FC5372-0AA30-0AA0", "V3", "V3.2.6")
    finally:
        client.disconnect()


def test_python_snap7_order_code_shows_the_same_firmware_as_pys7(emulator: EmulatorThread) -> None:
    import snap7

    client = snap7.Client()
    client.connect("127.0.0.1", 0, 2, emulator.port)
    try:
        order = client.get_order_code()
        assert (order.OrderCode, order.V1, order.V2, order.V3) == (b"6FC5372-0AA30-0AA0", 3, 2, 6)
    finally:
        client.disconnect()


def test_python_snap7_get_cpu_state_gets_the_controllers_refusal(emulator: EmulatorThread) -> None:
    """python-snap7 3.3's get_cpu_state sends a read-var job with a 1-byte parameter (no item count).
    A controller refuses such a frame with a header error; so do we, and the connection goes on."""
    import snap7
    from snap7.error import S7ProtocolError

    client = snap7.Client()
    client.connect("127.0.0.1", 0, 2, emulator.port)
    try:
        with pytest.raises(S7ProtocolError, match="class=0x85"):
            client.get_cpu_state()
        assert client.get_cpu_info().ModuleTypeName
    finally:
        client.disconnect()
