"""Alarm events of the OPC UA face: the NCK's alarms as ``CncAlarmType`` events on the Server object.

The SINUMERIK OPC UA server reports alarms as events of OPC 40502's ``CncAlarmType`` (a
``DiscreteAlarmType`` with ``AlarmIdentifier``, ``AuxParameters``, ``HelpSource``), severity 1, 500 or
1000, without acknowledgement or comments, with ConditionRefresh, to sessions with the AlarmRead right.
Here each alarm raised or cleared on the NCK's alarm list (``nck/alarms.py``) becomes one event: raised
with ``Retain`` and ``ActiveState/Id`` true, cleared with both false. asyncua keeps the retained ones
and sends them again between RefreshStart and RefreshEnd events when a client calls ConditionRefresh.
Acknowledge and AddComment are not offered (no method nodes on the type): the controller supports
neither. With the CNC model on (models.py), the type is the CNC NodeSet's own ``CncAlarmType`` (namespace
``http://opcfoundation.org/UA/CNC``) and each event's SourceNode is the ``CncInterface`` object; without
it, a type of the same name and fields is made in ``http://opcfoundation.org/UA/CNC/``. Which severity an alarm gets is ours (``severity_of``, docs/assumptions.md).
"""

from __future__ import annotations

import asyncio
import copy
import logging
import threading
import zlib
from collections.abc import Awaitable, Callable
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from asyncua import Server, ua

from nckemu.emulator.machine.nck.alarms import Alarm, AlarmEvent, Alarms

if TYPE_CHECKING:
    from nckemu.emulator.faces.opcua.parts import AlarmHost

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.opcua.alarms")

CNC_NAMESPACE = "http://opcfoundation.org/UA/CNC/"
SEVERITIES = (1, 500, 1000)
# The rights that let a session receive alarm events.
ALARM_RIGHTS = frozenset({"AlarmRead", "SinuReadAll", "SinuWriteAll"})


def severity_of(alarm: Alarm) -> int:
    """1000 for NCK alarms (numbers below 100000: the NCK's own ranges), 500 for the PLC's alarm ranges
    (400000..799999, where nckemu's own 700999 falls), 1 for the rest (messages)."""
    if alarm.number < 100_000:
        return 1000
    if 400_000 <= alarm.number < 800_000:
        return 500
    return 1


def condition_name(alarm: Alarm) -> str:
    return str(alarm.number)


def condition_id(alarm: Alarm, namespace: int) -> ua.NodeId:
    """One condition per alarm on the list (the list tells alarms apart by their text)."""
    return ua.NodeId(f"/Nck/Alarm/{alarm.number}/{zlib.crc32(alarm.text.encode()):08x}", namespace)


def event_fields(event: AlarmEvent, namespace: int) -> dict[str, Any]:
    """The fields a raised or cleared alarm sets on a ``CncAlarmType`` event."""
    alarm, active = event.alarm, event.raised
    state = ua.LocalizedText("Active" if active else "Inactive")
    return {
        "NodeId": condition_id(alarm, namespace), "SourceName": "NCK",
        "Message": ua.LocalizedText(alarm.text), "Severity": severity_of(alarm),
        "ConditionName": condition_name(alarm), "Retain": active,
        "ActiveState": state, "ActiveState/Id": active,
        "EnabledState": ua.LocalizedText("Enabled"), "EnabledState/Id": True,
        "AckedState": ua.LocalizedText("Acknowledged"), "AckedState/Id": True,  # nothing to acknowledge
        "AlarmIdentifier": str(alarm.number), "AuxParameters": list(alarm.parameters), "HelpSource": "",
    }


class AlarmEventQueue:
    """The alarms raised and cleared on an NCK's alarm list (told on any thread), handed in order to
    ``send`` by one task on the face's loop. ``start`` on that loop: it also queues the alarms already
    pending, so that a client's ConditionRefresh finds them."""

    def __init__(self, alarm_list: Alarms, send: Callable[[AlarmEvent], Awaitable[None]], what: str) -> None:
        self.alarm_list = alarm_list
        self._send = send
        self._what = what  # named in the log line of an event that could not be sent
        self._pending: list[AlarmEvent] = []
        self._sender: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._loop_thread = 0

    def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._loop_thread = threading.get_ident()
        self.alarm_list.listeners.append(self.told)
        for alarm in self.alarm_list.pending:  # raised before the face started
            self.told(AlarmEvent(alarm, True, alarm.time_s))

    def stop(self) -> None:
        if self.told in self.alarm_list.listeners:
            self.alarm_list.listeners.remove(self.told)
        if self._sender is not None:
            self._sender.cancel()

    def told(self, event: AlarmEvent) -> None:
        self._pending.append(event)
        loop = self._loop
        if self._sender is not None or loop is None:
            return
        if threading.get_ident() == self._loop_thread:
            self._start_sender()
        else:
            loop.call_soon_threadsafe(self._start_sender)

    def _start_sender(self) -> None:
        if self._sender is None and self._loop is not None:
            self._sender = self._loop.create_task(self._send_pending())

    async def _send_pending(self) -> None:
        try:
            while self._pending:
                await self._send(self._pending.pop(0))
        except Exception:  # an event that cannot be sent must not stop the ones after it
            log.exception(self._what)
        finally:
            self._sender = None
            if self._pending:
                self._start_sender()


class AlarmEvents:
    """Sends the alarm events of one face's emulator; ``start`` after the server is initialised."""

    def __init__(self, face: AlarmHost) -> None:
        self.face = face
        self._generator: Any = None
        self._template: Any = None
        self._source: ua.NodeId | None = None
        self.namespace_index = 0   # the namespace of CncAlarmType's own fields (AlarmIdentifier ...)
        self._queue = AlarmEventQueue(face.emulator.nck.alarm_list, self._send, "OPC UA alarm event")
        self.sent = 0

    async def start(self, server: Server) -> None:
        official = self.face.models.cnc_alarm_type()  # OPC 40502's own type when its NodeSet is loaded
        if official is not None:
            event_type: Any = official
            self.namespace_index = official.NamespaceIndex
        else:
            self.namespace_index = await server.register_namespace(CNC_NAMESPACE)
            event_type = await server.create_custom_event_type(
                self.namespace_index, "CncAlarmType", ua.ObjectIds.DiscreteAlarmType,
                [("AlarmIdentifier", ua.VariantType.String), ("AuxParameters", ua.VariantType.String),
                 ("HelpSource", ua.VariantType.String)])
        self._generator = await server.get_event_generator(event_type, ua.ObjectIds.Server)
        self._template = self._generator.event
        self._source = self.face.models.cnc_interface()  # the alarms' source: the CncInterface object
        self._queue.start()

    async def stop(self) -> None:
        self._queue.stop()

    async def _send(self, event: AlarmEvent) -> None:
        fields = copy.copy(self._template)  # one object per event: asyncua keeps the retained ones
        for name, value in event_fields(event, self.face.namespace).items():
            setattr(fields, name, value)
        if self._source is not None:
            fields.SourceNode = self._source
        self._generator.event = fields
        await self._generator.trigger(time_attr=datetime.now(UTC))
        self.sent += 1
