"""The OPC UA face with asyncua's client, against the S7 face (python-snap7) over the same model."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import snap7
from asyncua import Client, ua
from asyncua.ua.uaerrors import UaStatusCodeError

from nckemu.catalogue.node_ids import parse_node_id
from nckemu.clients import NckClient
from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.machine.nck.access import HIGHEST_LEVEL, AccessContext
from nckemu.emulator.runner import EmulatorThread
from tests.support.opcua_tools import connect, two_faces, write_status

pytestmark = pytest.mark.timeout(120)
NS_URI = "SinumerikVarProvider"
SD43900_AX4 = "/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]"
HIGHEST = AccessContext(level=HIGHEST_LEVEL, client="test")


@pytest.fixture(scope="module")
def faces() -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    with two_faces() as pair:
        yield pair


def run(coroutine: Any) -> Any:
    return asyncio.run(coroutine)


async def _read(face: OpcUaFace, *ids: str, user: str | None = None, password: str | None = None) -> list[Any]:
    client = await connect(face, user, password)
    try:
        ns = await client.get_namespace_index(NS_URI)
        return [await client.get_node(ua.NodeId(i, ns)).read_value() for i in ids]
    finally:
        await client.disconnect()


async def _status_of_read(face: OpcUaFace, node_id: str) -> str:
    client = await connect(face)
    try:
        ns = await client.get_namespace_index(NS_URI)
        value = await client.get_node(ua.NodeId(node_id, ns)).read_data_value(raise_on_bad_status=False)
        return value.StatusCode.name
    finally:
        await client.disconnect()


def test_namespace_is_sinumerik_var_provider_at_index_2(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    async def go() -> int:
        client = await connect(faces[1])
        try:
            return await client.get_namespace_index(NS_URI)
        finally:
            await client.disconnect()
    assert run(go()) == 2


def test_reads_in_the_controllers_syntax(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    _, face = faces
    status, status_u1, r_range, r_count, plc_flag = run(_read(
        face, "/Channel/State/progStatus", "/Channel/State/progStatus[u1]", "/Channel/Parameter/R[u1,1,5]",
        "/Channel/Parameter/R[u1, 1, #3]", "/Plc/M5.0"))
    assert status == status_u1 and isinstance(status, int)
    assert r_range == [0.0] * 5 and r_count == [0.0] * 3
    assert plc_flag is False


def test_opcua_write_is_read_over_s7_and_back(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    emulator, face = faces
    assert run(write_status(face, SD43900_AX4, ua.Variant(0.0125, ua.VariantType.Double))) == "Good"
    with NckClient("127.0.0.1", emulator.port) as nck:
        assert nck.get("SD43900[AX4]") == [pytest.approx(0.0125)]
        nck.put({"SD43900[AX4]": -0.25})
    assert run(_read(face, SD43900_AX4)) == [pytest.approx(-0.25)]
    # PLC memory: OPC UA array write, python-snap7 db_read, python-snap7 db_write, OPC UA read
    assert run(write_status(face, "/Plc/DB130.DBW0:[3]", ua.Variant([1, 2, 515], ua.VariantType.UInt16))) == "Good"
    plc = snap7.Client()
    plc.connect("127.0.0.1", 0, 2, emulator.port)
    try:
        assert bytes(plc.db_read(130, 0, 6)) == b"\x00\x01\x00\x02\x02\x03"
        plc.db_write(130, 8, bytearray(b"\x41\x20\x00\x00"))  # 10.0 as a REAL
    finally:
        plc.disconnect()
    assert run(_read(face, "/Plc/DB130.DBD8:REAL")) == [10.0]


def test_subscription_sees_an_s7_write_within_two_publishing_intervals(
        faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    emulator, face = faces
    seen: list[tuple[float, Any]] = []

    class Handler:
        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            seen.append((time.monotonic(), value))

    async def go() -> float:
        client = await connect(face)
        try:
            ns = await client.get_namespace_index(NS_URI)
            subscription = await client.create_subscription(100, Handler())
            await subscription.subscribe_data_change(client.get_node(ua.NodeId("/Plc/DB130.DBW20", ns)))
            await asyncio.sleep(0.4)
            plc = snap7.Client()
            plc.connect("127.0.0.1", 0, 2, emulator.port)
            written = time.monotonic()
            plc.db_write(130, 20, bytearray(b"\x12\x34"))
            plc.disconnect()
            await asyncio.sleep(0.6)
            return written
        finally:
            await client.disconnect()

    written = run(go())
    changed = [(t, v) for t, v in seen if v == 0x1234]
    assert changed, seen
    assert changed[0][0] - written <= 0.2 + 0.1  # two publishing intervals (+ scheduling slack)


def test_every_s7_write_reaches_a_monitored_item_however_fast(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """Writes 5 ms apart, twenty per publishing interval: a sampler would see one in twenty; the face
    pushes each write, so the item's queue holds them all, in order (PLC words and an NC setting)."""
    emulator, face = faces
    seen: dict[str, list[Any]] = {"plc": [], "nc": []}

    class Handler:
        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            seen["nc" if "TEMP_COMP" in str(node.nodeid.Identifier) else "plc"].append(value)

    async def go() -> None:
        client = await connect(face)
        try:
            ns = await client.get_namespace_index(NS_URI)
            subscription = await client.create_subscription(100, Handler())
            nodes = [client.get_node(ua.NodeId(i, ns)) for i in ("/Plc/DB130.DBW40", SD43900_AX4)]
            await subscription.subscribe_data_change(nodes, queuesize=100)
            await asyncio.sleep(0.3)
            await asyncio.to_thread(write_fast)
            await asyncio.sleep(0.5)
        finally:
            await client.disconnect()

    def write_fast() -> None:
        plc = snap7.Client()
        plc.connect("127.0.0.1", 0, 2, emulator.port)
        try:
            with NckClient("127.0.0.1", emulator.port) as nck:
                for step in range(1, 41):
                    plc.db_write(130, 40, bytearray(step.to_bytes(2, "big")))
                    nck.put({"SD43900[AX4]": step / 1000})
                    time.sleep(0.005)
        finally:
            plc.disconnect()

    run(go())
    assert seen["plc"][-40:] == list(range(1, 41)), seen["plc"]
    assert seen["nc"][-40:] == [pytest.approx(step / 1000) for step in range(1, 41)], seen["nc"]


def test_errors_as_the_controller(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    _, face = faces
    assert run(_status_of_read(face, "Channel/State/progStatus")) == "BadNodeIdUnknown"  # no leading slash
    assert run(_status_of_read(face, "/Channel/Parameter/R[u1,")) == "BadNodeIdUnknown"
    assert run(_status_of_read(face, "/Nck/Spindle/driveLoad[u1, 3]")) == "BadAttributeIdInvalid"
    assert run(_status_of_read(face, "/Channel/Parameter/R[u1,99999999]")) == "BadNodeIdUnknown"
    assert run(_status_of_read(face, "/Channel/Parameter/R[u1,1000]")) == "BadAttributeIdInvalid"
    assert run(write_status(face, SD43900_AX4, ua.Variant(0.5, ua.VariantType.Double), user=None)) == "BadUserAccessDenied"
    assert run(write_status(face, SD43900_AX4, ua.Variant(5000.0, ua.VariantType.Double))) == "BadOutOfRange"
    assert run(write_status(face, "/Channel/State/progStatus", ua.Variant(1, ua.VariantType.UInt16))) == "BadNotWritable"


def test_user_rules(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    _, face = faces
    with pytest.raises(UaStatusCodeError):  # a wrong password is refused when the session activates
        run(_read(face, "/Channel/State/progStatus", user="nckemu", password="wrong"))
    assert run(_read(face, "/Channel/State/progStatus", user="nckemu", password="SUNRISE"))

    async def methods(user: str | None) -> tuple[Any, ...]:
        client = await connect(face, user, "SUNRISE")
        try:
            ns = await client.get_namespace_index(NS_URI)
            node = await client.nodes.objects.get_child([f"{ns}:Sinumerik", f"{ns}:Methods"])
            try:
                rights = await node.call_method(f"{ns}:GetMyAccessRights")
            except UaStatusCodeError as exc:
                return (type(exc).__name__,)
            await node.call_method(f"{ns}:CopyFileToServer", "Sinumerik/FileSystem/Part Program/OPCUA1.MPF",
                                   b"G1 X10 F100\nM30\n", True)
            back = await node.call_method(f"{ns}:CopyFileFromServer", "Sinumerik/FileSystem/Part Program/OPCUA1.MPF")
            return rights, back
        finally:
            await client.disconnect()

    assert run(methods(None)) == ("BadRequestNotAllowed",)
    rights, back = run(methods("nckemu"))
    assert rights == "SinuReadAll;SinuWriteAll" and back == b"G1 X10 F100\nM30\n"
    assert "/_N_MPF_DIR/_N_OPCUA1_MPF" in face.emulator.nck.programs.paths  # where PI _N_SELECT looks


def test_browsing_reaches_every_catalogue_row(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    from nckemu.catalogue.node_ids import node_paths

    _, face = faces

    async def go() -> set[str]:
        client = await connect(face)
        found: set[str] = set()
        try:
            ns = await client.get_namespace_index(NS_URI)
            stack = [await client.nodes.objects.get_child([f"{ns}:Sinumerik"])]
            while stack:
                for child in await stack.pop().get_children():
                    if await child.read_node_class() == ua.NodeClass.Variable:
                        found.add(str(child.nodeid.Identifier))
                    else:
                        stack.append(child)
        finally:
            await client.disconnect()
        return found

    found = run(go())
    assert {node_paths(spec)[0] for spec in face.specs} <= found


def test_limits_sessions_and_publishing_interval() -> None:
    from dataclasses import replace

    with two_faces() as (_, face):
        face.settings = replace(face.settings, max_sessions=1, max_subscriptions=1)

        async def go() -> tuple[str, float, str]:
            first = await connect(face)
            try:
                try:
                    second = await connect(face)
                    await second.disconnect()
                    too_many = "accepted"
                except UaStatusCodeError as exc:
                    too_many = type(exc).__name__
                subscription = await first.create_subscription(20, None)
                try:
                    await first.create_subscription(100, None)
                    sub_limit = "accepted"
                except UaStatusCodeError as exc:
                    sub_limit = type(exc).__name__
                return too_many, subscription.parameters.RequestedPublishingInterval, sub_limit
            finally:
                await first.disconnect()

        too_many, _interval, sub_limit = run(go())
        assert too_many == "BadTooManySessions"
        assert sub_limit == "BadTooManySubscriptions"


def test_samples_per_second_cap_refuses_the_item_past_it() -> None:
    """At 100 ms an item costs 10 samples/s: a cap of 25 takes two, refuses the third, and has room
    again once one is deleted; at 1000 ms the same cap takes 25 items."""
    from dataclasses import replace

    class Quiet:
        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            pass

    with two_faces() as (_, face):
        face.settings = replace(face.settings, max_samples_per_s=25)

        async def go() -> tuple[list[str], str, int]:
            client = await connect(face)
            try:
                ns = await client.get_namespace_index(NS_URI)
                fast = await client.create_subscription(100, Quiet())
                nodes = [client.get_node(ua.NodeId(f"/Plc/DB130.DBW{2 * i}", ns)) for i in range(3)]
                handles = await fast.subscribe_data_change(nodes)
                statuses = [h.name if isinstance(h, ua.StatusCode) else "Good" for h in handles]
                await fast.unsubscribe(handles[0])
                again = await fast.subscribe_data_change([nodes[2]])
                await fast.delete()
                slow = await client.create_subscription(1000, Quiet())
                many = await slow.subscribe_data_change(
                    [client.get_node(ua.NodeId(f"/Plc/DB130.DBW{2 * i}", ns)) for i in range(26)])
                return statuses, "Good" if isinstance(again[0], int) else again[0].name, \
                    sum(isinstance(h, int) for h in many)
            finally:
                await client.disconnect()

        statuses, again, slow_taken = run(go())
    assert statuses == ["Good", "Good", "BadTooManyMonitoredItems"]
    assert again == "Good"
    assert slow_taken == 25


async def _first_notifications(face: OpcUaFace, ids: list[str]) -> tuple[list[str], dict[str, Any]]:
    """Subscribe to ``ids`` anonymously: each item's create status and its first notification."""
    first: dict[str, Any] = {}

    class Handler:
        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            first.setdefault(str(node.nodeid.Identifier), (value, data.monitored_item.Value.StatusCode.name))

    client = await connect(face)
    try:
        ns = await client.get_namespace_index(NS_URI)
        subscription = await client.create_subscription(100, Handler())
        handles = await subscription.subscribe_data_change([client.get_node(ua.NodeId(i, ns)) for i in ids])
        await asyncio.sleep(0.4)
        return [h.name if isinstance(h, ua.StatusCode) else "Good" for h in handles], first
    finally:
        await client.disconnect()


def test_a_monitored_item_starts_with_the_value_and_needs_the_read_right() -> None:
    """The first notification is the variable's value read with the session's rights; an item on a
    variable the session may not read is refused (later pushes would carry what its reads are denied)."""
    from dataclasses import replace

    ids = ["/Channel/State/progStatus", "/Plc/DB130.DBW60"]
    with two_faces() as (emulator, face):
        face.settings = replace(face.settings, anonymous=frozenset({"StateRead"}))
        emulator.emulator.plc.write(0x84, 130, 60, b"\x00\x2a")
        statuses, first = run(_first_notifications(face, ids))
        expected_status = emulator.emulator.nck.read(parse_node_id(ids[0], face.specs).address, HIGHEST)[0]
    assert statuses == ["Good", "BadUserAccessDenied"]
    assert first[ids[0]] == (expected_status, "Good")
    assert ids[1] not in first

    with two_faces() as (emulator, face):  # SinuReadAll (the default machine's anonymous): the value
        emulator.emulator.plc.write(0x84, 130, 60, b"\x00\x2a")
        statuses, first = run(_first_notifications(face, ids))
    assert statuses == ["Good", "Good"]
    assert first[ids[1]] == (42, "Good")


def test_sessions_are_revised_to_the_controllers_timeout() -> None:
    """asyncua's client asks for an hour; the controller keeps an idle session 60 s (a setting)."""
    from dataclasses import replace

    with two_faces() as (_, face):
        async def revised() -> float:
            client = Client(face.url, timeout=10)
            async with client:
                return float(client.session_timeout)

        assert run(revised()) == 60_000.0
        face.settings = replace(face.settings, session_timeout_s=5)
        assert run(revised()) == 5_000.0


def test_machine_file_var_rows_are_served() -> None:
    machine = Path(__file__).resolve().parents[4] / "fixtures" / "machines" / "extra_vars.toml"
    with two_faces(machine) as (_, face):
        target, serial = run(_read(face, "/Nckemu/Channel/shiftTarget", "/NC/_N_NC_TEA_ACX/$MN_HW_SERIAL_NUMBER"))
        assert target == 120.0 and serial == "MIRROR-0001"


def test_subscription_sees_the_machines_own_dynamics(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    _, face = faces
    seen: list[Any] = []

    class Handler:
        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            seen.append(value)

    async def go() -> None:
        client = await connect(face)
        try:
            ns = await client.get_namespace_index(NS_URI)
            subscription = await client.create_subscription(100, Handler())
            # the NCK's system time in ms: changes by itself, no client writes it
            await subscription.subscribe_data_change(client.get_node(ua.NodeId("/Nck/State/sysTimeUdword", ns)))
            await asyncio.sleep(0.8)
        finally:
            await client.disconnect()

    run(go())
    assert len(set(seen)) >= 3, seen
