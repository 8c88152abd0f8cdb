"""OPC 40502 (CNC Systems): the ``CncInterface`` object with its axis, channel and spindle lists.

``Objects/CncInterface`` (browse name in the CNC namespace, as the specification's entry point) holds
one ``CncAxisType`` per machine axis that is no spindle, one ``CncChannelType`` per channel and one
``CncSpindleType`` per spindle, each with every mandatory variable of its type. What the NCK model knows
is fed from it through the BTSS variables (positions, speeds, overrides, states, program names; docs/
opcua.md lists them); what it does not model (loads, torques, power, gears, G and M functions) reads 0 or
empty. The positions are ``CncPositionDataType`` structures (actual, commanded, remaining distance),
sent encoded, and their three parts as variables of their own.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from asyncua import Server, ua

from nckemu import __version__
from nckemu.emulator.faces.opcua import nodesets
from nckemu.emulator.faces.opcua.feeds import Feed
from nckemu.emulator.faces.opcua.instances import HAS_COMPONENT, ORGANIZES, Instantiator, Made
from nckemu.emulator.faces.opcua.program_states import ABORTED
from nckemu.emulator.faces.opcua.units import (
    DEGREE,
    KILOWATT,
    MILLIMETRE,
    MILLIMETRE_PER_MINUTE,
    NEWTON_METRE,
    PERCENT,
    REVOLUTIONS_PER_MINUTE,
)
from nckemu.emulator.faces.opcua.values import raw_reader
from nckemu.emulator.machine.nck.channel import CHAN_RESET, PROG_ABORTED

if TYPE_CHECKING:
    from nckemu.emulator.faces.opcua.parts import ModelValues

# SINUMERIK codes -> OPC 40502 enumerations (ours, docs/assumptions.md)
OPERATION_MODE = {0: 0, 1: 1, 2: 2}          # opMode JOG/MDA/AUTO -> CncOperationMode Manual/MDA/Automatic
CHANNEL_STATUS = {0: 2, 1: 0, 2: 1}          # chanStatus reset/active/interrupted -> Reset/Active/Interrupted
# progStatus 1 interrupted, 2 stopped, 3 running, 4 waiting, 5 aborted -> CncChannelProgramStatus
# (aborted: Canceled or Stopped by the run's end, cnc_channel's variant)
PROGRAM_STATUS = {1: 3, 2: 0, 3: 1, 4: 2}
STOPPED, CANCELED = 0, 4
TURN_DIRECTION = {0: 2, 1: 0, 2: 1}          # turnState stopped/M3/M4 -> CncSpindleTurnDirection None/CW/CCW


def _first(kind: ua.VariantType, mapping: dict[int, int] | None = None) -> Callable[[object], ua.Variant]:
    def convert(raw: object) -> ua.Variant:
        value = raw[0]  # type: ignore[index]
        if mapping is not None:
            return ua.Variant(mapping.get(int(value), 0), kind)
        if kind == ua.VariantType.Double:
            return ua.Variant(float(value), kind)
        if kind == ua.VariantType.String:
            return ua.Variant(str(value), kind)
        if kind == ua.VariantType.Boolean:
            return ua.Variant(bool(value), kind)
        return ua.Variant(max(0, int(value)), kind)
    return convert


class CncInterfaceInstance:
    def __init__(self, models: ModelValues, maker: Instantiator) -> None:
        self.models, self.maker = models, maker
        self.face = models.face
        self.emulator = models.face.emulator
        self.made: Made | None = None
        self._binary: ua.NodeId | None = None

    def _btss(self, node_id: str) -> tuple[Callable[[], object], str]:
        name = self.face.node_name(node_id)
        return raw_reader(self.emulator, name), name.realm

    def _bind(self, made: Made, path: str, node_id: str, variant: Callable[[object], ua.Variant]) -> None:
        reader, realm = self._btss(node_id)
        self.models.bind(made[path], Feed(reader, variant, realm))

    def _units(self, made: Made, path: str, unit: ua.EUInformation, low: float, high: float) -> None:
        if made.get(f"{path}/EngineeringUnits") is not None:
            self.models.set(made[f"{path}/EngineeringUnits"], ua.Variant(unit))
        if made.get(f"{path}/EURange") is not None:
            self.models.set(made[f"{path}/EURange"], ua.Variant(ua.Range(low, high)))

    def _position(self, made: Made, path: str, actual: str | None, commanded: str | None,
                  remaining: str | None, unit: ua.EUInformation) -> None:
        """A CncPositionVariableType: the structure and its three parts, from SINUMERIK variables."""
        readers: list[Callable[[], object]] = []
        realm = "State"
        for part, node_id in (("ActPos", actual), ("CmdPos", commanded), ("RemDist", remaining)):
            if node_id is None:
                readers.append(lambda: [0.0])
                continue
            reader, realm = self._btss(node_id)
            readers.append(reader)
            self.models.bind(made[f"{path}/{part}"], Feed(reader, _first(ua.VariantType.Double), realm))
        binary = self._binary

        def structure() -> object:
            return tuple(float(read()[0]) for read in readers)  # type: ignore[index]

        def encoded(raw: object) -> ua.Variant:
            return ua.Variant(ua.ExtensionObject(TypeId=binary, Body=struct.pack("<3d", *raw)),  # type: ignore[arg-type]
                              ua.VariantType.ExtensionObject)
        self.models.bind(made[path], Feed(structure, encoded, realm))
        self._units(made, path, unit, -1.0e6, 1.0e6)

    def build(self) -> CncInterfaceInstance:
        types, models = self.maker.types, self.models
        cnc = models.ns(nodesets.CNC)
        self._binary = _binary_encoding(types, types.find(cnc, "CncPositionDataType"))
        self.made = made = self.maker.make(ua.NodeId(ua.ObjectIds.ObjectsFolder), types.find(cnc, "CncInterfaceType"),
                                           "CncInterface", root="CncInterface", reference=ORGANIZES,
                                           optional=("CncTypeName",), browse_namespace=cnc)
        for path, text in (("VendorName", "nckemu"), ("VendorRevision", __version__), ("Version", "1.0.0"),
                           ("CncTypeName", f"SINUMERIK (emulated: {self.emulator.machine.name})")):
            self.models.set(made[path], ua.Variant(text, ua.VariantType.String))
        channels: dict[int, Made] = {}
        for channel in sorted(self.emulator.nck.channels):
            channels[channel] = self._channel(types, cnc, made["CncChannelList"], channel)
        channel_1 = channels[min(channels)].root
        axes = sorted(self.emulator.machine.axes, key=lambda axis: axis.number)
        for axis in (axis for axis in axes if not axis.spindle):
            self._axis(types, cnc, made["CncAxisList"], axis, channel_1)
        for line, axis in enumerate((axis for axis in axes if axis.spindle), start=1):
            self._spindle(types, cnc, made["CncSpindleList"], axis, line, channel_1)
        return self

    def _channel(self, types: Any, cnc: int, parent: ua.NodeId, channel: int) -> Made:
        made = self.maker.make(parent, types.find(cnc, "CncChannelType"), f"Channel{channel}",
                               root=f"CncInterface/CncChannelList/Channel{channel}", reference=HAS_COMPONENT,
                               optional=("ActProgramLine",))
        u = f"[u{channel}]"
        self.models.set(made["Id"], ua.Variant(channel, ua.VariantType.UInt32))
        self._bind(made, "ActFeedrate", f"/Channel/State/actFeedRateIpo{u}", _first(ua.VariantType.Double))
        self._bind(made, "CmdFeedrate", f"/Channel/State/cmdFeedRateIpo{u}", _first(ua.VariantType.Double))
        self._bind(made, "ActOverride", f"/Channel/State/feedRateIpoOvr{u}", _first(ua.VariantType.Double))
        self._bind(made, "CmdOverride", f"/Channel/State/feedRateIpoOvr{u}", _first(ua.VariantType.Double))
        self._bind(made, "ActStatus", f"/Channel/State/chanStatus{u}", _first(ua.VariantType.Int32, CHANNEL_STATUS))
        self._program_status(made, channel)
        self._bind(made, "ActOperationMode", "/Bag/State/opMode[u1]", _first(ua.VariantType.Int32, OPERATION_MODE))
        self._bind(made, "CmdOperationMode", "/Bag/State/opMode[u1]", _first(ua.VariantType.Int32, OPERATION_MODE))
        self._bind(made, "ActMainProgramName", f"/Channel/ProgramInfo/progName{u}", _first(ua.VariantType.String))
        self._bind(made, "ActMainProgramFile", f"/Channel/ProgramInfo/workPandProgName{u}",
                   _first(ua.VariantType.String))
        self._current_program(made, channel)
        # OPC 40502 declares the block as an array (the current block and those prepared after it); the
        # channel prepares no blocks ahead, so it holds the current one alone.
        self._bind(made, "ActProgramBlock", f"/Channel/ProgramInfo/actBlock{u}",
                   lambda raw: ua.Variant([str(raw[0])], ua.VariantType.String))  # type: ignore[index]
        self._bind(made, "ActProgramLine", f"/Channel/ProgramInfo/actLineNumber{u}",
                   lambda raw: ua.Variant(str(int(raw[0])), ua.VariantType.String))  # type: ignore[index]
        self._bind(made, "ActModalOffsetFunction", f"/Channel/State/actFrameIndex{u}", _first(ua.VariantType.UInt32))
        self._bind(made, "ToolId", f"/Channel/State/actTNumber{u}", _first(ua.VariantType.UInt32))
        for path, unit in (("ActFeedrate", None), ("CmdFeedrate", None), ("ActOverride", None),
                           ("CmdOverride", None), ("ActJogIncrement", MILLIMETRE), ("DryRunFeed", None)):
            low, high = (0.0, 200.0) if "Override" in path else (0.0, 1.0e6)
            self._units(made, path, unit or _unit_of(path), low, high)
        for path, _value in made.paths.items():
            if path.startswith("PosTcp") and path.count("/") == 0:
                self._position(made, path, None, None, None, MILLIMETRE)
        return made

    def _current_program(self, made: Made, channel: int) -> None:
        """ActProgramName and ActProgramFile: the program the current block belongs to (a subprogram
        while one runs), in reset the selected main program's name and path."""
        main_name, realm = self._btss(f"/Channel/ProgramInfo/progName[u{channel}]")
        main_file, _realm = self._btss(f"/Channel/ProgramInfo/workPandProgName[u{channel}]")
        state = self.emulator.nck.channels[channel].state

        def raw() -> object:
            current = state.program if state.status != CHAN_RESET else ""  # in reset: the selected program
            return current, str(main_name()[0]), str(main_file()[0])  # type: ignore[index]

        def name(value: object) -> ua.Variant:
            current, main, _file = value  # type: ignore[misc]
            return ua.Variant(current.rsplit("/", 1)[-1] if current else main, ua.VariantType.String)

        def file(value: object) -> ua.Variant:
            current, _main, main = value  # type: ignore[misc]
            return ua.Variant(current or main, ua.VariantType.String)
        self.models.bind(made["ActProgramName"], Feed(raw, name, realm))
        self.models.bind(made["ActProgramFile"], Feed(raw, file, realm))

    def _program_status(self, made: Made, channel: int) -> None:
        """ActProgramStatus from progStatus; in reset (progStatus 5, aborted) Canceled only when a reset
        aborted the program (the umati program state Aborted), else Stopped: nothing has run since
        power-on, or the program ended normally."""
        status, realm = self._btss(f"/Channel/State/progStatus[u{channel}]")
        tracker = self.models.tracker(channel)

        def raw() -> object:
            return int(status()[0]), tracker.program.state  # type: ignore[index]

        def variant(value: object) -> ua.Variant:
            code, state = value  # type: ignore[misc]
            if code == PROG_ABORTED:
                return ua.Variant(CANCELED if state == ABORTED else STOPPED, ua.VariantType.Int32)
            return ua.Variant(PROGRAM_STATUS.get(code, STOPPED), ua.VariantType.Int32)
        self.models.bind(made["ActProgramStatus"], Feed(raw, variant, realm))

    def _axis(self, types: Any, cnc: int, parent: ua.NodeId, axis: Any, channel: ua.NodeId) -> None:
        made = self.maker.make(parent, types.find(cnc, "CncAxisType"), axis.name,
                               root=f"CncInterface/CncAxisList/{axis.name}", reference=HAS_COMPONENT)
        a = axis.number
        self.models.set(made["ActChannel"], ua.Variant(channel, ua.VariantType.NodeId))
        self.models.set(made["IsRotational"], ua.Variant(bool(axis.rotary), ua.VariantType.Boolean))
        referenced = self.emulator.nck.axes.referenced
        self.models.bind(made["IsReferenced"], Feed(lambda: referenced.get(a, False),
                                                    lambda raw: ua.Variant(bool(raw), ua.VariantType.Boolean),
                                                    "State"))
        unit = DEGREE if axis.rotary else MILLIMETRE
        self._position(made, "PosDirect", f"/Nckemu/Axis/NCKEMU_ACTUAL_POS[u{a}]",
                       f"/Nckemu/Axis/NCKEMU_COMMANDED_POS[u{a}]", f"/Nckemu/Channel/remainingDistance[u1,{a}]", unit)
        self._position(made, "PosIndirect", f"/Nckemu/Channel/workPosition[u1,{a}]", None, None, unit)
        self._drive(made, axis)
        for path in ("ActLoad", "ActPower", "ActTorque", "CmdTorque"):
            self._units(made, path, _unit_of(path), 0.0, 1.0e6)

    def _spindle(self, types: Any, cnc: int, parent: ua.NodeId, axis: Any, line: int, channel: ua.NodeId) -> None:
        made = self.maker.make(parent, types.find(cnc, "CncSpindleType"), axis.name,
                               root=f"CncInterface/CncSpindleList/{axis.name}", reference=HAS_COMPONENT)
        self.models.set(made["ActChannel"], ua.Variant(channel, ua.VariantType.NodeId))
        where = f"[u1,{line}]"
        self._bind(made, "ActSpeed", f"/Channel/Spindle/actSpeed{where}", _first(ua.VariantType.Double))
        self._bind(made, "ActOverride", f"/Channel/Spindle/speedOvr{where}", _first(ua.VariantType.Double))
        self._bind(made, "CmdOverride", f"/Channel/Spindle/speedOvr{where}", _first(ua.VariantType.Double))
        self._bind(made, "ActTurnDirection", f"/Channel/Spindle/turnState{where}",
                   _first(ua.VariantType.Int32, TURN_DIRECTION))
        self._bind(made, "ActStatus", f"/Channel/Spindle/actSpeed{where}",
                   lambda raw: ua.Variant(1 if float(raw[0]) else 0, ua.VariantType.Int32))  # type: ignore[index]
        self._position(made, "AnglePos", None, None, None, DEGREE)
        self._drive(made, axis)
        for path in ("ActSpeed", "CmdSpeed", "ActOverride", "CmdOverride", "ActLoad", "ActPower", "ActTorque",
                     "CmdTorque"):
            low, high = (0.0, 200.0) if "Override" in path else (0.0, 1.0e6)
            self._units(made, path, _unit_of(path), low, high)

    def _drive(self, made: Made, axis: Any) -> None:
        """ActLoad, ActPower, ActTorque of an axis or spindle: its drive's r0081, r0032, r0080 (the drive
        model, the values S7 and the BTSS node read); an axis without a drive keeps zero."""
        drive = self.emulator.nck.drives.drive_of_axis(axis.number)
        if drive is None:
            return
        for path, parameter in (("ActLoad", "r0081"), ("ActPower", "r0032"), ("ActTorque", "r0080")):
            if made.get(path) is not None:
                self._bind(made, path, f"/DriveVsa/Drive/{parameter}[u{drive.number}]", _first(ua.VariantType.Double))

    async def start(self, server: Server) -> None:
        pass

    async def stop(self) -> None:
        pass


_UNITS = {  # by the variable's name: UNECE common codes (units.py)
    "Feedrate": MILLIMETRE_PER_MINUTE, "DryRunFeed": MILLIMETRE_PER_MINUTE, "Override": PERCENT,
    "Speed": REVOLUTIONS_PER_MINUTE, "Power": KILOWATT, "Torque": NEWTON_METRE, "Load": PERCENT,
}


def _unit_of(path: str) -> ua.EUInformation:
    for suffix, unit in _UNITS.items():
        if path.endswith(suffix):
            return unit
    return MILLIMETRE


def _binary_encoding(types: Any, data_type: ua.NodeId) -> ua.NodeId:
    """The ``Default Binary`` encoding node of a structured data type."""
    for ref in types.node(data_type).references:
        if ref.IsForward and ref.ReferenceTypeId == ua.NodeId(ua.ObjectIds.HasEncoding) \
                and ref.BrowseName.Name == "Default Binary":
            return ref.NodeId  # type: ignore[no-any-return]
    raise KeyError(f"{data_type} has no Default Binary encoding")
