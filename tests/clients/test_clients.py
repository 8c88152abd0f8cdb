"""Our clients (sync, async, FB-faithful, 840C channel) against the real emulator on loopback."""

from __future__ import annotations

import asyncio
import socket
import struct
import time
from collections.abc import Iterator
from pathlib import Path

import dpkt
import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from nckemu.clients import AsyncNckClient, Channel840C, Channel840CError, FbPut, NckClient, parse_variable
from nckemu.clients.fb import STATE_NUMVAR_INVALID, item_state
from nckemu.emulator.runner import EmulatorThread
from nckemu.errors import (
    NckAccessDenied,
    NckConfigError,
    NckConnectionError,
    NckObjectDoesNotExist,
    NckServiceError,
    NckTimeoutError,
)


@pytest.fixture
def nck(emulator: EmulatorThread) -> Iterator[NckClient]:
    with NckClient("127.0.0.1", emulator.port, timeout_s=3.0) as client:
        yield client


def test_put_then_get_eight_variables(nck: NckClient) -> None:
    names = [f"R{i}" for i in range(8)]
    nck.put({name: float(i) + 0.5 for i, name in enumerate(names)})
    assert nck.get(*names) == [i + 0.5 for i in range(8)]


def test_numvar_nine_is_refused_before_sending(nck: NckClient) -> None:
    with pytest.raises(NckConfigError, match="1..8"):
        nck.get(*[f"R{i}" for i in range(9)])


def test_mixed_valid_and_invalid_write(nck: NckClient) -> None:
    results = nck.put_items([("R1", 1.25), ("MD32750[AX4]", 1), ("R2", 2.5)])
    assert [r.return_code for r in results] == [0xFF, 0x03, 0xFF]
    assert nck.get("R1", "R2") == [1.25, 2.5]
    with pytest.raises(NckAccessDenied, match="variable 2"):
        nck.put({"R1": 1.0, "MD32750[AX4]": 1})


def test_access_level_raised_by_login(nck: NckClient) -> None:
    with pytest.raises(NckAccessDenied):
        nck.put({"MD32750[AX4]": 1})
    nck.login("EVENING")
    nck.put({"MD32750[AX4]": 1})
    assert nck.get("MD32750[AX4]") == [1]


def test_pi_errors(nck: NckClient) -> None:
    with pytest.raises(NckConfigError, match="takes 2 arguments"):
        nck.pi_service("_N_SELECT", "201")
    with pytest.raises(NckServiceError):
        nck.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_NOPE_MPF")
    with pytest.raises(NckServiceError):
        nck.pi_service("_N_LOGIN_", "/NC", "WRONG")
    nck.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_TEST_MPF")
    assert nck.get("progName[C1]") == ["/_N_MPF_DIR/_N_TEST_MPF"]


def test_object_errors_name_the_variable(nck: NckClient) -> None:
    from nckemu.protocol.addresses import NckAddress

    with pytest.raises(NckObjectDoesNotExist, match="variable 2"):
        nck.get("R1", NckAddress(3, 9, 43900, 1, 0x16))


def test_real32_rounding_as_the_plc_sends(emulator: EmulatorThread) -> None:
    with NckClient("127.0.0.1", emulator.port, plc_real32=True) as client:
        client.put({"SD43920[AX4]": 1234.5678})
        (value,) = client.get("SD43920[AX4]")
    assert value != 1234.5678 and abs(value - 1234.5678) < 1e-4


def test_timeout_against_a_silent_server() -> None:
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(4)
    try:
        client = NckClient("127.0.0.1", silent.getsockname()[1], timeout_s=0.5)
        started = time.monotonic()
        with pytest.raises(NckTimeoutError):
            client.connect()
        assert time.monotonic() - started < 5
        client.close()
    finally:
        silent.close()


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def test_connection_loss_then_reuse_after_reconnect() -> None:
    port = _free_port()
    first = EmulatorThread(port=port).start()
    client = NckClient("127.0.0.1", port, timeout_s=2.0).connect()
    try:
        client.put({"R1": 3.0})
        first.stop()
        with pytest.raises(NckConnectionError):
            client.get("R1")
        with EmulatorThread(port=port):
            assert client.get("R1") == [0.0]  # a new controller, reached by reconnecting
    finally:
        client.close()


def test_async_client(emulator: EmulatorThread) -> None:
    async def run() -> list[object]:
        async with AsyncNckClient("127.0.0.1", emulator.port) as client:
            await client.put({"SD43900[AX4]": 0.25, "SD43920[AX4]": -500.0})
            return await client.get("SD43900[AX4]", "SD43920[AX4]")

    assert asyncio.run(run()) == [0.25, -500.0]


SEED000_PUT_PARAMETER = bytes.fromhex(
    "0503" "12088264AB7C00011601" "12088264AB8600011601" "12088264AB9000011601")


def _client_jobs(path: Path) -> list[bytes]:
    jobs = []
    with path.open("rb") as handle:
        for _ts, frame in dpkt.pcapng.Reader(handle):
            tcp = dpkt.ethernet.Ethernet(frame).data.data
            payload = bytes(tcp.data)
            if tcp.dport == 102 and len(payload) > 7 and payload[7] == 0x32 and payload[8] == 1:
                jobs.append(payload[7:])
    return jobs


def test_seed000_put_bytes_equal_the_reference_vector(tmp_path: Path) -> None:
    """The three-variable PUT of seed 000 (K0, tan beta, P0 of axis 4) as a real FB3 sends it."""
    capture = tmp_path / "put.pcapng"
    with EmulatorThread(record_path=capture) as emu, NckClient("127.0.0.1", emu.port) as client:
        client.put({"SD43900[AX4]": 0.3, "SD43910[AX4]": 0.0, "SD43920[AX4]": 0.0})
    (job,) = [j for j in _client_jobs(capture) if j[10] == 0x05]
    expected_data = b"".join(b"\x00\x09\x00\x08" + struct.pack("<d", v) for v in (0.3, 0.0, 0.0))
    assert job[6:8] == struct.pack(">H", len(SEED000_PUT_PARAMETER))
    assert job[8:10] == struct.pack(">H", len(expected_data))
    assert job[10:] == SEED000_PUT_PARAMETER + expected_data


def test_fb3_put_across_plc_cycles(nck: NckClient) -> None:
    block = FbPut(nck)
    addresses = [parse_variable("SD43900[AX4]"), parse_variable("SD43910[AX4]")]
    first = block.cycle(Req=True, NumVar=2, Addr=addresses, SD=[0.3, 0.000012])
    assert first.Busy and not first.Done
    outputs = [block.cycle(Req=True, NumVar=2, Addr=addresses, SD=[0.3, 0.000012]) for _ in range(2000)
               if not time.sleep(0.001)]
    done = [o for o in outputs if o.Done]
    assert len(done) == 1 and not any(o.Error for o in outputs)  # Done for one cycle, Req held high
    assert nck.get("SD43910[AX4]") == [pytest.approx(0.000012, rel=1e-6)]


def test_fb3_put_errors_carry_the_variable_number(nck: NckClient) -> None:
    block = FbPut(nck)
    addresses = ["SD43900[AX4]", "MD32750[AX4]"]
    outputs = [block.cycle(Req=True, NumVar=2, Addr=addresses, SD=[0.1, 1])]
    while not (outputs[-1].Done or outputs[-1].Error):
        time.sleep(0.001)
        outputs.append(block.cycle(Req=False, NumVar=2, Addr=addresses, SD=[0.1, 1]))
    assert outputs[-1].Error and outputs[-1].State == item_state(0x03, 2)
    assert block.cycle(Req=True, NumVar=9, Addr=addresses, SD=[]).State == STATE_NUMVAR_INVALID


def test_channel_840c(emulator: EmulatorThread) -> None:
    async def run() -> None:
        async with AsyncNckClient("127.0.0.1", emulator.port, slot=2) as client:
            channel = Channel840C(client, user_db=131)
            # P0 = 0 with the A flag is accepted (issue 14 2.10: the manual only advises against it)
            await channel.send(axis=4, k_tcabs_mm=0.0, tan_beta=0.00001, p0_mm=0.0)
            await channel.send(axis=4, k_tcabs_mm=0.05, tan_beta=0.00001, p0_mm=-200.0)
            with pytest.raises(Channel840CError, match="error 6"):
                await channel.send(axis=7, k_tcabs_mm=0.05, tan_beta=0.0, p0_mm=10.0)

    asyncio.run(run())
    position = emulator.call(lambda: emulator.nck.axis_position_mm(4))
    tan_beta = round(0.00001 * (2**31 - 1)) / (2**31 - 1)  # what 2^-31 fixed point carries
    expected = 0.05 + tan_beta * (position + 200.0)
    assert emulator.call(lambda: emulator.nck.tc_value_mm(4)) == pytest.approx(expected, abs=1e-12)


def test_channel_840c_refuses_p0_at_zero_when_the_machine_says_so() -> None:
    import nckemu.emulator.machine
    from nckemu.emulator.machine.machine_file import parse_machine

    text = (Path(nckemu.emulator.machine.__file__).parent / "machines" / "default.toml").read_text()
    machine = parse_machine(text.replace("c840_refuse_p0_at_zero = false", "c840_refuse_p0_at_zero = true"))

    async def run(port: int) -> None:
        async with AsyncNckClient("127.0.0.1", port, slot=2) as client:
            with pytest.raises(Channel840CError, match="error 10"):
                await Channel840C(client, user_db=131).send(axis=4, k_tcabs_mm=0.0, tan_beta=0.00001, p0_mm=0.0)

    with EmulatorThread(machine) as strict:
        asyncio.run(run(strict.port))


class PutGetAgreement(RuleBasedStateMachine):
    """Random put/get sequences keep a model dictionary and the emulator in agreement."""

    def __init__(self) -> None:
        super().__init__()
        self.emulator = EmulatorThread().start()
        self.client = NckClient("127.0.0.1", self.emulator.port).connect()
        self.model: dict[str, float] = {}

    names = st.sampled_from([f"R{i}" for i in range(10)] + ["SD43900[AX4]", "SD43920[AX1]", "SD43910[AX2]"])

    @rule(data=st.dictionaries(names, st.floats(-0.09, 0.09, allow_nan=False), min_size=1, max_size=8))
    def put(self, data: dict[str, float]) -> None:
        self.client.put(data)
        self.model.update(data)

    @rule(keys=st.lists(names, min_size=1, max_size=8))
    def get(self, keys: list[str]) -> None:
        assert self.client.get(*keys) == [self.model.get(k, 0.0) for k in keys]

    @invariant()
    def connected(self) -> None:
        assert self.client.connected

    def teardown(self) -> None:
        self.client.close()
        self.emulator.stop()


TestPutGetAgreement = PutGetAgreement.TestCase
TestPutGetAgreement.settings = settings(max_examples=15, stateful_step_count=12, deadline=None)


def test_sync_facade_mirrors_every_public_coroutine() -> None:
    """One copy of the protocol code: every public coroutine of AsyncNckClient has its sync twin."""
    import inspect

    from nckemu.clients import AsyncNckClient, NckClient

    coroutines = {name for name, member in inspect.getmembers(AsyncNckClient)
                  if not name.startswith("_") and inspect.iscoroutinefunction(member)}
    assert coroutines <= {name for name in dir(NckClient) if not name.startswith("_")}


def test_sync_clients_share_a_loop_and_a_failed_connect_leaks_no_thread() -> None:
    import socket
    import threading

    from nckemu.clients import NckClient
    from nckemu.clients.sync import ClientLoop
    from nckemu.emulator.runner import EmulatorThread
    from nckemu.errors import NckConnectionError

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        closed_port = probe.getsockname()[1]
    before = threading.active_count()
    for _ in range(3):
        with pytest.raises(NckConnectionError):
            with NckClient("127.0.0.1", closed_port, timeout_s=1.0):
                pass
    assert threading.active_count() <= before
    loop = ClientLoop()
    try:
        with EmulatorThread() as emulator:
            with NckClient("127.0.0.1", emulator.port, loop=loop) as one, \
                    NckClient("127.0.0.1", emulator.port, loop=loop) as two:
                one.put({"SD43900[AX1]": 0.25})
                assert two.get("SD43900[AX1]") == [0.25]
        assert loop.loop.is_running()  # a shared loop outlives its clients
    finally:
        loop.stop()
    with pytest.raises(NckConnectionError, match="not running"):
        loop.run(asyncio.sleep(0))
