"""The OPC UA face as an MES/dashboard integrator reads it (issue 43): units a client can look up,
identities that tell machines apart, rights shown before a write fails, and values equal across faces.
"""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from typing import Any

import pytest
from asyncua import Client, ua

from nckemu.emulator.faces.opcua import OpcUaFace, nodesets
from nckemu.emulator.runner import EmulatorThread
from tests.support.opcua_tools import connect, two_faces

pytestmark = [pytest.mark.timeout(300)]
needs_models = pytest.mark.skipif(nodesets.find() is None, reason=nodesets.how_to_get())

NS_URI = "SinumerikVarProvider"
UNECE = "http://www.opcfoundation.org/UA/units/un/cefact"
# UNECE Recommendation 20 common codes the instances may use: code -> (symbol, name)
RECOMMENDATION_20 = {
    "MMT": ("mm", "millimetre"), "DD": ("°", "degree [unit of angle]"), "H81": ("mm/min", "millimetre per minute"),
    "P1": ("%", "percent"), "RPM": ("r/min", "revolutions per minute"), "KWT": ("kW", "kilowatt"),
    "NU": ("N·m", "newton metre"),
}


def code_of(unit_id: int) -> str:
    """The letters a UnitId was made of (OPC 10000-8: one byte a letter, the first the highest)."""
    letters = []
    while unit_id:
        letters.append(chr(unit_id & 0xFF))
        unit_id >>= 8
    return "".join(reversed(letters))


def unit_id_of(code: str) -> int:
    return sum(ord(letter) << (8 * position) for position, letter in enumerate(reversed(code)))


def test_unit_ids_are_the_letters_of_their_code() -> None:
    assert unit_id_of("KWT") == 4937556 and unit_id_of("NU") == 20053
    assert unit_id_of("H81") == 4732977 and unit_id_of("RPM") == 5394509 and unit_id_of("P1") == 20529
    assert code_of(unit_id_of("MMT")) == "MMT"


@pytest.fixture(scope="module")
def faces() -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    with two_faces() as pair:
        yield pair


def run(coroutine: Any) -> Any:
    return asyncio.run(coroutine)


async def _variables(client: Client, root: Any) -> list[tuple[str, Any]]:
    """Every variable below ``root`` (browse path, node), depth first."""
    found: list[tuple[str, Any]] = []

    async def walk(node: Any, path: str, depth: int) -> None:
        if depth > 10:
            return
        for description in await node.get_children_descriptions():
            child = client.get_node(description.NodeId)
            where = f"{path}/{description.BrowseName.Name}"
            if description.NodeClass == ua.NodeClass.Variable:
                found.append((where, child))
            if description.NodeClass in (ua.NodeClass.Object, ua.NodeClass.Variable):
                await walk(child, where, depth + 1)

    await walk(root, "", 0)
    return found


async def _instance_roots(client: Client) -> list[tuple[str, Any]]:
    namespaces = await client.get_namespace_array()
    machines = await client.nodes.objects.get_child(f"{namespaces.index(nodesets.MACHINERY)}:Machines")
    cnc = await client.nodes.objects.get_child(f"{namespaces.index(nodesets.CNC)}:CncInterface")
    return [("Machines", machines), ("CncInterface", cnc)]


@needs_models
def test_every_engineering_unit_is_a_unece_common_code_with_its_unit_id(faces: tuple[EmulatorThread, OpcUaFace]
                                                                        ) -> None:
    async def go() -> dict[str, tuple[str, str, str]]:
        client = await connect(faces[1])
        try:
            units: dict[str, tuple[str, str, str]] = {}
            for name, root in await _instance_roots(client):
                for path, node in await _variables(client, root):
                    if path.endswith("/EngineeringUnits"):
                        unit = await node.read_value()
                        assert isinstance(unit, ua.EUInformation), path
                        assert unit.NamespaceUri == UNECE, path
                        code = code_of(unit.UnitId)
                        assert unit.UnitId == unit_id_of(code), path
                        units[name + path] = (code, unit.DisplayName.Text, unit.Description.Text)
            return units
        finally:
            await client.disconnect()

    units = run(go())
    assert len(units) > 20
    for path, (code, symbol, name) in units.items():
        assert code in RECOMMENDATION_20, f"{path}: UnitId of {code!r}, no common code"
        assert (symbol, name) == RECOMMENDATION_20[code], path
    by_name = {path.rsplit("/", 2)[-2]: code for path, (code, _s, _n) in units.items()}
    assert by_name["ActPower"] == "KWT" and by_name["ActTorque"] == "NU" and by_name["ActSpeed"] == "RPM"
    assert by_name["ActFeedrate"] == "H81" and by_name["DryRunFeed"] == "H81" and by_name["ActLoad"] == "P1"


# One writable variable of each realm that has variables, and read-only ones (no one writes them).
WRITABLE = {"State": "/Channel/Parameter/R[u1,3]", "Frame": "/Nckemu/Channel/linShift",
            "Sea": "/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]", "Tea": "/NC/_N_AX_TEA_ACX/$MA_TEMP_COMP_TYPE",
            "Tool": "/Tool/Compensation/cuttEdgeParam", "Drive": "/DriveVsa/Drive/p0604", "Plc": "/Plc/MB10"}
READ_ONLY = ["/Nckemu/Channel/actToolBasePos", "/DriveVsa/Drive/r0021", "/Channel/Configuration/numUserFrames",
             "/NC/_N_NC_TEA_ACX/$MN_AXCONF_MACHAX_NAME_TAB"]
RW = ua.AccessLevel.CurrentRead.mask | ua.AccessLevel.CurrentWrite.mask
READ = ua.AccessLevel.CurrentRead.mask


def _machine_with_users(tmp_path: Any) -> Any:
    from importlib import resources

    text = resources.files("nckemu.emulator.machine").joinpath("machines/default.toml").read_text("utf-8")
    users = ['[opcua.users.reader]\npassword = "r"\nrights = ["SinuReadAll"]\n',
             '[opcua.users.stateonly]\npassword = "s"\nrights = ["StateRead"]\n']
    users += [f'[opcua.users.{realm.lower()}writer]\npassword = "w"\nrights = ["{realm}Write"]\n' for realm in WRITABLE]
    machine = tmp_path / "users.toml"
    machine.write_text(text + "\n" + "\n".join(users), encoding="utf-8")
    return machine


def _expected_level(rights: set[str], realm: str, access: int) -> int:
    read = bool({"SinuReadAll", "SinuWriteAll", f"{realm}Read", f"{realm}Write"} & rights)
    write = bool({"SinuWriteAll", f"{realm}Write"} & rights)
    return access & ((READ if read else 0) | (ua.AccessLevel.CurrentWrite.mask if write else 0))


def test_user_access_level_and_user_executable_follow_the_sessions_rights(tmp_path: Any) -> None:
    sessions: dict[str, tuple[str | None, str | None, set[str]]] = {
        "anonymous": (None, None, {"SinuReadAll"}), "reader": ("reader", "r", {"SinuReadAll"}),
        "stateonly": ("stateonly", "s", {"StateRead"}), "writer": ("nckemu", "SUNRISE", {"SinuReadAll", "SinuWriteAll"}),
    }
    sessions |= {f"{realm.lower()}writer": (f"{realm.lower()}writer", "w", {f"{realm}Write"}) for realm in WRITABLE}
    with two_faces(_machine_with_users(tmp_path)) as (_emulator, face):
        async def session(user: str | None, password: str | None) -> dict[str, Any]:
            client = await connect(face, user, password)
            try:
                ns = await client.get_namespace_index(NS_URI)
                seen: dict[str, Any] = {}
                for path in [*WRITABLE.values(), *READ_ONLY]:
                    node = client.get_node(ua.NodeId(path, ns))
                    access, user_access = await node.read_attributes(
                        [ua.AttributeIds.AccessLevel, ua.AttributeIds.UserAccessLevel])
                    seen[path] = (access.Value.Value, user_access.Value.Value)
                methods = client.get_node(ua.NodeId("/Methods", ns))
                for method in await methods.get_children():
                    name = (await method.read_browse_name()).Name
                    seen[name] = (await method.read_attribute(ua.AttributeIds.UserExecutable)).Value.Value
                return seen
            finally:
                await client.disconnect()

        for who, (user, password, rights) in sessions.items():
            seen = run(session(user, password))
            for realm, path in WRITABLE.items():
                assert seen[path] == (RW, _expected_level(rights, realm, RW)), (who, path)
            for path in READ_ONLY:
                access, user_access = seen[path]
                assert access == READ and user_access in (0, READ), (who, path)
            logged_in = user is not None
            assert seen["GetMyAccessRights"] is logged_in, who
            assert seen["CopyFileFromServer"] is (logged_in and bool({"SinuReadAll", "FSRead"} & rights)), who
            assert seen["AddUser"] is (user == "nckemu"), who
            may_select = logged_in and bool({"SinuWriteAll", "StateWrite"} & rights)
            assert seen["Select"] is seen["Unselect"] is may_select, who
            assert seen["AddCertificateUser"] is False


def test_a_node_no_one_may_write_answers_bad_not_writable_to_everyone(faces: tuple[EmulatorThread, OpcUaFace]
                                                                      ) -> None:
    from tests.support.opcua_tools import write_status

    face = faces[1]
    for user, password in ((None, ""), ("nckemu", "SUNRISE")):
        for path in READ_ONLY[:2]:
            assert run(write_status(face, path, ua.Variant(1.0, ua.VariantType.Double), user, password)) \
                == "BadNotWritable", (user, path)
    # a writable variable and anonymous (read rights only): a rights question
    assert run(write_status(face, WRITABLE["Sea"], ua.Variant(1.0, ua.VariantType.Double), None)) \
        == "BadUserAccessDenied"

    async def standard_and_model_nodes() -> list[str]:
        client = await connect(face, "nckemu", "SUNRISE")
        try:
            statuses = []
            nodes = [client.get_node(ua.NodeId(ua.ObjectIds.Server_ServerStatus_BuildInfo_ProductName))]
            if face.models.on:
                namespaces = await client.get_namespace_array()
                cnc = await client.nodes.objects.get_child(f"{namespaces.index(nodesets.CNC)}:CncInterface")
                nodes.append(await cnc.get_child(f"{namespaces.index(nodesets.CNC)}:VendorName"))
            for node in nodes:
                try:
                    await node.write_value(ua.Variant("x", ua.VariantType.String))
                    statuses.append("Good")
                except ua.UaStatusCodeError as exc:
                    statuses.append(type(exc).__name__)
            return statuses
        finally:
            await client.disconnect()

    assert set(run(standard_and_model_nodes())) == {"BadNotWritable"}


async def _child(client: Client, node: Any, name: str) -> Any:
    """A child by browse name, whichever namespace the model gives it."""
    for description in await node.get_children_descriptions():
        if description.BrowseName.Name == name:
            return client.get_node(description.NodeId)
    raise KeyError(name)


@needs_models
@pytest.mark.slow  # 20 faces start (about 0.3 s each from the models' cache)
async def test_a_fleet_of_twenty_registers_as_twenty_assets(tmp_path: Any) -> None:
    """Each machine of a fleet has its own name, serial number (equal to MD18030 over S7 and to SZL 0x001C
    as python-snap7's get_cpu_info reads it), ProductInstanceUri and ApplicationUri; an asset registry keyed
    by ProductInstanceUri finds 20."""
    from importlib import resources

    import snap7

    import nckemu
    from nckemu.clients import AsyncNckClient
    from nckemu.emulator.fleet import Fleet, FleetMachine, FleetSpec

    text = resources.files("nckemu.emulator.machine").joinpath("machines/default.toml").read_text("utf-8")
    machine = tmp_path / "plain.toml"  # no certificates to make: the test is about identity
    machine.write_text(text.replace("[opcua]\n", '[opcua]\nsecurity = ["None"]\n', 1), encoding="utf-8")
    names = [f"cell{index:02d}" for index in range(1, 21)]
    spec = FleetSpec("test", tuple(FleetMachine(name, "127.0.0.1", 0, machine=str(machine), opcua=0)
                                   for name in names))
    fleet = await Fleet(spec).start()
    assets: dict[str, dict[str, str]] = {}
    try:
        for running in fleet.machines:
            async with AsyncNckClient("127.0.0.1", running.port) as s7:
                md18030, md18040 = await s7.get("MD18030", "MD18040[u1,1]")
            plc = snap7.Client()
            try:
                await asyncio.to_thread(plc.connect, "127.0.0.1", 0, 2, running.port)
                cpu = await asyncio.to_thread(plc.get_cpu_info)
            finally:
                plc.disconnect()
            async with Client(running.ready()["opcua"], timeout=10) as client:
                namespaces = await client.get_namespace_array()
                machines = await client.nodes.objects.get_child(f"{namespaces.index(nodesets.MACHINERY)}:Machines")
                (tool,) = await machines.get_children()
                identification = await _child(client, tool, "Identification")

                async def read(name: str, identification: Any = identification, client: Client = client) -> Any:
                    return await (await _child(client, identification, name)).read_value()

                build = await client.get_node(ua.NodeId(ua.ObjectIds.Server_ServerStatus_BuildInfo)).read_value()
                endpoints = await client.get_endpoints()
                uri = await read("ProductInstanceUri")
                assets[uri] = {
                    "name": (await tool.read_browse_name()).Name, "serial": await read("SerialNumber"),
                    "software": await read("SoftwareRevision"), "md18030": str(md18030).rstrip(),
                    "md18040": str(md18040).rstrip(), "application": endpoints[0].Server.ApplicationUri,
                    "cpu_name": cpu.ASName.decode(), "cpu_serial": cpu.SerialNumber.decode(),
                    "product": f"{build.ProductName} {build.SoftwareVersion} {build.ProductUri}",
                }
    finally:
        await fleet.stop()
    assert len(assets) == 20
    assert sorted(asset["name"] for asset in assets.values()) == names
    assert len({asset["serial"] for asset in assets.values()}) == 20
    assert len({asset["application"] for asset in assets.values()}) == 20
    for uri, asset in assets.items():
        assert asset["serial"] == asset["md18030"] and asset["software"] == asset["md18040"], asset
        assert (asset["cpu_name"], asset["cpu_serial"]) == (asset["name"], asset["serial"]), asset
        assert uri.startswith("urn:nckemu:") and asset["name"] in uri and asset["serial"] in uri and "-:" not in uri
        assert asset["application"] == f"urn:nckemu:{asset['name']}"
        assert asset["product"] == f"nckemu {nckemu.__version__} urn:nckemu"


@needs_models
def test_cnc_drive_values_equal_the_drive_parameters_over_s7_and_btss(faces: tuple[EmulatorThread, OpcUaFace]
                                                                      ) -> None:
    """At 8000 rpm the spindle's CNC ActPower, ActTorque and ActLoad are its drive's r0032, r0080 and r0081,
    as S7 and the BTSS node read them at the same moment; a feed axis's too."""
    from nckemu.clients import NckClient

    emulator, face = faces
    nck = emulator.emulator.nck
    spindle_drive = nck.drives.drive_of_axis(3).number  # SP1 is machine axis 3 on the default machine
    x_drive = nck.drives.drive_of_axis(1).number
    parameters = ("r0032", "r0080", "r0081")

    async def read_ua() -> dict[str, float]:
        client = await connect(face)
        try:
            namespaces = await client.get_namespace_array()
            ns, cnc = namespaces.index(NS_URI), namespaces.index(nodesets.CNC)
            interface = await client.nodes.objects.get_child(f"{cnc}:CncInterface")
            values: dict[str, float] = {}
            for listing, item, drive in (("CncSpindleList", "SP1", spindle_drive), ("CncAxisList", "X1", x_drive)):
                entry = await _child(client, await _child(client, interface, listing), item)
                for path in ("ActPower", "ActTorque", "ActLoad"):
                    values[f"{item}/{path}"] = await (await _child(client, entry, path)).read_value()
                for parameter in parameters:
                    node = client.get_node(ua.NodeId(f"/DriveVsa/Drive/{parameter}[u{drive}]", ns))
                    values[f"{item}/{parameter}"] = await node.read_value()
            return values
        finally:
            await client.disconnect()

    emulator.call(lambda: nck.set_spindle_speed(1, 8000.0))
    try:
        with NckClient("127.0.0.1", emulator.port) as s7:
            over_s7 = dict(zip([f"SP1/{p}" for p in parameters] + [f"X1/{p}" for p in parameters],
                               s7.get(*[f"/DriveVsa/Drive/{p}[u{spindle_drive}]" for p in parameters],
                                      *[f"/DriveVsa/Drive/{p}[u{x_drive}]" for p in parameters]), strict=True))
        over_ua = run(read_ua())
    finally:
        emulator.call(lambda: nck.set_spindle_speed(1, None))
    assert over_s7["SP1/r0032"] > 1.0 and over_s7["SP1/r0080"] > 0.1 and over_s7["SP1/r0081"] > 10.0
    for item in ("SP1", "X1"):
        for path, parameter in (("ActPower", "r0032"), ("ActTorque", "r0080"), ("ActLoad", "r0081")):
            expected = over_s7[f"{item}/{parameter}"]
            assert over_ua[f"{item}/{parameter}"] == pytest.approx(expected, rel=1e-6), (item, parameter)
            assert over_ua[f"{item}/{path}"] == pytest.approx(expected, rel=1e-6), (item, path)


def test_the_siemens_machine_axis_path_reads_the_extension_row(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """``/Channel/MachineAxis/actToolBasePos[u1,n]`` (the controller's MachineAxis area) is the row nckemu
    first served as ``/Nckemu/Channel/actToolBasePos``: the same value over S7 and OPC UA, every axis."""
    from nckemu.clients import NckClient

    emulator, face = faces
    axes = emulator.emulator.nck.axes
    emulator.call(lambda: axes.set_position(4, -12.5))  # Z1 moves
    with NckClient("127.0.0.1", emulator.port) as s7:
        try:
            lines = range(1, 5)
            siemens = s7.get(*[f"/Channel/MachineAxis/actToolBasePos[u1,{n}]" for n in lines])
            extension = s7.get(*[f"/Nckemu/Channel/actToolBasePos[u1,{n}]" for n in lines])

            async def read_ua() -> tuple[list[Any], list[Any]]:
                client = await connect(face)
                try:
                    ns = await client.get_namespace_index(NS_URI)
                    both = []
                    for root in ("/Channel/MachineAxis", "/Nckemu/Channel"):
                        both.append([await client.get_node(ua.NodeId(f"{root}/actToolBasePos[u1,{n}]", ns))
                                     .read_value() for n in lines])
                    return both[0], both[1]
                finally:
                    await client.disconnect()

            ua_siemens, ua_extension = run(read_ua())
        finally:
            emulator.call(lambda: axes.set_position(4, 0.0))
    assert siemens == extension == ua_siemens == ua_extension
    assert siemens[3] == pytest.approx(-12.5)


def test_the_geometric_axis_paths_count_the_channels_wcs_axes(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """``/Channel/GeometricAxis/...[u1,n]`` counts X, Y, Z of channel 1 (machine axes 1, 2 and 4 on the
    default machine, whose axis 3 is the spindle). With no work offset and no tool offset active, the tool
    base and the programmed point equal the machine-axis rows; with G54 and a tool edge active, the tool
    base is the SEGA workPosition row and the programmed point lies the tool length below it along Z.
    The same over S7 and OPC UA."""
    from nckemu.clients import NckClient

    emulator, face = faces
    nck = emulator.emulator.nck
    state = nck.channels[1].state
    before = (nck.frames.active[1], state.t_number, state.d_number)
    paths = ("actToolBasePos", "cmdToolBasePos", "actProgPos", "cmdProgPos")

    def read_all(s7: NckClient) -> dict[str, list[Any]]:
        values = {path: s7.get(*[f"/Channel/GeometricAxis/{path}[u1,{n}]" for n in (1, 2, 3)]) for path in paths}
        values["name"] = s7.get(*[f"/Channel/GeometricAxis/name[u1,{n}]" for n in (1, 2, 3, 4)])
        values["machine"] = s7.get(*[f"/Channel/MachineAxis/actToolBasePos[u1,{n}]" for n in (1, 2, 4)])
        values["work"] = s7.get(*[f"workPosition[u1,{n}]" for n in (1, 2, 4)])
        values["length"] = s7.get("/Channel/State/actOriToolLength3[u1]")
        return values

    async def read_ua() -> dict[str, list[Any]]:
        client = await connect(face)
        try:
            ns = await client.get_namespace_index(NS_URI)
            return {path: [await client.get_node(ua.NodeId(f"/Channel/GeometricAxis/{path}[u1,{n}]", ns)).read_value()
                           for n in (1, 2, 3)] for path in (*paths, "name")}
        finally:
            await client.disconnect()

    emulator.call(lambda: nck.axes.set_position(4, -12.5))
    try:
        with NckClient("127.0.0.1", emulator.port) as s7:
            emulator.call(lambda: (nck.select_frame(0), nck.select_tool(0, 0)))  # G500, T0 D0
            plain, plain_ua = read_all(s7), run(read_ua())
            emulator.call(lambda: (nck.select_frame(1), nck.select_tool(1, 1)))  # G54, T1 D1
            offset, offset_ua = read_all(s7), run(read_ua())
    finally:
        emulator.call(lambda: (nck.axes.set_position(4, 0.0), nck.select_frame(before[0]),
                               nck.select_tool(before[1], before[2])))
    assert plain["name"] == ["X", "Y", "Z", ""] and plain_ua["name"] == ["X", "Y", "Z"]
    for path in paths:
        assert plain[path] == plain["machine"] == plain_ua[path], path
        assert offset[path] == offset_ua[path], path
    assert plain["machine"][2] == pytest.approx(-12.5)
    assert offset["actToolBasePos"] == offset["cmdToolBasePos"] == offset["work"] != offset["machine"]
    assert offset["length"][0] > 0  # the default machine's T1 D1 has a length along Z
    assert offset["actProgPos"][:2] == offset["work"][:2]
    assert offset["actProgPos"][2] == pytest.approx(offset["work"][2] - offset["length"][0])


@needs_models
def test_identification_equals_the_s7_face_and_build_info_names_nckemu(faces: tuple[EmulatorThread, OpcUaFace]
                                                                       ) -> None:
    import nckemu
    from nckemu.clients import NckClient

    emulator, face = faces
    with NckClient("127.0.0.1", emulator.port) as s7:
        md18030, md18040 = s7.get("MD18030", "MD18040[u1,1]")

    async def read() -> tuple[dict[str, Any], Any, str]:
        client = await connect(face)
        try:
            namespaces = await client.get_namespace_array()
            machines = await client.nodes.objects.get_child(f"{namespaces.index(nodesets.MACHINERY)}:Machines")
            (tool,) = await machines.get_children()
            identification = await _child(client, tool, "Identification")
            values = {name: await (await _child(client, identification, name)).read_value()
                      for name in ("SerialNumber", "SoftwareRevision", "ProductInstanceUri", "Manufacturer")}
            build = await client.get_node(ua.NodeId(ua.ObjectIds.Server_ServerStatus_BuildInfo)).read_value()
            return values, build, (await tool.read_browse_name()).Name
        finally:
            await client.disconnect()

    values, build, name = run(read())
    assert values["SerialNumber"] == str(md18030).rstrip() == emulator.emulator.serial_number
    assert values["SoftwareRevision"] == str(md18040).rstrip() == "06.00.00.00.000"
    assert values["ProductInstanceUri"] == f"urn:nckemu:{name.replace(' ', '-')}:{values['SerialNumber']}"
    assert (build.ProductName, build.ManufacturerName, build.SoftwareVersion, build.ProductUri) \
        == ("nckemu", "nckemu", nckemu.__version__, "urn:nckemu")
