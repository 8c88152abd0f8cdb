"""The OPC UA face with an outside client: node-opcua-client (npm, installed by ``make test``)."""

from __future__ import annotations

import json
import shutil
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import snap7

from nckemu.clients import NckClient
from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.runner import EmulatorThread
from tests.support.opcua_tools import two_faces

HERE = Path(__file__).parent / "node_opcua"
NODE = shutil.which("node")
pytestmark = [
    pytest.mark.timeout(180),
    pytest.mark.skipif(NODE is None, reason="node is not installed (node-opcua tests need Node.js and npm)"),
    pytest.mark.skipif(not (HERE / "node_modules" / "node-opcua-client").is_dir(),
                       reason="node-opcua-client is not installed: run `make npm` (make test does)"),
]
SD43900_AX4 = "ns=2;s=/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]"


@pytest.fixture(scope="module")
def faces() -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    with two_faces() as pair:
        yield pair


def node_client(face: OpcUaFace, ops: list[dict[str, Any]], user: str | None = None,
                password: str | None = None) -> Any:
    job = {"url": face.url, "user": user, "password": password, "ops": ops}
    done = subprocess.run([str(NODE), str(HERE / "client.js"), json.dumps(job)], capture_output=True, text=True,
                          timeout=120, cwd=HERE)
    return _result(done.stdout.splitlines())


def _result(lines: list[str]) -> Any:
    """The client's "RESULT <json>" line (node-opcua writes its own warnings to stdout)."""
    for line in reversed(lines):
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])
    raise AssertionError(f"no result from node client.js: {lines[-5:]}")


def test_reads(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    _, face = faces
    results = node_client(face, [{"read": "ns=2;s=/Channel/State/progStatus"},
                                 {"read": "ns=2;s=/Channel/Parameter/R[u1, 1, #4]"},
                                 {"read": "ns=2;s=/Bag/State/opMode"}])
    assert [r["status"] for r in results] == ["Good"] * 3
    assert results[1]["value"] == [0.0] * 4


def test_write_then_s7_and_back(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    emulator, face = faces
    results = node_client(face, [{"write": SD43900_AX4, "value": 0.375, "type": "Double"}], "nckemu", "SUNRISE")
    assert results == [{"status": "Good"}]
    with NckClient("127.0.0.1", emulator.port) as nck:
        assert nck.get("SD43900[AX4]") == [pytest.approx(0.375)]
        nck.put({"SD43900[AX4]": 0.125})
    assert node_client(face, [{"read": SD43900_AX4}])[0]["value"] == pytest.approx(0.125)


def test_errors_and_user_rules(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    _, face = faces
    results = node_client(face, [{"read": "ns=2;s=Channel/State/progStatus"},
                                 {"read": "ns=2;s=/Nck/Spindle/driveLoad[u1, 3]"},
                                 {"write": SD43900_AX4, "value": 0.5, "type": "Double"}])
    assert [r["status"] for r in results] == ["BadNodeIdUnknown", "BadAttributeIdInvalid", "BadUserAccessDenied"]
    results = node_client(face, [{"write": SD43900_AX4, "value": 5000.0, "type": "Double"}], "nckemu", "SUNRISE")
    assert results[0]["status"] == "BadOutOfRange"
    refused = node_client(face, [{"read": "ns=2;s=/Channel/State/progStatus"}], "nckemu", "wrong")
    assert "error" in refused


def _subscribed_client(job: dict[str, Any]) -> subprocess.Popen[str]:
    """client.js started on ``job``, once it says its subscription is live (so the test acts only then)."""
    process = subprocess.Popen([str(NODE), str(HERE / "client.js"), json.dumps(job)], stdout=subprocess.PIPE,
                               text=True, cwd=HERE)
    assert process.stdout is not None
    first = process.stdout.readline()
    while first and not first.startswith("RESULT "):
        first = process.stdout.readline()
    assert _result([first]) == {"subscribed": True}, first
    return process


def test_subscription_sees_an_s7_write(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    emulator, face = faces
    job = {"url": face.url, "user": None, "password": None,
           "ops": [{"subscribe": "ns=2;s=/Plc/DB130.DBW40", "ms": 1500}]}
    process = _subscribed_client(job)

    def write_over_s7() -> None:
        plc = snap7.Client()
        plc.connect("127.0.0.1", 0, 2, emulator.port)
        plc.db_write(130, 40, bytearray(b"\x00\x2a"))
        plc.disconnect()

    timer = threading.Timer(0.3, write_over_s7)
    timer.start()
    out, _ = process.communicate(timeout=60)
    timer.join()
    values = _result(out.splitlines())[0]["values"]
    assert 42 in values, values


def test_alarm_events_reach_node_opcua(tmp_path: Path) -> None:
    """An alarm the emulator raises (its retained state cannot be written) arrives at node-opcua's event
    monitor on the Server object with its number, text and active state; its clearing too."""
    blocker = tmp_path / ".state.json.tmp"
    with two_faces(state_path=tmp_path / "state.json") as (emulator, face):
        cnc = face.alarm_events.namespace_index  # the CNC NodeSet's namespace, or the face's own CNC one
        fields = ["Message", "Severity", f"{cnc}:AlarmIdentifier", "ActiveState.Id", "Retain"]
        job = {"url": face.url, "user": None, "password": None,
               "ops": [{"events": "i=2253", "fields": fields, "ms": 2500}]}
        process = _subscribed_client(job)

        def fail_then_recover() -> None:
            blocker.mkdir()
            with NckClient("127.0.0.1", emulator.port) as nck:
                nck.put({"SD43900[AX4]": 0.1})
                blocker.rmdir()
                nck.put({"SD43900[AX4]": 0.2})

        timer = threading.Timer(0.3, fail_then_recover)
        timer.start()
        out, _ = process.communicate(timeout=60)
        timer.join()
    events = _result(out.splitlines())[0]["events"]
    alarms = [dict(zip(fields, event, strict=True)) for event in events if event[2] == "700999"]
    assert [(a["ActiveState.Id"], a["Retain"], a["Severity"]) for a in alarms] == [(True, True, 500), (False, False, 500)]
    assert alarms[0]["Message"].startswith("retained state not saved")


MACHINERY = "http://opcfoundation.org/UA/Machinery/"
MACHINE_TOOL = "http://opcfoundation.org/UA/MachineTool/"


def test_browses_machines_to_the_umati_instance_then_reads_and_subscribes(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """Objects/Machines -> the MachineToolType instance -> Monitoring -> the channel's feed override: read,
    then subscribed while S7 puts change it."""
    emulator, face = faces
    if not face.models.on:
        pytest.skip("the umati/CNC NodeSets are not installed (make nodesets)")
    to_override = [[MACHINERY, "Machines"], "*", [MACHINE_TOOL, "Monitoring"], [face.models.ns_uri, "CHAN1"],
                   [MACHINE_TOOL, "FeedOverride"]]
    results = node_client(face, [{"browse": to_override[:2]}, {"browse": to_override}, {"read": "$browsed"}])
    assert results[0]["typeDefinition"] == "MachineToolType"
    assert results[2] == {"status": "Good", "value": 100.0}
    job = {"url": face.url, "ops": [{"browse": to_override}, {"subscribe": "$browsed", "ms": 2000}]}
    process = _subscribed_client(job)
    try:
        with NckClient("127.0.0.1", emulator.port) as nck:
            for value in (55.0, 65.0, 75.0):
                nck.put({"feedRateIpoOvr[C1]": value})
        out, _ = process.communicate(timeout=60)
    finally:
        process.kill()
    assert _result(out.splitlines())[1]["values"] == [100.0, 55.0, 65.0, 75.0]


CNC = "http://opcfoundation.org/UA/CNC"
# A declared DataType's built-in type -> the variant types a value of it may travel as: Enumeration as
# Int32, Structure as ExtensionObject; the abstract BaseDataType, Number, Integer, UInteger as any.
_ANY = {24, 26, 27, 28}
_TRAVELS_AS = {29: {6}, 22: {22}}


def test_node_opcua_reads_every_instance_variable_as_declared(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """node-opcua walks the MachineTool and CncInterface instances and reads every variable: a good status, a
    value of its declared DataType (as the built-in type that DataType comes from) and ValueRank, and every
    EngineeringUnits a UNECE common code whose UnitId is its letters."""
    from tests.emulator.faces.opcua.test_opcua_integrator import RECOMMENDATION_20, UNECE, code_of, unit_id_of

    _, face = faces
    if not face.models.on:
        pytest.skip("the umati/CNC NodeSets are not installed (make nodesets)")
    results = node_client(face, [{"browse": [[MACHINERY, "Machines"], "*"]}, {"walk": "$browsed"},
                                 {"browse": [[CNC, "CncInterface"]]}, {"walk": "$browsed"}])
    assert "error" not in results, results
    variables = results[1]["variables"] + results[3]["variables"]
    assert len(variables) > 300
    problems = []
    units = 0
    for entry in variables:
        where = entry["path"]
        if entry["status"] != "Good":
            problems.append(f"{where}: {entry['status']}")
            continue
        base, variant = entry["base"], entry["variant"]
        if base is None:
            problems.append(f"{where}: DataType {entry['dataType']} comes from no built-in type")
        elif base not in _ANY and variant is not None and variant not in _TRAVELS_AS.get(base, {base}):
            problems.append(f"{where}: DataType {entry['dataType']} (built-in {base}), value as variant type {variant}")
        if entry["valueRank"] == -1 and entry["array"]:
            problems.append(f"{where}: ValueRank -1, an array value")
        if entry["valueRank"] >= 1 and entry["array"] is False:
            problems.append(f"{where}: ValueRank {entry['valueRank']}, a scalar value")
        if where.endswith("/EngineeringUnits"):
            units += 1
            unit = entry.get("eu") or {}
            code = code_of(int(unit.get("unitId", 0)))
            if unit.get("namespaceUri") != UNECE or unit_id_of(code) != unit.get("unitId") \
                    or RECOMMENDATION_20.get(code) != (unit.get("displayName"), unit.get("description")):
                problems.append(f"{where}: {unit}")
    assert problems == []
    assert units > 20
