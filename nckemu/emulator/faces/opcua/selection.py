"""``Select(file, channel)`` and ``Unselect(channel)`` under ``Sinumerik/Methods``: a channel's program
chosen for NC start, as the SINUMERIK server offers it (there is no Start method: a client starts by
writing ``/Plc/DB21.DBX7.1``).

Both answer with a status number rather than a Bad code, as the SINUMERIK methods do:

- Select: 0 selected, 1 the channel does not exist, 2 no such program, 3 the channel is not in reset,
  4 rejected (a file that is not an NC program name, or any other refusal of the channel);
- Unselect (ours where the manual is silent, docs/opcua.md): 0 unselected, 1 the channel does not exist,
  2 nothing is selected, 3 the channel is not in reset, 4 rejected, 5 the program is running.

``file`` is a path as a client names the program (``/_N_MPF_DIR/_N_PART1_MPF``, ``PART1.MPF``,
``WARMUP_CYCLE.SPF``, ``Sinumerik/FileSystem/Part Program/PART1.MPF``), as a String or as the NodeId of
the file whose string identifier is such a path. Calling either needs a user session (anonymous:
``BadRequestNotAllowed``) with the right to write channel state (``StateWrite`` or ``SinuWriteAll``;
else ``BadUserAccessDenied``), as writing the DB21 start bit does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from asyncua import Server, ua

from nckemu.emulator.faces.opcua import files
from nckemu.emulator.faces.opcua.settings import may
from nckemu.emulator.machine.nck.channel import CHAN_ACTIVE, CHAN_RESET, Channel
from nckemu.errors import NckError, NckNoSuchFile, NckPiStateError

if TYPE_CHECKING:
    from nckemu.emulator.faces.opcua.parts import MethodHost

SELECTED, NO_CHANNEL, NO_PROGRAM, NOT_IN_RESET, REJECTED = 0, 1, 2, 3, 4
NOTHING_SELECTED, RUNNING = 2, 5
REALM = "State"


def selected_path(text: Any) -> str | None:
    """The program store's path of ``file`` as a client passes it (a path or a file's NodeId), or None."""
    if isinstance(text, ua.NodeId):
        text = text.Identifier
    if not isinstance(text, str):
        return None
    return files.program_path(text)


def select(face: MethodHost, file: Any, channel_number: Any) -> int:
    """Select ``file`` in channel ``channel_number``; the status number."""
    channel = _channel(face, channel_number)
    if channel is None:
        return NO_CHANNEL
    path = selected_path(file)
    if path is None:
        return REJECTED
    programs = face.emulator.nck.programs
    if not programs.exists(path):
        return NO_PROGRAM
    try:
        channel.select(path)
    except NckNoSuchFile:
        return NO_PROGRAM
    except NckPiStateError:
        return NOT_IN_RESET
    except NckError:
        return REJECTED
    return SELECTED


def unselect(face: MethodHost, channel_number: Any) -> int:
    """Unselect channel ``channel_number``'s program; the status number."""
    channel = _channel(face, channel_number)
    if channel is None:
        return NO_CHANNEL
    if not channel.selected:
        return NOTHING_SELECTED
    if channel.state.status == CHAN_ACTIVE:
        return RUNNING
    if channel.state.status != CHAN_RESET:
        return NOT_IN_RESET
    try:
        channel.unselect()
    except NckPiStateError:
        return NOT_IN_RESET
    except NckError:
        return REJECTED
    return SELECTED


def _channel(face: MethodHost, number: Any) -> Channel | None:
    if isinstance(number, bool) or not isinstance(number, int):
        return None
    return face.emulator.nck.channels.get(number)


async def add_methods(face: MethodHost, server: Server, methods: Any) -> None:
    """Select and Unselect below ``methods`` (``Sinumerik/Methods``)."""
    ns = face.namespace

    def status(value: int) -> list[ua.Variant]:
        return [ua.Variant(value, ua.VariantType.Int32)]

    async def select_method(_parent: Any, file: Any, channel: Any) -> Any:
        refusal = files.refused(REALM, True)
        if refusal is not None:
            return refusal
        return status(select(face, files.plain(file), files.plain(channel)))

    async def unselect_method(_parent: Any, channel: Any) -> Any:
        refusal = files.refused(REALM, True)
        if refusal is not None:
            return refusal
        return status(unselect(face, files.plain(channel)))

    def executable(user: str, rights: frozenset[str]) -> bool:  # as ``files.refused`` decides
        return bool(user) and may(rights, REALM, write=True)

    argument, int32 = files.argument, ua.VariantType.Int32
    file = argument("file", ua.VariantType.String, "the program: /_N_MPF_DIR/_N_NAME_MPF, NAME.MPF or its file path")
    channel = argument("channel", ua.VariantType.UInt32, "the channel number (1 ...)")
    await files.add_method_nodes(server, methods, ns, [
        ("Select", select_method, [file, channel],
         [argument("status", int32, "0 ok, 1 no such channel, 2 no such program, "
                                    "3 channel not in reset, 4 rejected")], executable),
        ("Unselect", unselect_method, [channel],
         [argument("status", int32, "0 ok, 1 no such channel, 2 nothing selected, "
                                    "3 channel not in reset, 4 rejected, 5 program running")], executable),
    ])
