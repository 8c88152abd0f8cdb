"""Alarm events on the OPC UA face: an alarm the emulator raises (its retained state cannot be written)
arrives as a CncAlarmType event on the Server object, its clearing too; ConditionRefresh sends the
pending ones again; sessions without AlarmRead get none; malformed event filters never hurt the server."""

from __future__ import annotations

import asyncio
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua
from asyncua.ua.uaerrors import UaStatusCodeError
from hypothesis import given
from hypothesis import strategies as st

from nckemu.clients import NckClient
from nckemu.emulator.faces.opcua import nodesets
from nckemu.emulator.faces.opcua.alarms import CNC_NAMESPACE, SEVERITIES, condition_id, event_fields
from nckemu.emulator.machine.nck.alarms import ALARM_RETAINED_STATE, Alarm, AlarmEvent
from tests.support.opcua_tools import two_faces

pytestmark = pytest.mark.timeout(180)
FIELDS = ("Message", "Severity", "Retain", "ActiveState/Id", "AlarmIdentifier", "AuxParameters", "ConditionName",
          "SourceName", "EventType")


class Events:
    def __init__(self) -> None:
        self.seen: list[dict[str, Any]] = []

    def event_notification(self, event: Any) -> None:
        self.seen.append({k: v for k, v in event.get_event_props_as_fields_dict().items() if k in FIELDS}
                         | {"type": event.EventType})


async def _alarm_type(client: Client) -> Any:
    """CncAlarmType: the CNC NodeSet's (models on) or the face's own (models off)."""
    namespaces = await client.get_namespace_array()
    cnc = namespaces.index(nodesets.CNC if nodesets.CNC in namespaces else CNC_NAMESPACE)
    return await client.nodes.base_event_type.get_child(
        ["0:ConditionType", "0:AcknowledgeableConditionType", "0:AlarmConditionType", "0:DiscreteAlarmType",
         f"{cnc}:CncAlarmType"])


def _values(seen: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: (v.Value.Text if k == "Message" else v.Value) for k, v in e.items() if k in FIELDS and k != "EventType"}
            for e in seen if "AlarmIdentifier" in e]


def _wait(condition: Any, seconds: float = 3.0) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not condition():
        time.sleep(0.05)


def test_a_raised_and_a_cleared_alarm_arrive_and_refresh_sends_the_pending(tmp_path: Path) -> None:
    state = tmp_path / "state.json"
    blocker = tmp_path / ".state.json.tmp"  # where the retained state's temporary file goes
    with two_faces(state_path=state) as (emulator, face):
        events = Events()

        async def go() -> list[dict[str, Any]]:
            async with Client(face.url, timeout=10) as client:
                subscription = await client.create_subscription(100, events)
                await subscription.subscribe_events(client.nodes.server, await _alarm_type(client))
                await asyncio.sleep(0.3)
                blocker.mkdir()
                await asyncio.to_thread(put, 0.1)  # answered; the NCK raises 700999
                await asyncio.to_thread(_wait, lambda: len(_values(events.seen)) >= 1)
                refresh = Events()
                refreshing = await client.create_subscription(100, refresh)
                await refreshing.subscribe_events(client.nodes.server, [ua.ObjectIds.RefreshStartEventType,
                                                                        ua.ObjectIds.RefreshEndEventType,
                                                                        await _alarm_type(client)])
                await client.get_node(ua.ObjectIds.ConditionType).call_method(  # ConditionRefresh(SubscriptionId)
                    ua.NodeId(ua.ObjectIds.ConditionType_ConditionRefresh),
                    ua.Variant(refreshing.subscription_id, ua.VariantType.UInt32))
                await asyncio.sleep(0.5)
                blocker.rmdir()
                await asyncio.to_thread(put, 0.2)  # written again: the alarm clears
                await asyncio.to_thread(_wait, lambda: len(_values(events.seen)) >= 2)
                return refresh.seen

        def put(value: float) -> None:
            with NckClient("127.0.0.1", emulator.port) as nck:
                nck.put({"SD43900[AX4]": value})

        refreshed = asyncio.run(go())
    raised, cleared = _values(events.seen)[:2]
    assert raised["AlarmIdentifier"] == str(ALARM_RETAINED_STATE) and raised["ConditionName"] == "700999"
    assert raised["Message"].startswith("retained state not saved") and raised["Severity"] == 500
    assert raised["Retain"] is True and raised["ActiveState/Id"] is True and raised["SourceName"] == "NCK"
    assert cleared["Retain"] is False and cleared["ActiveState/Id"] is False
    types = [e["type"] for e in refreshed]
    start, end = ua.NodeId(ua.ObjectIds.RefreshStartEventType), ua.NodeId(ua.ObjectIds.RefreshEndEventType)
    assert start in types and end in types
    between = refreshed[types.index(start) + 1:types.index(end)]
    assert [e["AlarmIdentifier"].Value for e in between] == ["700999"]


def test_a_session_without_alarm_read_gets_no_alarm_events() -> None:
    with two_faces() as (_, face):
        face.settings = replace(face.settings, anonymous=frozenset({"StateRead"}))

        async def go(user: str | None) -> str:
            client = Client(face.url, timeout=10)
            if user:
                client.set_user(user)
                client.set_password("SUNRISE")
            async with client:
                subscription = await client.create_subscription(100, Events())
                try:
                    await subscription.subscribe_events(client.nodes.server, await _alarm_type(client))
                except UaStatusCodeError as exc:
                    return type(exc).__name__
                return "Good"

        assert asyncio.run(go(None)) == "BadUserAccessDenied"
        assert asyncio.run(go("nckemu")) == "Good"


def test_malformed_event_filters_are_answered_and_the_server_serves_on() -> None:
    with two_faces() as (_, face):
        async def go() -> list[str]:
            outcomes = []
            async with Client(face.url, timeout=10) as client:
                subscription = await client.create_subscription(100, Events())
                for select in ([ua.SimpleAttributeOperand(TypeDefinitionId=ua.NodeId(987654, 7),
                                                           BrowsePath=[ua.QualifiedName("Nothing", 9)],
                                                           AttributeId=99)],
                               [ua.SimpleAttributeOperand(BrowsePath=[ua.QualifiedName("Message", 0)] * 40,
                                                          AttributeId=ua.AttributeIds.Value)], []):
                    params = ua.MonitoredItemCreateRequest()
                    params.ItemToMonitor = ua.ReadValueId(ua.NodeId(ua.ObjectIds.Server), ua.AttributeIds.EventNotifier)
                    params.MonitoringMode = ua.MonitoringMode.Reporting
                    params.RequestedParameters = ua.MonitoringParameters(
                        ClientHandle=1, QueueSize=10, Filter=ua.EventFilter(SelectClauses=select))
                    try:
                        results = await subscription.create_monitored_items([params])
                        outcomes.append(type(results[0]).__name__)
                    except UaStatusCodeError as exc:
                        outcomes.append(type(exc).__name__)
                ns = await client.get_namespace_index("SinumerikVarProvider")
                outcomes.append(str(await client.get_node(ua.NodeId("/Channel/State/progStatus", ns)).read_value()))
            return outcomes

        outcomes = asyncio.run(go())
    assert len(outcomes) == 4 and outcomes[-1].isdigit()


alarms = st.builds(Alarm, st.integers(1, 999_999), st.text(min_size=1, max_size=40), st.floats(0, 1e6),
                   st.lists(st.text(max_size=8), max_size=3).map(tuple))


@given(alarms, st.booleans())
def test_event_fields_follow_the_alarm(alarm: Alarm, raised: bool) -> None:
    fields = event_fields(AlarmEvent(alarm, raised, alarm.time_s), 2)
    assert fields["Severity"] in SEVERITIES
    assert fields["Retain"] is raised and fields["ActiveState/Id"] is raised
    assert fields["AlarmIdentifier"] == str(alarm.number) and fields["Message"].Text == alarm.text
    assert fields["AuxParameters"] == list(alarm.parameters)
    assert fields["NodeId"] == condition_id(alarm, 2)


@given(alarms, alarms)
def test_alarms_of_other_texts_are_other_conditions(first: Alarm, second: Alarm) -> None:
    if (first.number, first.text) != (second.number, second.text):
        assert condition_id(first, 2) != condition_id(second, 2) or first.text == second.text
