"""The umati (OPC 40501-1 MachineTool) and CNC (OPC 40502) models on the OPC UA face.

The conformance test reads the NodeSet files themselves (ElementTree, not asyncua's importer): for every
object of the instances whose type a file declares, each Mandatory child the type and its supertypes
declare (and their Mandatory children, recursively) must exist with the declared browse name, node class,
type definition (or a subtype), data type (or a subtype) and access level, and read with a good status.
The other tests read the same value through S7, the SINUMERIK node id and the umati node, subscribe to
umati values while the machine changes, and check that the BTSS realms guard the umati view.
"""

from __future__ import annotations

import asyncio
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua

from nckemu.clients import NckClient
from nckemu.emulator.faces.opcua import OpcUaFace, nodesets
from nckemu.emulator.runner import EmulatorThread
from tests.support.opcua_tools import connect, two_faces

DEFAULT_MACHINE = resources.files("nckemu.emulator.machine").joinpath("machines/default.toml")

pytestmark = [pytest.mark.timeout(300),
              pytest.mark.skipif(nodesets.find() is None, reason=nodesets.how_to_get())]

UA = "http://opcfoundation.org/UA/"
_NS = "{http://opcfoundation.org/UA/2011/03/UANodeSet.xsd}"
MANDATORY = (UA, "i=78")
CHILD_REFERENCES = {"HasComponent", "HasProperty", "HasOrderedComponent", "HasAddIn", "Organizes"}
Key = tuple[str, str]   # (namespace URI, node id in that namespace)


@dataclass
class XmlNode:
    key: Key
    tag: str
    browse: tuple[str, str]
    refs: list[tuple[str, bool, Key]] = field(default_factory=list)
    data_type: Key | None = None
    access: int = 1
    value_rank: int = -1


class NodeSets:
    """The NodeSet files as published: nodes, their references, aliases resolved."""

    def __init__(self, directory: Path) -> None:
        self.nodes: dict[Key, XmlNode] = {}
        names = ["Opc.Ua.NodeSet2.xml"] + [name for _uri, name in nodesets.FILES]
        for name in names:
            root = ET.parse(directory / name).getroot()
            uris_element = root.find(_NS + "NamespaceUris")
            uris = [UA] + ([u.text or "" for u in uris_element] if uris_element is not None else [])
            aliases_element = root.find(_NS + "Aliases")
            aliases = {a.get("Alias"): a.text for a in (aliases_element if aliases_element is not None else [])}

            def key(text: str, uris: list[str] = uris, aliases: dict[Any, Any] = aliases) -> Key:
                text = aliases.get(text, text).strip()
                if text.startswith("ns="):
                    index, rest = text[3:].split(";", 1)
                    return uris[int(index)], rest
                return UA, text

            def browse(text: str, uris: list[str] = uris) -> tuple[str, str]:
                if ":" in text:
                    index, rest = text.split(":", 1)
                    if index.isdigit():
                        return uris[int(index)], rest
                return UA, text

            for element in root:
                if not element.tag.startswith(_NS + "UA"):
                    continue
                node = XmlNode(key(element.get("NodeId", "")), element.tag[len(_NS):],
                               browse(element.get("BrowseName", "")))
                references = element.find(_NS + "References")
                for ref in references if references is not None else []:
                    node.refs.append((aliases.get(ref.get("ReferenceType"), ref.get("ReferenceType")),
                                      ref.get("IsForward", "true") != "false", key(ref.text or "")))
                if element.get("DataType"):
                    node.data_type = key(element.get("DataType", ""))
                node.access = int(element.get("AccessLevel", "1"))
                node.value_rank = int(element.get("ValueRank", "-1"))
                self.nodes.setdefault(node.key, node)

    def _target(self, key: Key, reference: str, forward: bool = True) -> Key | None:
        names = {"HasTypeDefinition": "i=40", "HasModellingRule": "i=37", "HasSubtype": "i=45"}
        for ref_type, is_forward, target in self.nodes[key].refs:
            if is_forward == forward and ref_type in (reference, names.get(reference)):
                return target
        return None

    def type_definition(self, key: Key) -> Key | None:
        return self._target(key, "HasTypeDefinition")

    def supertype(self, key: Key) -> Key | None:
        return self._target(key, "HasSubtype", forward=False)

    def is_subtype(self, key: Key, of: Key) -> bool:
        current: Key | None = key
        while current is not None and current in self.nodes:
            if current == of:
                return True
            current = self.supertype(current)
        return current == of

    def _own(self, key: Key) -> dict[str, Key]:
        found: dict[str, Key] = {}
        for ref_type, forward, target in self.nodes[key].refs:
            if forward and ref_type in CHILD_REFERENCES | {"i=47", "i=46", "i=49", "i=17604", "i=35"} \
                    and target in self.nodes:
                found.setdefault(self.nodes[target].browse[1], target)
        return found

    def type_children(self, type_key: Key) -> dict[str, Key]:
        found: dict[str, Key] = {}
        current: Key | None = type_key
        while current is not None and current in self.nodes:
            for name, child in self._own(current).items():
                found.setdefault(name, child)
            current = self.supertype(current)
        return found

    def declaration_children(self, declaration: Key) -> dict[str, Key]:
        found = dict(self._own(declaration))
        type_key = self.type_definition(declaration)
        if type_key is not None:
            for name, child in self.type_children(type_key).items():
                found.setdefault(name, child)
        return found

    def mandatory(self, children: dict[str, Key]) -> dict[str, Key]:
        return {name: key for name, key in children.items()
                if self._target(key, "HasModellingRule") == MANDATORY}


@pytest.fixture(scope="module")
def xml() -> NodeSets:
    directory = nodesets.find()
    assert directory is not None
    return NodeSets(directory)


@pytest.fixture(scope="module")
def faces() -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    with two_faces() as pair:
        assert pair[1].models.on
        yield pair


def run(coroutine: Any) -> Any:
    return asyncio.run(coroutine)


async def _machine(client: Client) -> Any:
    """Objects/Machines -> the MachineToolType instance, found by browsing."""
    namespaces = await client.get_namespace_array()
    machinery = namespaces.index(nodesets.MACHINERY)
    machines = await client.nodes.objects.get_child(f"{machinery}:Machines")
    children = await machines.get_children()
    assert len(children) == 1
    return children[0]


async def _key(client: Client, nodeid: ua.NodeId, namespaces: list[str]) -> Key:
    identifier = nodeid.to_string().split(";", 1)[-1] if nodeid.NamespaceIndex else nodeid.to_string()
    return namespaces[nodeid.NamespaceIndex], identifier


async def _check_instance(client: Client, xml: NodeSets, root: Any, problems: list[str]) -> int:
    """Every mandatory child, recursively, of every typed object below ``root``; how many were checked."""
    namespaces = await client.get_namespace_array()
    checked = 0

    async def check_children(node: Any, expected: dict[str, Key], where: str) -> None:
        nonlocal checked
        present = {(namespaces[d.BrowseName.NamespaceIndex], d.BrowseName.Name): d
                   for d in await node.get_children_descriptions()}
        for name, declaration in xml.mandatory(expected).items():
            decl = xml.nodes[declaration]
            found = present.get(decl.browse)
            path = f"{where}/{name}"
            checked += 1
            if found is None:
                problems.append(f"{path}: missing")
                continue
            child = client.get_node(found.NodeId)
            node_class = {"UAObject": ua.NodeClass.Object, "UAVariable": ua.NodeClass.Variable,
                          "UAMethod": ua.NodeClass.Method}[decl.tag]
            if found.NodeClass != node_class:
                problems.append(f"{path}: node class {found.NodeClass}, declared {node_class}")
            declared_type = xml.type_definition(declaration)
            if declared_type is not None:
                actual_type = await _key(client, found.TypeDefinition, namespaces)
                if not xml.is_subtype(actual_type, declared_type):
                    problems.append(f"{path}: type definition {actual_type}, declared {declared_type}")
            if decl.tag == "UAVariable":
                data_type, access, value = await child.read_attributes(
                    [ua.AttributeIds.DataType, ua.AttributeIds.AccessLevel, ua.AttributeIds.Value])
                actual_data_type = await _key(client, data_type.Value.Value, namespaces)
                if decl.data_type is not None and not xml.is_subtype(actual_data_type, decl.data_type):
                    problems.append(f"{path}: data type {actual_data_type}, declared {decl.data_type}")
                if access.Value.Value != decl.access:
                    problems.append(f"{path}: access level {access.Value.Value}, declared {decl.access}")
                if not value.StatusCode.is_good():
                    problems.append(f"{path}: read {value.StatusCode.name}")
                elif value.Value is None or (value.Value.Value is None and decl.value_rank < 0):
                    problems.append(f"{path}: no value")
            await check_children(child, xml.declaration_children(declaration), path)

    async def walk(node: Any, where: str, depth: int) -> None:
        type_node = await node.read_type_definition()
        if type_node is not None:
            type_key = await _key(client, type_node, namespaces)
            if type_key in xml.nodes and type_key[0] != UA:
                await check_children(node, xml.type_children(type_key), where)
        if depth > 8:
            return
        for description in await node.get_children_descriptions():
            if description.NodeClass == ua.NodeClass.Object:
                await walk(client.get_node(description.NodeId), f"{where}/{description.BrowseName.Name}", depth + 1)

    await walk(root, (await root.read_browse_name()).Name, 0)
    return checked


def test_instances_hold_every_mandatory_node_of_their_types_as_the_nodesets_declare(
        faces: tuple[EmulatorThread, OpcUaFace], xml: NodeSets) -> None:
    _, face = faces

    async def go() -> tuple[list[str], int, Any]:
        problems: list[str] = []
        async with Client(face.url, timeout=30) as client:
            machine = await _machine(client)
            machine_type = await _key(client, await machine.read_type_definition(), await client.get_namespace_array())
            checked = await _check_instance(client, xml, machine, problems)
            cnc_index = (await client.get_namespace_array()).index(nodesets.CNC)
            cnc = await client.nodes.objects.get_child(f"{cnc_index}:CncInterface")
            checked += await _check_instance(client, xml, cnc, problems)
        return problems, checked, machine_type

    problems, checked, machine_type = run(go())
    assert xml.nodes[machine_type].browse == (nodesets.MACHINE_TOOL, "MachineToolType")
    assert problems == []
    assert checked > 300  # MachineTool, channels, spindles, jobs, tools, the CNC lists


async def _umati(client: Client, *path: str) -> Any:
    node = await _machine(client)
    namespaces = await client.get_namespace_array()
    for name in path:
        for description in await node.get_children_descriptions():
            if description.BrowseName.Name == name:
                node = client.get_node(description.NodeId)
                break
        else:
            raise AssertionError(f"no {name} below {await node.read_browse_name()} ({namespaces})")
    return node


def test_one_value_three_paths_after_an_s7_write(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """The channel's feed override: put over S7, read over S7, as /Channel/State/feedRateIpoOvr and as
    Monitoring/<channel>/FeedOverride and Monitoring/MachineTool/FeedOverride."""
    emulator, face = faces

    async def over_opcua() -> tuple[float, float, float]:
        async with Client(face.url, timeout=30) as client:
            ns = await client.get_namespace_index("SinumerikVarProvider")
            btss = await client.get_node(ua.NodeId("/Channel/State/feedRateIpoOvr[u1]", ns)).read_value()
            channel = await (await _umati(client, "Monitoring", "CHAN1", "FeedOverride")).read_value()
            machine = await (await _umati(client, "Monitoring", "MachineTool", "FeedOverride")).read_value()
            return btss, channel, machine

    for value in (37.5, 120.0):
        with NckClient("127.0.0.1", emulator.port) as nck:
            nck.put({"feedRateIpoOvr[C1]": value})
            over_s7 = nck.get("feedRateIpoOvr[C1]")[0]
        assert (over_s7, *run(over_opcua())) == (value, value, value, value)


def test_subscriptions_follow_the_machine(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """A start over S7 (the channel command), spindle override puts over S7, a PI program select over S7
    and the model's own change (the spindle turning) each reach the umati subscriptions as the SINUMERIK
    node's do: every value, and in the same push (one source timestamp for both)."""
    emulator, face = faces
    seen: dict[str, list[Any]] = {}
    stamps: dict[str, dict[Any, Any]] = {}

    class Handler:
        def __init__(self, names: dict[Any, str]) -> None:
            self.names = names

        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            name = self.names[node.nodeid]
            seen.setdefault(name, []).append(value)
            stamps.setdefault(name, {})[value] = data.monitored_item.Value.SourceTimestamp

    async def go() -> None:
        async with Client(face.url, timeout=30) as client:
            ns = await client.get_namespace_index("SinumerikVarProvider")
            nodes = {
                "state": await _umati(client, "Monitoring", "CHAN1", "ChannelState"),
                "program": await _umati(client, "Production", "ActiveProgram", "State", "CurrentState"),
                "name": await _umati(client, "Production", "ActiveProgram", "Name"),
                "override": await _umati(client, "Monitoring", "SP1", "Override"),
                "rotating": await _umati(client, "Monitoring", "SP1", "IsRotating"),
                "btss": client.get_node(ua.NodeId("/Channel/State/chanStatus[u1]", ns)),
                "btss override": client.get_node(ua.NodeId("/Channel/Spindle/speedOvr[u1,1]", ns)),
                "btss name": client.get_node(ua.NodeId("/Channel/ProgramInfo/progName[u1]", ns)),
            }
            subscription = await client.create_subscription(100, Handler({n.nodeid: k for k, n in nodes.items()}))
            await subscription.subscribe_data_change(list(nodes.values()))
            await asyncio.sleep(0.5)
            model = emulator.emulator.nck
            model.add_program("/_N_MPF_DIR/_N_UMATI_MPF")
            model.programs.write("/_N_MPF_DIR/_N_UMATI_MPF", b"G4 F60\nM30\n")  # runs until the reset
            with NckClient("127.0.0.1", emulator.port) as nck:
                nck.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_UMATI_MPF")  # sampled: no write
                nck.put({"NCKEMU_CHAN_COMMAND[C1]": 1})   # start: active, running
                for step in (50.0, 60.0, 70.0):
                    nck.put({"/Channel/Spindle/speedOvr[u1,1]": step})
            model.set_spindle_speed(1, 1200.0)             # the machine's own change: no write
            await asyncio.sleep(1.0)
            with NckClient("127.0.0.1", emulator.port) as nck:
                nck.put({"NCKEMU_CHAN_COMMAND[C1]": 0})   # reset
            model.set_spindle_speed(1, None)
            await asyncio.sleep(1.0)

    run(go())
    assert seen["state"] == [2, 0, 2]               # Reset, Active, Reset
    assert seen["btss"] == [0, 1, 0]
    # power-on is the initial state (no program has run yet), a reset aborts the running program
    assert [text.Text for text in seen["program"]] == ["Initializing", "Running", "Aborted"]
    assert seen["override"][-3:] == seen["btss override"][-3:] == [50.0, 60.0, 70.0]   # every write, none lost
    assert seen["rotating"] == [False, True, False]
    assert seen["name"][-1] == seen["btss name"][-1] == "_N_UMATI_MPF"
    for value in (50.0, 60.0, 70.0):
        assert stamps["override"][value] == stamps["btss override"][value]
    assert stamps["name"]["_N_UMATI_MPF"] == stamps["btss name"]["_N_UMATI_MPF"]


def test_realms_guard_the_umati_view(tmp_path: Path) -> None:
    """A session with StateRead but not ToolRead reads the channel state and not the tool list."""
    machine = tmp_path / "m.toml"
    text = DEFAULT_MACHINE.read_text("utf-8")
    text = text.replace('[opcua]\nanonymous = ["SinuReadAll"]', '[opcua]\nanonymous = ["StateRead"]')
    machine.write_text(text, encoding="utf-8")
    with two_faces(machine) as (_emulator, face):
        async def go() -> tuple[str, str, str]:
            client = await connect(face)
            try:
                state = await (await _umati(client, "Monitoring", "CHAN1", "ChannelState")).read_data_value(
                    raise_on_bad_status=False)
                tool = await (await _umati(client, "Equipment", "Tools", "END_MILL_D10", "ControlIdentifier1")
                              ).read_data_value(raise_on_bad_status=False)
                subscription = await client.create_subscription(100, None)
                tool_node = await _umati(client, "Equipment", "Tools", "END_MILL_D10", "Name")
                try:
                    await subscription.subscribe_data_change(tool_node)
                    monitored = "Good"
                except ua.UaStatusCodeError as exc:
                    monitored = type(exc).__name__
                return state.StatusCode.name, tool.StatusCode.name, monitored
            finally:
                await client.disconnect()
        assert run(go()) == ("Good", "BadUserAccessDenied", "BadUserAccessDenied")


def test_models_off_in_the_machine_file(tmp_path: Path) -> None:
    machine = tmp_path / "m.toml"
    text = DEFAULT_MACHINE.read_text("utf-8")
    assert 'models = ["MachineTool", "CNC"]' in text
    machine.write_text(text.replace('models = ["MachineTool", "CNC"]', 'models = ["CNC"]'), encoding="utf-8")
    with two_faces(machine) as (_emulator, face):
        async def go() -> tuple[int, list[str]]:
            async with Client(face.url, timeout=30) as client:
                machinery = (await client.get_namespace_array()).index(nodesets.MACHINERY)
                machines = await client.nodes.objects.get_child(f"{machinery}:Machines")
                names = [(await c.read_browse_name()).Name for c in await client.nodes.objects.get_children()]
                return len(await machines.get_children()), names
        count, names = run(go())
    assert count == 0 and "CncInterface" in names
    assert "test" not in names, "the CNC file's example instance under Objects is left out"


def test_the_face_starts_fast_from_the_cache(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """A second face on the same machine starts from the models' shelf in well under the import's time."""
    emulator, _face = faces

    async def start_stop() -> tuple[float, int]:
        started = time.perf_counter()
        face = await OpcUaFace(emulator.emulator, "127.0.0.1", 0).start()
        took = time.perf_counter() - started
        made = face.models.nodes_made
        await face.stop()
        return took, made

    took, made = asyncio.run_coroutine_threadsafe(start_stop(), emulator._loop).result(timeout=120)
    assert made > 300
    assert took < 10.0  # the import alone takes 10-50 s


def test_nck_alarms_are_alerts_of_notification_messages(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """An alarm raised and cleared on the NCK's alarm list: two AlertType events from Messages, active then
    not, with the alarm's number as ErrorCode and its text."""
    emulator, face = faces
    seen: list[dict[str, Any]] = []

    class Handler:
        def event_notification(self, event: Any) -> None:
            seen.append(event.get_event_props_as_fields_dict())

    async def go() -> None:
        async with Client(face.url, timeout=30) as client:
            messages = await _umati(client, "Notification", "Messages")
            mt = (await client.get_namespace_array()).index(nodesets.MACHINE_TOOL)
            alert_type = await client.nodes.base_event_type.get_child(
                ["0:ConditionType", "0:AcknowledgeableConditionType", "0:AlarmConditionType", f"{mt}:AlertType"])
            subscription = await client.create_subscription(100, Handler())
            await subscription.subscribe_events(messages, alert_type)
            await asyncio.sleep(0.3)
            alarms = emulator.emulator.nck.alarm_list
            alarms.raise_alarm("spindle too warm", 700123, ("SP1",))
            await asyncio.sleep(0.5)
            alarms.clear("spindle too warm")
            await asyncio.sleep(0.8)

    run(go())
    mine = [e for e in seen if e["ErrorCode"].Value == "700123"]
    assert [(e["ActiveState/Id"].Value, e["Retain"].Value, e["Message"].Value.Text) for e in mine] == [
        (True, True, "spindle too warm"), (False, False, "spindle too warm")]


def test_a_living_machine_three_paths_and_a_subscription(tmp_path: Path) -> None:
    """`nckemu serve --inputs REC --plc PROG --speed 600x --opcua 0`: the spindle turns and rests as the
    recording says. asyncua subscribes to umati's IsRotating and reads, between two S7 reads of actSpeed that
    agree (no recording step between), the same speed as /Channel/Spindle/actSpeed and as the CNC model's
    CncSpindle ActSpeed."""
    from tests.support.live_tools import MACHINE, PROGRAM, serve, write_recording

    recording = write_recording(tmp_path / "rec.csv", hours=3.0)
    with serve("--machine", str(MACHINE), "--inputs", str(recording), "--plc", str(PROGRAM), "--speed", "600x",
               "--opcua", "0") as served:
        url = str(served.ready["opcua"])
        seen: list[bool] = []
        agreed: list[tuple[float, float, float]] = []

        class Handler:
            def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
                seen.append(value)

        async def go() -> None:
            async with Client(url, timeout=30) as client:
                ns = await client.get_namespace_index("SinumerikVarProvider")
                cnc_ns = (await client.get_namespace_array()).index(nodesets.CNC)
                rotating = await _umati(client, "Monitoring", "SP1", "IsRotating")
                btss = client.get_node(ua.NodeId("/Channel/Spindle/actSpeed[u1,1]", ns))
                cnc = await _cnc_spindle_speed(client, cnc_ns)
                subscription = await client.create_subscription(100, Handler())
                await subscription.subscribe_data_change(rotating)
                deadline = time.monotonic() + 8.0
                with NckClient("127.0.0.1", served.port) as nck:
                    while time.monotonic() < deadline:
                        before = nck.get("/Channel/Spindle/actSpeed[u1,1]")[0]
                        over_btss, over_cnc = await btss.read_value(), await cnc.read_value()
                        after = nck.get("/Channel/Spindle/actSpeed[u1,1]")[0]
                        if before == after:
                            agreed.append((before, over_btss, over_cnc))
                        await asyncio.sleep(0.05)

        run(go())
    speeds = {speed for speed, _, _ in agreed}
    assert {0.0, 6000.0} <= speeds   # both the rest and the turning were read
    # The drive interpolates between the recording's rows (60 s apart): a read inside the one step from
    # rest to 6000 rpm sees a speed on that ramp (3000 at its middle), never anything outside it.
    assert all(0.0 <= speed <= 6000.0 for speed in speeds), speeds
    assert all(s7 == btss == cnc for s7, btss, cnc in agreed), agreed[:10]
    assert True in seen and False in seen                       # IsRotating followed the recording
    assert all(a != b for a, b in zip(seen, seen[1:], strict=False))  # a change each time, none repeated


async def _cnc_spindle_speed(client: Client, cnc_ns: int) -> Any:
    node = await client.nodes.objects.get_child(f"{cnc_ns}:CncInterface")
    for name in ("CncSpindleList", "SP1", "ActSpeed"):
        for description in await node.get_children_descriptions():
            if description.BrowseName.Name == name:
                node = client.get_node(description.NodeId)
                break
        else:
            raise AssertionError(f"no {name} in the CNC interface")
    return node


def test_the_stacklight_follows_its_plc_bits(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """The default machine's stack light: Lamp1 (red) is Q0.0. python-snap7 writes the output byte; the
    lamp's SignalOn and /Plc/Q0.0 change in the same push, each time."""
    import snap7
    from snap7.type import Area

    emulator, face = faces
    seen: dict[str, list[tuple[bool, Any]]] = {}

    class Handler:
        def __init__(self, names: dict[Any, str]) -> None:
            self.names = names

        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            seen.setdefault(self.names[node.nodeid], []).append(
                (value, data.monitored_item.Value.SourceTimestamp))

    async def go() -> tuple[int, Any]:
        async with Client(face.url, timeout=30) as client:
            ns = await client.get_namespace_index("SinumerikVarProvider")
            lamp = await _umati(client, "Monitoring", "Stacklight", "Lamp1")
            color = await (await _umati(client, "Monitoring", "Stacklight", "Lamp1", "SignalColor")).read_value()
            nodes = {"lamp": await _umati(client, "Monitoring", "Stacklight", "Lamp1", "SignalOn"),
                     "btss": client.get_node(ua.NodeId("/Plc/Q0.0", ns))}
            subscription = await client.create_subscription(100, Handler({n.nodeid: k for k, n in nodes.items()}))
            await subscription.subscribe_data_change(list(nodes.values()))
            await asyncio.sleep(0.4)
            plc = snap7.Client()
            plc.connect("127.0.0.1", 0, 2, emulator.port)
            try:
                for byte in (1, 0, 1, 0):
                    plc.write_area(Area.PA, 0, 0, bytearray([byte]))
            finally:
                plc.disconnect()
            await asyncio.sleep(0.8)
            return color, lamp

    color, _lamp = run(go())
    assert color == 1  # Red
    assert [value for value, _ in seen["lamp"]] == [value for value, _ in seen["btss"]] == [
        False, True, False, True, False]
    assert [stamp for _, stamp in seen["lamp"][1:]] == [stamp for _, stamp in seen["btss"][1:]]
