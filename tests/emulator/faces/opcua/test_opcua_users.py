"""User management on the OPC UA face (Sinumerik/Methods) with asyncua's client, and users and part
programs kept over a restart with --state; the registry against a plain model (hypothesis)."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest
from asyncua import ua
from asyncua.ua.uaerrors import UaStatusCodeError
from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.faces.opcua.settings import RIGHTS, OpcUaSettings, User
from nckemu.emulator.faces.opcua.users import MAX_USERS, UserError, UserRegistry, format_rights, parse_rights
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import load_machine
from tests.support.opcua_tools import connect, write_status

pytestmark = pytest.mark.timeout(180)
SD = "/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]"
PROGRAM = "Sinumerik/FileSystem/Part Program/KEEP1.MPF"


async def _call(face: OpcUaFace, user: str | None, password: str | None, method: str, *arguments: Any) -> Any:
    client = await connect(face, user, password)
    try:
        ns = await client.get_namespace_index("SinumerikVarProvider")
        methods = await client.nodes.objects.get_child([f"{ns}:Sinumerik", f"{ns}:Methods"])
        try:
            return await methods.call_method(f"{ns}:{method}", *arguments)
        except UaStatusCodeError as exc:
            return type(exc).__name__
    finally:
        await client.disconnect()


async def _can_login(face: OpcUaFace, user: str, password: str) -> bool:
    try:
        client = await connect(face, user, password)
    except UaStatusCodeError:
        return False
    await client.disconnect()
    return True


async def _face(state: Path | None = None) -> OpcUaFace:
    return await OpcUaFace(Emulator(load_machine(None), state_path=state), "127.0.0.1", 0).start()


def test_the_admin_manages_users_and_their_rights_apply_at_once(tmp_path: Path) -> None:
    async def go() -> dict[str, Any]:
        face = await _face()
        admin = ("nckemu", "SUNRISE")
        seen: dict[str, Any] = {}
        try:
            seen["add"] = await _call(face, *admin, "AddUser", "op1", "first")
            seen["give"] = await _call(face, *admin, "GiveUserAccess", "op1", "PlcRead;PlcWrite;StateRead")
            seen["rights"] = await _call(face, *admin, "GetUserAccessRights", "op1")
            seen["list"] = await _call(face, *admin, "GetUserList")
            seen["plc"] = await write_status(face, "/Plc/DB130.DBW0", ua.Variant(5, ua.VariantType.UInt16), "op1", "first")
            seen["sea"] = await write_status(face, SD, ua.Variant(0.1, ua.VariantType.Double), "op1", "first")
            seen["take"] = await _call(face, *admin, "DeleteUserAccess", "op1", "PlcWrite")
            seen["plc_after"] = await write_status(face, "/Plc/DB130.DBW0", ua.Variant(6, ua.VariantType.UInt16),
                                                  "op1", "first")
            seen["not_admin"] = await _call(face, "op1", "first", "AddUser", "op2", "x")
            seen["anonymous"] = await _call(face, None, None, "GetUserList")
            seen["certificate"] = await _call(face, *admin, "AddCertificateUser", "op3", b"\x30\x00")
            seen["bad_realm"] = await _call(face, *admin, "GiveUserAccess", "op1", "EverythingWrite")
            seen["password"] = await _call(face, "op1", "first", "ChangeMyPassword", "first", "second")
            seen["old_login"] = await _can_login(face, "op1", "first")
            seen["new_login"] = await _can_login(face, "op1", "second")
            seen["delete"] = await _call(face, *admin, "DeleteUser", "op1")
            seen["deleted_login"] = await _can_login(face, "op1", "second")
        finally:
            await face.stop()
        return seen

    seen = asyncio.run(go())
    assert seen["add"] is None and seen["give"] is None and seen["take"] is None and seen["password"] is None
    assert seen["rights"] == "PlcRead;PlcWrite;StateRead" and seen["list"] == ["nckemu", "op1"]
    assert seen["plc"] == "Good" and seen["sea"] == "BadUserAccessDenied"
    assert seen["plc_after"] == "BadUserAccessDenied"
    assert seen["not_admin"] == "BadInvalidArgument" and seen["anonymous"] == "BadRequestNotAllowed"
    assert seen["certificate"] == "BadNotSupported" and seen["bad_realm"] == "BadInvalidArgument"
    assert seen["old_login"] is False and seen["new_login"] is True
    assert seen["delete"] is None and seen["deleted_login"] is False


def test_at_most_twenty_users() -> None:
    async def go() -> list[Any]:
        face = await _face()
        try:
            answers = [await _call(face, "nckemu", "SUNRISE", "AddUser", f"u{i}", "pw") for i in range(MAX_USERS)]
        finally:
            await face.stop()
        return answers

    answers = asyncio.run(go())
    assert answers[:MAX_USERS - 1] == [None] * (MAX_USERS - 1)  # the default machine has one user already
    assert answers[-1] == "BadInvalidArgument"


def test_users_and_copied_programs_survive_a_restart_with_state(tmp_path: Path) -> None:
    state = tmp_path / "state.json"

    async def first_run() -> None:
        face = await _face(state)
        try:
            assert await _call(face, "nckemu", "SUNRISE", "AddUser", "keeper", "kept") is None
            assert await _call(face, "nckemu", "SUNRISE", "GiveUserAccess", "keeper", "FSRead") is None
            assert await _call(face, "nckemu", "SUNRISE", "CopyFileToServer", PROGRAM, b"G0 X1\nM30\n", True) is None
        finally:
            await face.stop()

    async def second_run() -> tuple[bool, Any, Any]:
        face = await _face(state)
        try:
            return (await _can_login(face, "keeper", "kept"),
                    await _call(face, "keeper", "kept", "CopyFileFromServer", PROGRAM),
                    await _call(face, "nckemu", "SUNRISE", "GetUserAccessRights", "keeper"))
        finally:
            await face.stop()

    asyncio.run(first_run())
    login, program, rights = asyncio.run(second_run())
    assert login is True and program == b"G0 X1\nM30\n" and rights == "FSRead"
    restarted = Emulator(load_machine(None), state_path=state)
    assert "/_N_MPF_DIR/_N_KEEP1_MPF" in restarted.nck.programs.paths  # where PI _N_SELECT looks


@given(st.sets(st.sampled_from(sorted(RIGHTS)), min_size=1))
def test_rights_text_round_trips(rights: set[str]) -> None:
    assert parse_rights(format_rights(frozenset(rights))) == rights
    assert parse_rights(" ; ".join(sorted(rights)) + ";") == rights


@given(st.text(max_size=30))
def test_rights_text_is_parsed_or_refused(text: str) -> None:
    try:
        assert parse_rights(text) <= RIGHTS
    except UserError as refusal:
        assert refusal.status == "BadInvalidArgument"


names = st.sampled_from(["nckemu", "a", "b", "c", "", "x y", "a" * 70])
operations = st.lists(st.one_of(
    st.tuples(st.just("add"), st.sampled_from(["nckemu", "a"]), names, st.sampled_from(["pw", ""])),
    st.tuples(st.just("delete"), st.sampled_from(["nckemu", "a"]), names),
    st.tuples(st.just("give"), st.sampled_from(["nckemu", "a"]), names, st.sampled_from(["PlcRead", "Nope"])),
    st.tuples(st.just("take"), st.sampled_from(["nckemu", "a"]), names, st.sampled_from(["PlcRead", "StateRead"])),
    st.tuples(st.just("password"), names, st.sampled_from(["pw", "SUNRISE"]), st.sampled_from(["new", ""])),
), max_size=25)


@given(operations)
def test_registry_as_a_plain_model(steps: list[tuple[Any, ...]]) -> None:
    """Each call either changes the users as a dict of (password, rights) would, or is refused and
    changes nothing; the admin always remains; never more than 20 users."""
    settings = OpcUaSettings(users={"nckemu": User("nckemu", "SUNRISE", frozenset({"SinuReadAll"}))})
    registry = UserRegistry(settings)
    model = {"nckemu": ("SUNRISE", frozenset({"SinuReadAll"}))}
    for step in steps:
        before = registry.snapshot()
        kind, caller, *rest = step
        try:
            if kind == "add":
                registry.add_user(caller, *rest)
                model[rest[0]] = (rest[1], frozenset())
            elif kind == "delete":
                registry.delete_user(caller, rest[0])
                del model[rest[0]]
            elif kind == "give":
                registry.give_access(caller, *rest)
                model[rest[0]] = (model[rest[0]][0], model[rest[0]][1] | {rest[1]})
            elif kind == "take":
                registry.delete_access(caller, *rest)
                model[rest[0]] = (model[rest[0]][0], model[rest[0]][1] - {rest[1]})
            else:
                registry.change_my_password(caller, *rest)
                model[caller] = (rest[1], model[caller][1])
        except UserError as refusal:
            assert refusal.status == "BadInvalidArgument"
            assert registry.snapshot() == before
        assert {n: (a.password, a.rights) for n, a in registry.accounts.items()} == model
        assert "nckemu" in model and len(model) <= MAX_USERS
