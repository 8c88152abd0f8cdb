"""Part programs over OPC UA as a client drives them: CopyFileToServer, Select, a start by writing
``/Plc/DB21.DBX7.1``, and the umati (OPC 40501-1) and CNC (OPC 40502) program nodes through a program's
life; the refusals of Select and Unselect (no channel, no program, not in reset, running, a user without
the right, anonymous).
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua
from asyncua.ua.uaerrors import UaStatusCodeError

from nckemu.emulator.faces.opcua import OpcUaFace, nodesets
from nckemu.emulator.runner import EmulatorThread
from tests.support.opcua_tools import NS_URI, connect, two_faces

DEFAULT_MACHINE = resources.files("nckemu.emulator.machine").joinpath("machines/default.toml")
ADMIN, PASSWORD = "nckemu", "SUNRISE"

pytestmark = [pytest.mark.timeout(300),
              pytest.mark.skipif(nodesets.find() is None, reason=nodesets.how_to_get())]



@pytest.fixture(scope="module")
def faces(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    """The default machine with a second user who may read everything and write files, not state."""
    machine = tmp_path_factory.mktemp("machine") / "m.toml"
    machine.write_text(DEFAULT_MACHINE.read_text("utf-8") + '\n[opcua.users.reader]\npassword = "READER"\n'
                       'rights = ["SinuReadAll", "FSWrite"]\n', encoding="utf-8")
    with two_faces(machine) as pair:
        assert pair[1].models.on
        yield pair


async def _call(client: Client, method: str, *arguments: Any) -> Any:
    ns = await client.get_namespace_index(NS_URI)
    methods = await client.nodes.objects.get_child([f"{ns}:Sinumerik", f"{ns}:Methods"])
    try:
        return await methods.call_method(f"{ns}:{method}", *arguments)
    except UaStatusCodeError as exc:
        return type(exc).__name__


async def _instance(client: Client, path: str) -> Any:
    ns = await client.get_namespace_index("urn:nckemu:instances")
    return await client.get_node(ua.NodeId(path, ns)).read_value()


async def _sinumerik(client: Client, node_id: str) -> Any:
    ns = await client.get_namespace_index(NS_URI)
    return await client.get_node(ua.NodeId(node_id, ns)).read_value()


def _text(value: Any) -> str:
    return value.Text if isinstance(value, ua.LocalizedText) else str(value)


ACTIVE = "MachineTool/Production/ActiveProgram"
JOB = "MachineTool/Production/ProductionPlan/Job1"
CNC = "CncInterface/CncChannelList/Channel1"


async def _view(client: Client) -> dict[str, Any]:
    """The program nodes a dashboard reads, at one moment."""
    return {
        "program": _text(await _instance(client, f"{ACTIVE}/State/CurrentState")),
        "transition": _text(await _instance(client, f"{ACTIVE}/State/LastTransition")),
        "job": _text(await _instance(client, f"{JOB}/State/CurrentState")),
        "name": await _instance(client, f"{ACTIVE}/Name"),
        "runs": await _instance(client, f"{JOB}/RunsCompleted"),
        "cnc name": await _instance(client, f"{CNC}/ActProgramName"),
        "cnc status": await _instance(client, f"{CNC}/ActProgramStatus"),
        "progName": await _sinumerik(client, "/Channel/ProgramInfo/progName[u1]"),
        "progStatus": await _sinumerik(client, "/Channel/State/progStatus[u1]"),
    }


def test_select_and_unselect_answer_as_the_control(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    emulator, face = faces
    channel = emulator.emulator.nck.channels[1]

    async def go() -> dict[str, Any]:
        seen: dict[str, Any] = {}
        admin = await connect(face, ADMIN, PASSWORD)
        reader = await connect(face, "reader", "READER")
        anonymous = await connect(face)
        try:
            program = ua.Variant(b"G4 F30\nM30\n", ua.VariantType.ByteString)
            seen["copy"] = await _call(admin, "CopyFileToServer", ua.Variant("SEL.MPF"), program, ua.Variant(True))
            one = ua.Variant(1, ua.VariantType.UInt32)
            seen["no channel"] = await _call(admin, "Select", ua.Variant("SEL.MPF"), ua.Variant(9, ua.VariantType.UInt32))
            seen["no program"] = await _call(admin, "Select", ua.Variant("NOPE.MPF"), one)
            seen["not a name"] = await _call(admin, "Select", ua.Variant("../../etc/passwd"), one)
            seen["anonymous"] = await _call(anonymous, "Select", ua.Variant("SEL.MPF"), one)
            seen["no right"] = await _call(reader, "Select", ua.Variant("SEL.MPF"), one)
            seen["unselect no right"] = await _call(reader, "Unselect", one)
            seen["selected"] = await _call(admin, "Select", ua.Variant("/_N_MPF_DIR/_N_SEL_MPF"), one)
            seen["view"] = await _view(admin)
            ns = await admin.get_namespace_index(NS_URI)
            seen["by node id"] = await _call(admin, "Select", ua.Variant(ua.NodeId("/_N_MPF_DIR/_N_SEL_MPF", ns)), one)
            emulator.call(channel.start)
            seen["select running"] = await _call(admin, "Select", ua.Variant("SEL.MPF"), one)
            seen["unselect running"] = await _call(admin, "Unselect", one)
            emulator.call(channel.stop)
            seen["select interrupted"] = await _call(admin, "Select", ua.Variant("SEL.MPF"), one)
            seen["unselect interrupted"] = await _call(admin, "Unselect", one)
            emulator.call(channel.reset)
            seen["unselect"] = await _call(admin, "Unselect", one)
            seen["unselect again"] = await _call(admin, "Unselect", one)
            seen["unselect no channel"] = await _call(admin, "Unselect", ua.Variant(0, ua.VariantType.UInt32))
            seen["after"] = await _view(admin)
        finally:
            for client in (admin, reader, anonymous):
                await client.disconnect()
        return seen

    seen = asyncio.run(go())
    assert seen["copy"] is None   # no outputs
    assert (seen["no channel"], seen["no program"], seen["not a name"]) == (1, 2, 4)
    assert seen["anonymous"] == "BadRequestNotAllowed"
    assert seen["no right"] == seen["unselect no right"] == "BadUserAccessDenied"
    assert seen["selected"] == seen["by node id"] == 0
    view = seen["view"]
    assert view["name"] == view["cnc name"] == view["progName"] != ""
    assert (view["program"], view["job"], view["transition"]) == ("Initializing", "Initializing", "")
    assert (seen["select running"], seen["unselect running"]) == (3, 5)
    assert (seen["select interrupted"], seen["unselect interrupted"]) == (3, 3)
    assert (seen["unselect"], seen["unselect again"], seen["unselect no channel"]) == (0, 2, 1)
    assert seen["after"]["name"] == seen["after"]["progName"] == ""
    assert seen["after"]["program"] == "Initializing"   # Aborted by the reset, then nothing selected


def test_copy_goes_through_the_program_store(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """Subprograms by the names users write; the program a channel runs is not replaced."""
    emulator, face = faces
    programs = emulator.emulator.nck.programs

    async def go() -> list[Any]:
        client = await connect(face, ADMIN, PASSWORD)
        try:
            seen = [await _call(client, "CopyFileToServer", ua.Variant("CYCLE.SPF"),
                                ua.Variant(b"G4 F1\nM17\n", ua.VariantType.ByteString), ua.Variant(True))]
            seen.append(await _call(client, "CopyFileFromServer", ua.Variant("/_N_SPF_DIR/_N_CYCLE_SPF")))
            programs.running = "/_N_SPF_DIR/_N_CYCLE_SPF"
            try:
                seen.append(await _call(client, "CopyFileToServer", ua.Variant("CYCLE.SPF"),
                                        ua.Variant(b"M17\n", ua.VariantType.ByteString), ua.Variant(True)))
            finally:
                programs.running = ""
            seen.append(await _call(client, "CopyFileFromServer", ua.Variant("CYCLE.SPF")))
            return seen
        finally:
            await client.disconnect()

    assert asyncio.run(go()) == [None, b"G4 F1\nM17\n", "BadInvalidState", b"G4 F1\nM17\n"]


async def _until(client: Client, wanted: str, timeout_s: float = 30.0) -> dict[str, Any]:
    """The view once the ActiveProgram is in state ``wanted``."""
    deadline = time.monotonic() + timeout_s
    while True:
        view = await _view(client)
        if view["program"] == wanted or time.monotonic() > deadline:
            return view
        await asyncio.sleep(0.05)


async def _pulse(client: Client, bit: str) -> None:
    """A rising edge on a PLC interface bit, as an operator's button gives it."""
    ns = await client.get_namespace_index(NS_URI)
    node = client.get_node(ua.NodeId(f"/Plc/{bit}", ns))
    await node.write_value(ua.Variant(True, ua.VariantType.Boolean))
    await asyncio.sleep(0.2)
    await node.write_value(ua.Variant(False, ua.VariantType.Boolean))


async def _subscribe_transitions(client: Client, handler: Any) -> None:
    """Events of both transition event types (the specification's, found by browsing) from the Server."""
    machine_tool = (await client.get_namespace_array()).index(nodesets.MACHINE_TOOL)
    subscription = await client.create_subscription(100, handler)
    for type_name in ("ProductionProgramTransitionEventType", "ProductionJobTransitionEventType"):
        event_type = await client.nodes.base_event_type.get_child(
            ["0:TransitionEventType", f"{machine_tool}:{type_name}"])
        await subscription.subscribe_events(client.nodes.server, event_type)


async def _ids(client: Client, machine: str) -> dict[str, Any]:
    """The state and transition nodes CurrentState/Id and LastTransition/Id name: their browse names, and
    whether the Number beside each is that node's StateNumber / TransitionNumber."""
    found = {}
    for key, variable, number_name in (("state", "CurrentState", "StateNumber"),
                                       ("transition", "LastTransition", "TransitionNumber")):
        node = client.get_node(await _instance(client, f"{machine}/{variable}/Id"))
        number = await _instance(client, f"{machine}/{variable}/Number")
        numbers = [await child.read_value() for child in await node.get_properties()
                   if (await child.read_browse_name()).Name == number_name]
        found[key] = ((await node.read_browse_name()).Name, numbers == [number])
    return found


# CncChannelProgramStatus as the SINUMERIK progStatus says it (1 interrupted, 2 stopped, 3 running, 4 waiting)
CNC_OF_PROG_STATUS = {1: 3, 2: 0, 3: 1, 4: 2}


def test_a_program_s_life_over_opc_ua() -> None:
    """Power-on, select, NC start, M0, NC start again, M30, and a start aborted by reset, read as a
    dashboard reads them, with the transition events a subscriber to the Server object gets."""
    with two_faces() as (_emulator, face):
        _life(face)


def _life(face: OpcUaFace) -> None:
    events: list[Any] = []

    class Handler:
        def event_notification(self, event: Any) -> None:
            events.append(event)

    async def go() -> dict[str, Any]:
        seen: dict[str, Any] = {}
        client = await connect(face, ADMIN, PASSWORD)
        try:
            one = ua.Variant(1, ua.VariantType.UInt32)
            seen["power-on"] = await _view(client)
            await _subscribe_transitions(client, Handler())
            text = b"N10 G4 F0.3\nN20 PAUSE\nN30 G4 F0.3\nN40 M30\n"
            await _call(client, "CopyFileToServer", ua.Variant("LIFE.MPF"),
                        ua.Variant(text, ua.VariantType.ByteString), ua.Variant(True))
            await _call(client, "CopyFileToServer", ua.Variant("PAUSE.SPF"),        # M0 in a subprogram
                        ua.Variant(b"N10 G4 F0.1\nN20 M0\nN30 M17\n", ua.VariantType.ByteString), ua.Variant(True))
            seen["select"] = await _call(client, "Select", ua.Variant("LIFE.MPF"), one)
            seen["selected"] = await _view(client)
            await _pulse(client, "DB21.DBX7.1")
            seen["m0"] = await _until(client, "Interrupted")
            seen["m0 programs"] = (await _instance(client, f"{CNC}/ActProgramName"),
                                   await _instance(client, f"{CNC}/ActMainProgramName"),
                                   await _instance(client, f"{CNC}/ActProgramFile"))
            seen["m0 pointer"] = (await _instance(client, f"{CNC}/ActProgramBlock"),
                                  await _instance(client, f"{CNC}/ActProgramLine"),
                                  await _sinumerik(client, "/Channel/ProgramInfo/actBlock[u1]"),
                                  await _sinumerik(client, "/Channel/ProgramInfo/actLineNumber[u1]"))
            await _pulse(client, "DB21.DBX7.1")
            seen["ended"] = await _until(client, "Ended")
            long_text = b"N10 G4 F60\nN20 M30\n"
            await _call(client, "CopyFileToServer", ua.Variant("LONG.MPF"),
                        ua.Variant(long_text, ua.VariantType.ByteString), ua.Variant(True))
            seen["select long"] = await _call(client, "Select", ua.Variant("LONG.MPF"), one)
            seen["reselected"] = await _view(client)
            await _pulse(client, "DB21.DBX7.1")
            seen["running"] = await _until(client, "Running")
            await _pulse(client, "DB21.DBX7.7")
            seen["aborted"] = await _until(client, "Aborted")
            await asyncio.sleep(0.5)  # the last events
        finally:
            await client.disconnect()
        return seen

    seen = asyncio.run(go())
    power_on = seen["power-on"]
    assert (power_on["program"], power_on["job"], power_on["transition"]) == ("Initializing", "Initializing", "")
    assert power_on["cnc status"] == 0   # Stopped: nothing has run, nothing was canceled
    assert seen["select"] == seen["select long"] == 0
    assert seen["selected"]["program"] == "Initializing" and "LIFE" in seen["selected"]["name"]
    m0 = seen["m0"]
    assert (m0["program"], m0["job"], m0["transition"]) == ("Interrupted", "Interrupted", "RunningToInterrupted")
    assert m0["cnc status"] == CNC_OF_PROG_STATUS[m0["progStatus"]]
    block, line, act_block, act_line = seen["m0 pointer"]
    assert block == [act_block] and line == str(act_line) and "M0" in act_block   # the same block on both faces
    # (CNC ActProgramBlock is an array, OPC 40502: the current block, no blocks prepared ahead)
    assert seen["m0 programs"] == ("_N_PAUSE_SPF", "_N_LIFE_MPF", "/_N_SPF_DIR/_N_PAUSE_SPF")
    ended = seen["ended"]
    assert (ended["program"], ended["job"], ended["transition"]) == ("Ended", "Ended", "RunningToEnded")
    assert ended["cnc status"] == 0 and ended["runs"] == power_on["runs"] + 1   # M30 counted a part
    assert ended["name"] == ended["cnc name"] == ended["progName"]
    assert seen["reselected"]["program"] == "Initializing" and "LONG" in seen["reselected"]["name"]
    running = seen["running"]
    assert (running["program"], running["cnc status"], running["progStatus"]) == ("Running", 1, 3)
    aborted = seen["aborted"]
    assert (aborted["program"], aborted["job"], aborted["transition"]) == ("Aborted", "Aborted", "RunningToAborted")
    assert aborted["cnc status"] == 4 and aborted["runs"] == ended["runs"]   # Canceled; no part
    program_steps = [_text(event.Transition) for event in events if hasattr(event, "JobIdentifier")]
    assert program_steps == ["InitializingToRunning", "RunningToInterrupted", "InterruptedToRunning",
                             "RunningToEnded", "EndedToInitializing", "InitializingToRunning", "RunningToAborted"]
    job_steps = [_text(event.Transition) for event in events if hasattr(event, "RunsCompleted")]
    assert job_steps[-1] == "RunningToAborted" and "RunningToEnded" in job_steps


def test_a_recording_s_run_is_followed(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """A machine driven by a recording runs its channel without a program and tells no steps: the umati
    state follows what the channel shows (running, interrupted, reset; running again, its end with a
    part counted), with its transition events."""
    emulator, face = faces
    channel = emulator.emulator.nck.channels[1]
    run = channel.run_without_program  # what the recording drive calls
    events: list[Any] = []

    class Handler:
        def event_notification(self, event: Any) -> None:
            events.append(event)

    async def go() -> list[str]:
        client = await connect(face)
        try:
            await _subscribe_transitions(client, Handler())
            states = [(await _view(client))["program"]]
            for action, wanted in ((run, "Running"), (channel.stop, "Interrupted"), (channel.reset, "Aborted"),
                                   (run, "Running"), (channel.end_program, "Ended")):
                emulator.call(action)
                states.append((await _until(client, wanted, 5.0))["program"])
            await asyncio.sleep(0.5)
            ids.update(await _ids(client, f"{ACTIVE}/State"))
            return states
        finally:
            await client.disconnect()

    ids: dict[str, Any] = {}
    states = asyncio.run(go())
    assert states[1:] == ["Running", "Interrupted", "Aborted", "Running", "Ended"]
    assert ids == {"state": ("Ended", True), "transition": ("RunningToEnded", True)}
    program = [(_text(event.Transition), _text(event.FromState), _text(event.ToState), event.Name)
               for event in events if hasattr(event, "JobIdentifier")]
    steps = ["InitializingToRunning", "RunningToInterrupted", "InterruptedToAborted", "AbortedToInitializing",
             "InitializingToRunning", "RunningToEnded"]
    assert program == [(step, *step.split("To"), "") for step in steps]
    job = [(_text(event.Transition), event.Identifier) for event in events if hasattr(event, "RunsCompleted")]
    assert job == [(step, "Job1") for step in steps]


def test_the_docs_example_runs() -> None:
    """docs/opcua.md "Programs over OPC UA": its asyncua example copies, selects and starts a program,
    which then runs to its end."""
    docs = Path(__file__).resolve().parents[4] / "docs" / "opcua.md"
    section = docs.read_text(encoding="utf-8").split("## Programs over OPC UA", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    names: dict[str, Any] = {}
    exec(compile(code, f"{docs}:Programs over OPC UA", "exec"), names)  # noqa: S102 - our own docs
    with two_faces() as (emulator, face):
        asyncio.run(names["run_part"](face.url))

        async def ended() -> str:
            client = await connect(face)
            try:
                return (await _until(client, "Ended", 10.0))["program"]
            finally:
                await client.disconnect()
        assert asyncio.run(ended()) == "Ended"
        assert emulator.emulator.nck.channels[1].state.actual_parts == 1


def test_a_recording_s_run_is_named_by_the_recording_on_every_face(tmp_path: Path) -> None:
    """A living machine whose recording turns the spindle runs no stored program, yet every face names the
    run: the recording's file name as a main program (``day-1 shift.csv`` -> ``_N_DAY_1_SHIFT_MPF``), in
    BTSS progName / workPandProgName over S7 and OPC UA, umati ActiveProgram Name and CNC ActProgramName,
    while it runs and after its end (as a selected program stays selected)."""
    from nckemu.clients import NckClient
    from nckemu.plcsim.drive import PROGRAM_END_IDLE_S, RecordingDrive, recording_program_path
    from nckemu.thermal.recordings.recording import load_recording
    from tests.support.live_tools import MACHINE, write_recording

    assert recording_program_path("day-1 shift") == "/_N_MPF_DIR/_N_DAY_1_SHIFT_MPF"
    assert recording_program_path("2017-06-17") == "/_N_MPF_DIR/_N_REC_2017_06_17_MPF"
    assert recording_program_path("Wärmegang über Nacht, Maschine 7") == "/_N_MPF_DIR/_N_W_RMEGANG__BER_NACHT__MA_MPF"  # 24 characters
    recording = load_recording(write_recording(tmp_path / "day-1 shift.csv", hours=2.0, step_s=10.0))
    path, name = "/_N_MPF_DIR/_N_DAY_1_SHIFT_MPF", "_N_DAY_1_SHIFT_MPF"

    def seen_by_faces(emulator: EmulatorThread, face: OpcUaFace) -> dict[str, Any]:
        with NckClient("127.0.0.1", emulator.port) as s7:
            status, prog_name, file = s7.get("/Channel/State/progStatus[u1]", "/Channel/ProgramInfo/progName[u1]",
                                             "/Channel/ProgramInfo/workPandProgName[u1]")

        async def read() -> dict[str, Any]:
            client = await connect(face)
            try:
                return await _view(client) | {"cnc file": await _instance(client, f"{CNC}/ActProgramFile")}
            finally:
                await client.disconnect()
        return asyncio.run(read()) | {"s7": (status, str(prog_name).rstrip("\0"), str(file).rstrip("\0"))}

    with two_faces(MACHINE) as (emulator, face):
        drive = RecordingDrive(emulator.emulator.machine, recording, 1.0, warmup_s=0.0)
        nck = emulator.emulator.nck

        def apply(cycles: range) -> None:
            for k in cycles:
                drive.apply(nck, k)

        before = seen_by_faces(emulator, face)
        emulator.call(lambda: apply(range(0, 1500)))   # the spindle turns from 1200 s
        running = seen_by_faces(emulator, face)
        emulator.call(lambda: apply(range(1500, 2400 + int(PROGRAM_END_IDLE_S) + 60)))  # stood long: M30
        ended = seen_by_faces(emulator, face)
    assert before["s7"][1:] == ("", "") and before["name"] == before["cnc name"] == ""
    assert running["s7"] == (3, name, path)
    assert (running["name"], running["cnc name"], running["progName"], running["cnc file"]) == (name, name, name, path)
    assert (running["program"], running["progStatus"]) == ("Running", 3)
    assert ended["s7"][1:] == (name, path) and ended["program"] == "Ended"
    assert (ended["name"], ended["cnc name"], ended["progName"], ended["cnc file"]) == (name, name, name, path)
