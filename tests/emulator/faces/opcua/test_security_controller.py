"""Security as the controller, over the wire: anonymous sessions never write (variables, programs,
users), a refused login does not say whether the user or the password was wrong, and nothing a
client names reaches a path outside the program store. (An untrusted certificate refused where trust
is on: tests/emulator/faces/opcua/test_opcua_security.py::test_only_trusted_client_certificates_when_not_accepting_any.)"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from asyncua import ua
from asyncua.ua.uaerrors import UaStatusCodeError

from bench.opcua_wire import Wire
from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.faces.opcua.settings import OpcUaSettings
from nckemu.emulator.runner import EmulatorThread
from nckemu.errors import NckConfigError
from tests.support.opcua_tools import NS_URI, connect, two_faces, write_status

pytestmark = pytest.mark.timeout(180)
VARIABLES = [  # one of each kind a client may write
    ("/Channel/Parameter/R[u1,3]", ua.Variant(1.5, ua.VariantType.Double)),
    ("/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]", ua.Variant(0.25, ua.VariantType.Double)),
    ("/Plc/DB130.DBW0", ua.Variant(7, ua.VariantType.UInt16)),
    ("/Plc/MB0", ua.Variant(7, ua.VariantType.Byte)),
]


@pytest.fixture(scope="module")
def faces(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[EmulatorThread, OpcUaFace]]:
    with two_faces(state_path=tmp_path_factory.mktemp("state") / "state.json") as pair:
        yield pair


async def _call(face: OpcUaFace, user: str | None, password: str | None, method: str, *arguments: Any) -> Any:
    client = await connect(face, user, password)
    try:
        ns = await client.get_namespace_index(NS_URI)
        methods = await client.nodes.objects.get_child([f"{ns}:Sinumerik", f"{ns}:Methods"])
        try:
            return await methods.call_method(f"{ns}:{method}", *arguments)
        except UaStatusCodeError as exc:
            return type(exc).__name__
    finally:
        await client.disconnect()


def test_anonymous_sessions_never_write(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    face = faces[1]
    programs_before = set(face.emulator.nck.programs.paths)

    async def go() -> list[Any]:
        seen = [await write_status(face, node, value, user=None) for node, value in VARIABLES]
        seen.append(await _call(face, None, None, "CopyFileToServer",
                                ua.Variant("Sinumerik/FileSystem/Part Program/ANON.MPF"),
                                ua.Variant(b"M30\n", ua.VariantType.ByteString), ua.Variant(True)))
        seen.append(await _call(face, None, None, "AddUser", ua.Variant("intruder"), ua.Variant("x")))
        seen.append(await _call(face, None, None, "ChangeMyPassword", ua.Variant("a"), ua.Variant("b")))
        return seen

    seen = asyncio.run(go())
    assert seen[:len(VARIABLES)] == ["BadUserAccessDenied"] * len(VARIABLES)
    assert seen[len(VARIABLES):] == ["BadRequestNotAllowed"] * 3
    assert set(face.emulator.nck.programs.paths) == programs_before
    assert "intruder" not in face.users.accounts


def test_anonymous_write_rights_are_refused_in_the_machine_file() -> None:
    with pytest.raises(NckConfigError) as raised:
        OpcUaSettings.from_machine({"anonymous": ["SinuReadAll", "PlcWrite"]}, "m.toml")
    assert "opcua.anonymous" in str(raised.value) and "never write" in str(raised.value)


def test_a_refused_login_does_not_say_which_part_was_wrong(faces: tuple[EmulatorThread, OpcUaFace]) -> None:
    """Wrong password, unknown user, both, empty: the same status, and no text that tells them apart."""
    face = faces[1]

    async def go() -> list[tuple[str, bytes]]:
        seen = []
        for user, password in (("nckemu", "WRONG"), ("nobody", "SUNRISE"), ("nobody", "WRONG"), ("nckemu", ""),
                               ("", "SUNRISE")):
            wire = Wire(face.url)
            got = await wire.handshake("127.0.0.1", face.port, user, password)
            wire.close()
            seen.append((ua.StatusCode(got.status).name, got.body[12:]))  # past the response's timestamp
        return seen

    seen = asyncio.run(go())
    assert {status for status, _ in seen} == {"BadUserAccessDenied"}
    assert len({body for _, body in seen}) == 1, seen  # diagnostics and all: byte for byte the same


HOSTILE_PATHS = [
    "../../etc/passwd", "/etc/passwd", "Sinumerik/FileSystem/Part Program/../../../tmp/x.MPF",
    "Sinumerik/FileSystem/Part Program/..%2F..%2Fx.MPF", "Sinumerik/FileSystem/Part Program/A/B.MPF",
    "/_N_MPF_DIR/_N_../../X_MPF", "/_N_MPF_DIR/../_N_X_MPF", "C:\\Windows\\x.MPF",
    "Sinumerik/FileSystem/Part Program/" + "A" * 25 + ".MPF", "Sinumerik/FileSystem/Part Program/" + "A" * 5000 + ".MPF",
    "Sinumerik/FileSystem/Part Program/X.MPF\x00.txt", "Sinumerik/FileSystem/Part Program/ .MPF",
    "Sinumerik/FileSystem/Part Program/X.MPF/..", "~/X.MPF", "file:///etc/passwd",
]


def test_copy_file_paths_never_leave_the_program_store(faces: tuple[EmulatorThread, OpcUaFace],
                                                       tmp_path: Path) -> None:
    face = faces[1]
    programs_before = set(face.emulator.nck.programs.paths)
    cwd_before = set(os.listdir("."))

    async def go() -> tuple[list[Any], list[Any]]:
        to, back = [], []
        for path in HOSTILE_PATHS:
            to.append(await _call(face, "nckemu", "SUNRISE", "CopyFileToServer", ua.Variant(path),
                                  ua.Variant(b"M30\n", ua.VariantType.ByteString), ua.Variant(True)))
            back.append(await _call(face, "nckemu", "SUNRISE", "CopyFileFromServer", ua.Variant(path)))
        return to, back

    to, back = asyncio.run(go())
    assert to == ["BadInvalidArgument"] * len(HOSTILE_PATHS)
    assert back == ["BadInvalidArgument"] * len(HOSTILE_PATHS)
    assert set(face.emulator.nck.programs.paths) == programs_before
    assert set(os.listdir(".")) == cwd_before
    assert all(not name.startswith("_N_") for name in os.listdir(face.emulator.store.path.parent)
               if face.emulator.store is not None)
