"""OPC 40501-1 (umati, OPC UA for Machine Tools): one ``MachineToolType`` instance under ``Machines``.

What each node shows and where it comes from is listed in docs/opcua.md; in short:

- Identification: the machine file's ``[opcua.identification]`` (manufacturer, model, serial number,
  software revision, location, year of construction, product instance URI), with defaults taken from the
  machine (its name, MD18030, MD18040 line 1).
- Monitoring/MachineTool: operation mode from the mode group's ``/Bag/State/opMode``, power-on duration
  (hours since the face started), feed override of channel 1 (``feedRateIpoOvr``). One
  ``ChannelMonitoringType`` per channel (``chanStatus``, ``opMode``, ``feedRateIpoOvr``,
  ``rapFeedRateOvr``) and one ``SpindleMonitoringType`` per spindle (``actSpeed`` non-zero, ``speedOvr``).
- Production: the active program (``/Channel/ProgramInfo/progName``, ``progStatus``), one job of channel
  1 in the production plan (runs completed ``actParts``, runs planned ``reqParts``, its state following
  ``progStatus``) and the statistics' parts in lifetime (``totalParts``).
- Notification/Messages: the NCK's alarms as ``AlertType`` events, raised and cleared with the alarm list.
- Equipment/Tools: one ``ToolType`` per tool of the NCK's tool table (T number, identifier).
- Monitoring/Stacklight: the machine file's lamps (``[opcua] stacklight``), each lit by a PLC bit.

Every value is read from the model through the BTSS variable it mirrors (``values.raw_reader``) on every
read and guarded by that variable's realm; the mappings of SINUMERIK codes to the model's enumerations
are ours (docs/assumptions.md).
"""

from __future__ import annotations

import copy
import logging
import re
import zlib
from collections.abc import Callable
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from asyncua import Server, ua

from nckemu.emulator.faces.opcua import nodesets, production
from nckemu.emulator.faces.opcua.alarms import AlarmEventQueue, severity_of
from nckemu.emulator.faces.opcua.feeds import Feed
from nckemu.emulator.faces.opcua.instances import HAS_COMPONENT, ORGANIZES, Instantiator, Made
from nckemu.emulator.faces.opcua.settings import SIGNAL_COLORS
from nckemu.emulator.faces.opcua.units import PERCENT
from nckemu.emulator.faces.opcua.values import PLC_AREAS, raw_reader, read_value
from nckemu.emulator.machine.nck.alarms import AlarmEvent
from nckemu.protocol.addresses import S7Area

if TYPE_CHECKING:
    from nckemu.emulator.faces.opcua.parts import ModelValues

log = logging.getLogger("nckemu.emulator.opcua.umati")

HAS_ORDERED_COMPONENT = ua.NodeId(ua.ObjectIds.HasOrderedComponent)
# SINUMERIK codes -> the model's enumerations (ours, docs/assumptions.md)
# opMode 0 JOG, 1 MDA, 2 AUTO -> MachineOperationMode (0 Manual, 1 Automatic, ...)
OPERATION_MODE = {0: 0, 1: 0, 2: 1}
# opMode -> ChannelMode (0 Automatic, 1 MdaMdi, 2 JogManual, 7 Other)
CHANNEL_MODE = {0: 2, 1: 1, 2: 0}
# chanStatus 0 reset, 1 active, 2 interrupted -> ChannelState (0 Active, 1 Interrupted, 2 Reset)
CHANNEL_STATE = {0: 2, 1: 0, 2: 1}


def product_instance_uri(name: str, serial: str) -> str:
    """The default ProductInstanceUri: nckemu's, the machine's own name (a fleet's machine's), its serial
    number; globally unique as long as serial numbers are (a fleet numbers them)."""
    parts = [re.sub(r"[^A-Za-z0-9._~-]+", "-", part).strip("-") or "machine" for part in (name, serial)]
    return f"urn:nckemu:{parts[0]}:{parts[1]}"


def _int(kind: ua.VariantType, mapping: dict[int, int] | None = None, default: int = 0) -> Callable[[object], ua.Variant]:
    def convert(raw: object) -> ua.Variant:
        value = int(raw[0])  # type: ignore[index]
        return ua.Variant(mapping.get(value, default) if mapping is not None else max(0, value), kind)
    return convert


def _double(raw: object) -> ua.Variant:
    return ua.Variant(float(raw[0]), ua.VariantType.Double)  # type: ignore[index]


def _text(raw: object) -> ua.Variant:
    return ua.Variant(str(raw[0]), ua.VariantType.String)  # type: ignore[index]


def _uint32(raw: object) -> ua.Variant:
    return ua.Variant(max(0, min(0xFFFFFFFF, int(float(raw[0])))), ua.VariantType.UInt32)  # type: ignore[index]


class MachineToolInstance:
    """The MachineTool instance of one face, built from the types in its address space."""

    def __init__(self, models: ModelValues, maker: Instantiator) -> None:
        self.models = models
        self.maker = maker
        self.face = models.face
        self.emulator = models.face.emulator
        self.made: Made | None = None
        self.alerts: Any = None
        self.messages: ua.NodeId | None = None
        self._template: Any = None
        self._alerts = AlarmEventQueue(self.emulator.nck.alarm_list, self._send, "OPC UA alert event")
        self.alerts_sent = 0
        self.production: production.Production | None = None

    # ------------------------------------------------------------------ helpers
    def feed(self, path: str, reader: Callable[[], object], variant: Callable[[object], ua.Variant],
             realm: str | None) -> None:
        assert self.made is not None
        self.models.bind(self.made[path], Feed(reader, variant, realm))

    def btss(self, node_id: str) -> tuple[Callable[[], object], str]:
        """The raw reader and realm of a SINUMERIK variable (the one the S7 and BTSS paths read)."""
        name = self.face.node_name(node_id)
        return raw_reader(self.emulator, name), name.realm

    def fed(self, path: str, node_id: str, variant: Callable[[object], ua.Variant]) -> None:
        reader, realm = self.btss(node_id)
        self.feed(path, reader, variant, realm)

    def value_of(self, node_id: str, default: object) -> object:
        """A SINUMERIK variable's value now (machine data for the identification), or ``default``."""
        try:
            value = read_value(self.emulator, self.face.node_name(node_id)).Value
        except Exception:
            return default
        return value if value not in ("", None) else default

    def _set(self, made: Made, path: str, variant: ua.Variant) -> None:
        self.models.set(made[path], variant)

    # ------------------------------------------------------------------ the instance
    def build(self) -> MachineToolInstance:
        models, types = self.models, self.maker.types
        mt, machinery = models.ns(nodesets.MACHINE_TOOL), models.ns(nodesets.MACHINERY)
        machines = _machines_folder(types, machinery)
        self.made = made = self.maker.make(  # named as the machine is among others (a fleet's own name)
            machines, types.find(mt, "MachineToolType"), self.emulator.name, root="MachineTool", reference=ORGANIZES,
            optional=("Identification/Model", "Identification/SoftwareRevision", "Identification/Location",
                      "Identification/YearOfConstruction", "Identification/ProductCode",
                      "Monitoring/MachineTool/FeedOverride", "Monitoring/MachineTool/PowerOnDuration",
                      "Production/ProductionPlan", "Production/Statistics/PartsProducedInLifetime",
                      "Production/ActiveProgram/JobIdentifier", "Production/ActiveProgram/JobNodeId",
                      *(f"Production/ActiveProgram/State/{path}" for path in production.LAST_TRANSITION),
                      "Notification/Messages", "Equipment/Tools")
            + (("Monitoring/Stacklight",) if self.face.settings.stacklight else ()))
        self._identification(made)
        self._monitoring(made, types, mt)
        self._production(made, types, mt)
        self._tools(made, types, mt)
        self._stacklight(made, types)
        self.messages = made["Notification/Messages"]
        return self

    def _identification(self, made: Made) -> None:
        table = dict(self.face.settings.identification)
        machine = self.emulator.machine
        manufacturer = str(table.get("manufacturer", "nckemu"))
        model = str(table.get("model", machine.name))
        # The serial number and software revision the S7 face serves (MD18030, MD18040 line 1), without
        # the padding of the fixed-length field.
        serial = str(table.get("serial_number", self.emulator.serial_number))
        software = str(table.get("software_revision",
                                 str(self.value_of("/NC/_N_NC_TEA_ACX/$MN_VERSION_INFO[u1,1]", "")).rstrip()))
        uri = str(table.get("product_instance_uri", product_instance_uri(self.emulator.name, serial)))
        strings = {"Identification/SerialNumber": serial, "Identification/SoftwareRevision": software,
                   "Identification/ProductInstanceUri": uri,
                   "Identification/Location": str(table.get("location", "")),
                   "Identification/ProductCode": str(table.get("product_code", ""))}
        for path, text in strings.items():
            self._set(made, path, ua.Variant(text, ua.VariantType.String))
        self._set(made, "Identification/Manufacturer", ua.Variant(ua.LocalizedText(manufacturer)))
        self._set(made, "Identification/Model", ua.Variant(ua.LocalizedText(model)))
        self._set(made, "Identification/YearOfConstruction",
                  ua.Variant(int(table.get("year_of_construction", 0)), ua.VariantType.UInt16))

    def _monitoring(self, made: Made, types: Any, mt: int) -> None:
        self.fed("Monitoring/MachineTool/OperationMode", "/Bag/State/opMode[u1]",
                 _int(ua.VariantType.Int32, OPERATION_MODE, default=5))
        started_s = self.emulator.clock.now_s()
        clock = self.emulator.clock
        self.feed("Monitoring/MachineTool/PowerOnDuration", lambda: int((clock.now_s() - started_s) // 3600),
                  lambda hours: ua.Variant(hours, ua.VariantType.UInt32), "State")
        self._override(made, "Monitoring/MachineTool/FeedOverride", "/Channel/State/feedRateIpoOvr[u1]")
        monitoring = made["Monitoring"]
        for channel in sorted(self.emulator.nck.channels):
            name = str(self.value_of(f"/NC/_N_CH_TEA_ACX/$MC_CHAN_NAME[u{channel}]", f"CHAN{channel}"))
            entry = self.maker.make(monitoring, types.find(mt, "ChannelMonitoringType"), name,
                                    root=f"MachineTool/Monitoring/Channel{channel}", reference=HAS_COMPONENT,
                                    optional=("RapidOverride",))
            self.models.set(entry["Name"], ua.Variant(name, ua.VariantType.String))
            self._bind(entry, "ChannelState", f"/Channel/State/chanStatus[u{channel}]",
                       _int(ua.VariantType.Int32, CHANNEL_STATE, default=2))
            self._bind(entry, "ChannelMode", "/Bag/State/opMode[u1]", _int(ua.VariantType.Int32, CHANNEL_MODE, 7))
            self._override(entry, "FeedOverride", f"/Channel/State/feedRateIpoOvr[u{channel}]")
            self._override(entry, "RapidOverride", f"/Channel/State/rapFeedRateOvr[u{channel}]")
        spindles = sorted((axis for axis in self.emulator.machine.axes if axis.spindle), key=lambda axis: axis.number)
        for line, axis in enumerate(spindles, start=1):
            entry = self.maker.make(monitoring, types.find(mt, "SpindleMonitoringType"), axis.name,
                                    root=f"MachineTool/Monitoring/Spindle{line}", reference=HAS_COMPONENT,
                                    optional=("Override",))
            self.models.set(entry["Name"], ua.Variant(axis.name, ua.VariantType.String))
            self._bind(entry, "IsRotating", f"/Channel/Spindle/actSpeed[u1,{line}]",
                       lambda raw: ua.Variant(float(raw[0]) != 0.0, ua.VariantType.Boolean))  # type: ignore[index]
            self._override(entry, "Override", f"/Channel/Spindle/speedOvr[u1,{line}]")

    def _bind(self, made: Made, path: str, node_id: str, variant: Callable[[object], ua.Variant]) -> None:
        reader, realm = self.btss(node_id)
        self.models.bind(made[path], Feed(reader, variant, realm))

    def _override(self, made: Made, path: str, node_id: str) -> None:
        """An AnalogUnitRangeType override in percent, its range the SINUMERIK variable's limits."""
        self._bind(made, path, node_id, _double)
        name = self.face.node_name(node_id)
        spec = getattr(name, "spec", None)
        low = float(spec.minimum) if spec is not None and spec.minimum is not None else 0.0
        high = float(spec.maximum) if spec is not None and spec.maximum is not None else 200.0
        self.models.set(made[f"{path}/EURange"], ua.Variant(ua.Range(low, high)))
        self.models.set(made[f"{path}/EngineeringUnits"], ua.Variant(PERCENT))

    def _production(self, made: Made, types: Any, mt: int) -> None:
        self.fed("Production/ActiveProgram/Name", "/Channel/ProgramInfo/progName[u1]", _text)
        self._set(made, "Production/ActiveProgram/NumberInList", ua.Variant(0, ua.VariantType.UInt16))
        self.fed("Production/Statistics/PartsProducedInLifetime", "/Channel/State/totalParts[u1]", _uint32)
        job = self.maker.make(made["Production/ProductionPlan"], types.find(mt, "ProductionJobType"), "Job1",
                              root="MachineTool/Production/ProductionPlan/Job1", reference=HAS_ORDERED_COMPONENT,
                              optional=tuple(f"State/{path}" for path in production.LAST_TRANSITION))
        self._set(made, "Production/ActiveProgram/JobIdentifier", ua.Variant("Job1", ua.VariantType.String))
        self._set(made, "Production/ActiveProgram/JobNodeId", ua.Variant(job.root, ua.VariantType.NodeId))
        self.models.set(job["Identifier"], ua.Variant("Job1", ua.VariantType.String))
        self.models.set(job["NumberInList"], ua.Variant(0, ua.VariantType.UInt16))
        self._bind(job, "RunsCompleted", "/Channel/State/actParts[u1]", _uint32)
        self._bind(job, "RunsPlanned", "/Channel/State/reqParts[u1]", _uint32)
        self._bind(job, "RunsPlanned/IsValid", "/Channel/State/reqParts[u1]",
                   lambda raw: ua.Variant(float(raw[0]) > 0, ua.VariantType.Boolean))  # type: ignore[index]
        # the state machines follow channel 1's program (production.py)
        self.production = production.Production(self)
        self.production.bind(made, job, "Production/ActiveProgram/State", "State")
        program = self.maker.make(job["ProductionPrograms"], types.find(mt, "ProductionProgramType"), "Program1",
                                  root="MachineTool/Production/ProductionPlan/Job1/ProductionPrograms/Program1",
                                  reference=HAS_ORDERED_COMPONENT)
        self._bind(program, "Name", "/Channel/ProgramInfo/progName[u1]", _text)
        self.models.set(program["NumberInList"], ua.Variant(0, ua.VariantType.UInt16))

    def _tools(self, made: Made, types: Any, mt: int) -> None:
        tools = made["Equipment/Tools"]
        tool_type = types.find(mt, "ToolType")
        for tool in sorted(self.emulator.machine.tools, key=lambda tool: tool.number):
            name = tool.ident or f"T{tool.number}"
            entry = self.maker.make(tools, tool_type, name, root=f"MachineTool/Equipment/Tools/T{tool.number}",
                                    reference=HAS_COMPONENT, optional=("Identifier", "Name"))
            number, ident = tool.number, tool.ident

            def constant(value: object) -> Callable[[], object]:
                return lambda: value
            fixed = {"ControlIdentifier1": (number, ua.VariantType.UInt32),
                     "ControlIdentifierInterpretation": (0, ua.VariantType.Int32),   # NumberBased: T numbers
                     "Locked": (False, ua.VariantType.Boolean),
                     "Locked/ReasonForLocking": (0, ua.VariantType.Int32),           # CapabilityUnavailable
                     "Identifier": (ident, ua.VariantType.String), "Name": (ident, ua.VariantType.String)}
            for path, (value, kind) in fixed.items():
                self.models.bind(entry[path], Feed(constant(value), lambda raw, kind=kind: ua.Variant(raw, kind),
                                                   "Tool"))

    def _stacklight(self, made: Made, types: Any) -> None:
        """The machine file's lamps (``[[opcua.stacklight]]``), each lit by its PLC bit."""
        lamps = self.face.settings.stacklight
        if not lamps:
            return
        ia = self.models.ns(nodesets.IA)
        self._set(made, "Monitoring/Stacklight/StacklightMode", ua.Variant(0, ua.VariantType.Int32))  # Segmented
        lamp_type = types.find(ia, "StackElementLightType")
        for number, (color, bit) in enumerate(lamps):
            entry = self.maker.make(made["Monitoring/Stacklight"], lamp_type, f"Lamp{number + 1}",
                                    root=f"MachineTool/Monitoring/Stacklight/Lamp{number + 1}",
                                    reference=HAS_ORDERED_COMPONENT, optional=("SignalColor", "SignalOn", "SignalMode"))
            self.models.set(entry["NumberInList"], ua.Variant(number, ua.VariantType.UInt32))
            self.models.set(entry["SignalColor"], ua.Variant(SIGNAL_COLORS.index(color), ua.VariantType.Int32))
            self.models.set(entry["SignalMode"], ua.Variant(0, ua.VariantType.Int32))  # Continuous
            name = self.face.node_name(f"/Plc/{bit}")
            area = PLC_AREAS[name.area]
            self.models.bind(entry["SignalOn"], Feed(
                raw_reader(self.emulator, name), lambda raw: ua.Variant(bool(raw[0]), ua.VariantType.Boolean),  # type: ignore[index]
                name.realm, plc=(area, name.db if area == S7Area.DB else 0, name.byte, name.byte + 1)))

    # ------------------------------------------------------------------ alarms as alerts
    async def start(self, server: Server) -> None:
        """The Messages object sends the NCK's alarms as ``AlertType`` events."""
        mt = self.models.ns(nodesets.MACHINE_TOOL)
        alert_type = self.maker.types.find(mt, "AlertType")
        messages = server.get_node(self.messages)
        await messages.write_attribute(ua.AttributeIds.EventNotifier, ua.DataValue(ua.Variant(
            ua.EventNotifier.SubscribeToEvents, ua.VariantType.Byte)))
        self.alerts = await server.get_event_generator(alert_type, messages)
        self._template = self.alerts.event
        self._alerts.start()
        if self.production is not None:
            await self.production.start(server)

    async def stop(self) -> None:
        self._alerts.stop()
        if self.production is not None:
            await self.production.stop()

    async def _send(self, event: AlarmEvent) -> None:
        """An ``AlertType`` event from Notification/Messages: the alarm's number as ErrorCode and condition
        name, its text, severity (as the CncAlarmType events), active state and retain."""
        alarm, active = event.alarm, event.raised
        fields = copy.copy(self._template)  # one object per event: asyncua keeps the retained ones
        values: dict[str, Any] = {
            "SourceName": "NCK", "Message": ua.LocalizedText(alarm.text), "Severity": severity_of(alarm),
            "ConditionName": str(alarm.number), "Retain": active, "ErrorCode": str(alarm.number),
            "ActiveState": ua.LocalizedText("Active" if active else "Inactive"), "ActiveState/Id": active,
            "EnabledState": ua.LocalizedText("Enabled"), "EnabledState/Id": True,
            "AckedState": ua.LocalizedText("Acknowledged"), "AckedState/Id": True,
            "NodeId": ua.NodeId(f"MachineTool/Notification/Messages/{alarm.number}/"
                                f"{zlib.crc32(alarm.text.encode()):08x}", self.models.instance_namespace),
        }
        for name, value in values.items():
            setattr(fields, name, value)
            if not fields.data_types.get(name):  # asyncua found no data type for some imported fields
                fields.data_types[name] = _VARIANT_OF.get(type(value), ua.VariantType.Variant)
        self.alerts.event = fields
        await self.alerts.trigger(time_attr=datetime.now(UTC))
        self.alerts_sent += 1


_VARIANT_OF = {str: ua.VariantType.String, bool: ua.VariantType.Boolean, int: ua.VariantType.UInt16,
               ua.LocalizedText: ua.VariantType.LocalizedText, ua.NodeId: ua.VariantType.NodeId}


def _machines_folder(types: Any, machinery: int) -> ua.NodeId:
    """Machinery's entry point ``Objects/Machines``."""
    for ref in types.node(ua.NodeId(ua.ObjectIds.ObjectsFolder)).references:
        if ref.IsForward and ref.BrowseName.Name == "Machines" and ref.BrowseName.NamespaceIndex == machinery:
            return ref.NodeId  # type: ignore[no-any-return]
    raise KeyError("no Machines folder under Objects (Machinery NodeSet)")
