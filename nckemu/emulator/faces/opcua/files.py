"""Methods under ``Sinumerik/Methods``: GetMyAccessRights, CopyFileToServer, CopyFileFromServer.

Part programs live in the emulator's program store, the ``_N_MPF_DIR`` the PI services select from:
``Sinumerik/FileSystem/Part Program/PART1.MPF`` is ``/_N_MPF_DIR/_N_PART1_MPF``; the names the control
and users write (``/_N_SPF_DIR/_N_CYCLE_SPF``, ``CYCLE.SPF``) are taken too. A program is written and read
whole through the store (``Programs.write``/``read``); the program a channel runs is not replaced.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Any

from asyncua import Server, ua

from nckemu.catalogue.program_names import program_path as nc_program_path
from nckemu.emulator.faces.opcua import request
from nckemu.emulator.faces.opcua.settings import may
from nckemu.errors import NckNoSuchFile, NckPiBadArguments, NckPiStateError

log = logging.getLogger(__name__)

if TYPE_CHECKING:
    from nckemu.emulator.faces.opcua.parts import MethodHost

MAX_PROGRAM_BYTES = 16 * 1024 * 1024
_UA_PATH = re.compile(r"^/?sinumerik/filesystem/part program/(?P<name>[A-Za-z0-9_]{1,24})\.mpf$", re.IGNORECASE)
_NC_PATH = re.compile(r"^/_N_MPF_DIR/_N_(?P<name>[A-Za-z0-9_]{1,24})_MPF$", re.IGNORECASE)


def program_path(text: str) -> str | None:
    """The program store's path of a file path a client names, or None."""
    for pattern in (_UA_PATH, _NC_PATH):
        match = pattern.match(text.strip())
        if match:
            return f"/_N_MPF_DIR/_N_{match['name'].upper()}_MPF"
    try:  # the names the control and users write
        return nc_program_path(text)
    except NckPiBadArguments:
        return None


def plain(argument: Any) -> Any:
    """asyncua hands method arguments over as variants."""
    return argument.Value if isinstance(argument, ua.Variant) else argument


def _bad(name: str) -> ua.StatusCode:
    return ua.StatusCode(getattr(ua.StatusCodes, name))


def refused(right: str, write: bool) -> ua.StatusCode | None:
    """Why the request's session may not call a method needing ``right`` (None: it may)."""
    if not request.user():
        return _bad("BadRequestNotAllowed")  # as the controller: anonymous sessions call no methods
    if not may(request.rights(), right, write):
        return _bad("BadUserAccessDenied")
    return None


def argument(name: str, kind: ua.VariantType, description: str = "") -> ua.Argument:
    """A scalar method argument (described by its name unless ``description`` is given)."""
    return ua.Argument(Name=name, DataType=ua.NodeId(kind.value), ValueRank=-1, ArrayDimensions=[],
                       Description=ua.LocalizedText(description or name))


MethodRow = tuple[str, Callable[..., Awaitable[Any]], list[ua.Argument], list[ua.Argument],
                  Callable[[str, frozenset[str]], bool]]


async def add_method_nodes(server: Server, methods: Any, ns: int, table: list[MethodRow]) -> None:
    """Each row's method below ``methods`` as ``/Methods/<name>``, with UserExecutable as the session
    reads it decided by the row's last entry (user, rights), as the handler decides."""
    for name, method, inputs, outputs, executable in table:
        node = await methods.add_method(ua.NodeId(f"/Methods/{name}", ns), ua.QualifiedName(name, ns),
                                        request.with_arguments(method, len(inputs)), inputs, outputs)
        server.set_attribute_value_callback(node.nodeid, request.user_executable(executable),
                                            ua.AttributeIds.UserExecutable)


async def add_methods(face: MethodHost, server: Server) -> Any:
    ns = face.namespace
    root = await server.nodes.objects.get_child([f"{ns}:Sinumerik"])
    methods = await root.add_object(ua.NodeId("/Methods", ns), ua.QualifiedName("Methods", ns))
    programs = face.emulator.nck.programs

    async def get_my_access_rights(_parent: Any) -> Any:
        if not request.user():
            return _bad("BadRequestNotAllowed")
        return [ua.Variant(";".join(sorted(request.rights())), ua.VariantType.String)]

    async def copy_to_server(_parent: Any, path: Any, data: Any, overwrite: Any) -> Any:
        status = refused("FS", True)
        if status is not None:
            return status
        path, data, overwrite = plain(path), plain(data), plain(overwrite)
        target = program_path(path) if isinstance(path, str) else None
        if target is None or not isinstance(data, bytes) or len(data) > MAX_PROGRAM_BYTES:
            return _bad("BadInvalidArgument")
        if target in programs.paths and not overwrite:
            return _bad("BadInvalidState")
        try:
            programs.write(target, bytes(data))
        except NckPiStateError:  # the program a channel is running
            return _bad("BadInvalidState")
        except NckPiBadArguments as exc:  # a definition file with an error: refused, the old one stays
            log.info("CopyFileToServer %s refused: %s", target, exc)
            return _bad("BadInvalidArgument")
        face.emulator.saves.request()  # the program store is retained data (serve --state)
        await face.emulator.saves.durable()
        return []

    async def copy_from_server(_parent: Any, path: Any) -> Any:
        status = refused("FS", False)
        if status is not None:
            return status
        path = plain(path)
        target = program_path(path) if isinstance(path, str) else None
        if target is None:
            return _bad("BadInvalidArgument")
        try:
            text = programs.read(target)
        except NckNoSuchFile:
            return _bad("BadNotFound")
        return [ua.Variant(text, ua.VariantType.ByteString)]

    text, blob, flag = ua.VariantType.String, ua.VariantType.ByteString, ua.VariantType.Boolean
    # Who may call each (UserExecutable as the session reads it): as the handlers above decide.
    await add_method_nodes(server, methods, ns, [
        ("GetMyAccessRights", get_my_access_rights, [], [argument("rights", text)],
         lambda user, _rights: bool(user)),
        ("CopyFileToServer", copy_to_server,
         [argument("path", text), argument("data", blob), argument("overwrite", flag)], [],
         lambda user, rights: bool(user) and may(rights, "FS", True)),
        ("CopyFileFromServer", copy_from_server, [argument("path", text)], [argument("data", blob)],
         lambda user, rights: bool(user) and may(rights, "FS", False)),
    ])
    return methods
