"""Part programs to and from an NCK, and the program's control: the telegrams libnodave's
``davePutNCProgram`` and ``daveGetNcFile`` send (userdata group "NC programming"), PI ``_N_F_XFER`` /
``_N_SELECT`` / ``_N_F_DELE``, and NC start, stop and reset as rising edges of DB21.DBX7.1 / 7.3 / 7.7.

Async functions take an ``AsyncNckClient``, their ``*_sync`` twins an ``NckClient``; both use the
client's python-snap7 connection, so they drive the emulator or a real control alike.

Download: request download (the file name alone) -> the NC answers a sequence number and a window ->
download blocks of at most PDU size - 28 bytes, waiting for the NC's "continue download" after each
window's last block unless it is the transfer's last -> download ended, whose answer says whether
the program was stored. Upload: PI ``_N_F_XFER("P01", path)``, start upload (window 20, the name's
last part) -> the first piece in the answer, the others as NC pushes; after every 20 of them
"continue upload".
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable, Coroutine
from dataclasses import dataclass
from datetime import datetime
from typing import Any, TypeVar

from nckemu.catalogue.program_names import directory_path, program_path, user_name
from nckemu.errors import (
    NckConfigError,
    NckConnectionError,
    NckError,
    NckProtocolError,
    NckServiceError,
    NckTimeoutError,
    service_error_for,
)
from nckemu.protocol import blocks, ncprog, s7
from nckemu.protocol.codes import HEADER_ERROR_TEXTS
from nckemu.protocol.ncprog import NcData, NcParameter, NcSubfunction

from .async_client import AsyncNckClient
from .sync import NckClient

T = TypeVar("T")

# libnodave's window after the first one (it ignores the count a "continue download" carries).
DOWNLOAD_WINDOW_AFTER_FIRST = 8
# The address identification clients give file PIs (libnodave's tests, DotNetSiemensPLCToolBoxLibrary).
FILE_PI_IDENT = "P01"
# _N_SELECT's address identification (the channel's: "201" in every capture).
SELECT_IDENT = "201"
# PLC interface to the channel: DB21 for channel 1, DB22 for channel 2, ...; DBB7 bits.
CHANNEL_DB_BASE = 21
SIGNAL_BITS = {"start": 1, "stop": 3, "reset": 7}


@dataclass(frozen=True)
class Listing:
    """A directory as the NC sends it: entries (name, size in bytes or None) and the raw text."""

    directory: str
    entries: tuple[tuple[str, int | None], ...]
    text: bytes


class _Wire:
    """Telegrams on the client's connection, one at a time, each receive bounded by ``timeout_s``."""

    def __init__(self, nck: AsyncNckClient, connection: Any, pdu_size: int) -> None:
        self._nck = nck
        self._connection = connection
        self.pdu_size = pdu_size

    async def send(self, parameter: bytes, data: bytes) -> None:
        pdu = s7.S7Pdu(s7.Rosctr.USERDATA, next(self._nck._refs), parameter, data)
        await self._connection.send_data(s7.build_pdu(pdu))

    async def receive(self, what: str) -> tuple[NcParameter, NcData]:
        try:
            raw = await asyncio.wait_for(self._connection.receive_data(), self._nck.timeout_s)
        except TimeoutError:
            raise NckTimeoutError(f"{what}: no answer within {self._nck.timeout_s} s") from None
        pdu = s7.parse_pdu(bytes(raw))
        if pdu.error_class or pdu.error_code:
            code = (pdu.error_class << 8) | pdu.error_code
            raise service_error_for(pdu.error_class, pdu.error_code,
                                    f"{what}: the controller refused it: "
                                    f"{HEADER_ERROR_TEXTS.get(code, 'no known text')} (0x{code:04X})")
        if pdu.rosctr != s7.Rosctr.USERDATA or not ncprog.is_nc_parameter(pdu.parameter):
            raise NckProtocolError(f"{what}: the answer is not an NC programming telegram")
        parameter = ncprog.parse_nc_parameter(pdu.parameter)
        if parameter.error_code:
            code = parameter.error_code
            meaning = ncprog.ERROR_TEXTS.get(code) or HEADER_ERROR_TEXTS.get(code, "no known text")
            raise service_error_for(code >> 8, code & 0xFF, f"{what}: the controller refused it: {meaning} "
                                                             f"(error 0x{code:04X})")
        return parameter, ncprog.parse_nc_data(pdu.data)


async def _on_wire(nck: AsyncNckClient, what: str, operation: Callable[[_Wire], Awaitable[T]]) -> T:
    """Run one transfer on the client's connection (its lock held); any fault but the controller's
    own answer closes the connection (the next call reconnects), as ``AsyncNckClient`` does."""
    async with nck._lock:
        if nck._client is None:
            await nck.connect()
        client = nck._client
        assert client is not None
        # python-snap7's AsyncClient keeps its ISO connection in the public ``connection`` attribute
        # (``send_data`` / ``receive_data`` move one PDU each): checked here, so a new version fails loudly.
        connection = getattr(client, "connection", None)
        if connection is None or not hasattr(connection, "send_data") or not hasattr(connection, "receive_data"):
            raise NckConnectionError(f"{what}: python-snap7's connection has no send_data/receive_data")
        try:
            return await operation(_Wire(nck, connection, int(getattr(client, "pdu_length", 240))))
        except NckProtocolError:
            await nck.disconnect()
            raise
        except NckTimeoutError:
            await nck.disconnect()
            raise
        except NckError:
            raise
        except Exception as exc:
            await nck.disconnect()
            raise NckConnectionError(f"{what}: connection to {nck.host}:{nck.port} lost ({exc}); "
                                     "the next call reconnects") from None



async def put_program(nck: AsyncNckClient, name: str, text: bytes, *, now: datetime | None = None) -> str:
    """Send ``text`` as the program ``name`` (``DAILY.MPF``, ``/_N_MPF_DIR/_N_DAILY_MPF``); returns its
    path. Raises NckServiceError with the controller's code when it refuses (store full, running)."""
    path = program_path(name)
    directory, leaf = path.rsplit("/", 1)
    content = ncprog.build_transfer_content(ncprog.TransferContent(directory, bytes(text),
                                                                   ncprog.stamp_at(now or datetime.now())))

    async def transfer(wire: _Wire) -> str:
        what = f"download of {user_name(path)}"
        room = wire.pdu_size - ncprog.BLOCK_OVERHEAD
        pieces = ncprog.split_content(content, room)
        await wire.send(ncprog.build_nc_parameter(NcParameter(ncprog.NC_REQUEST, NcSubfunction.REQUEST_DOWNLOAD)),
                        ncprog.build_nc_data(NcData(ncprog.build_name(leaf))))
        answer, data = await wire.receive(what)
        if answer.subfunction != NcSubfunction.REQUEST_DOWNLOAD:
            raise NckProtocolError(f"{what}: answered with subfunction {answer.subfunction}")
        sequence = answer.sequence
        window = max(1, ncprog.parse_window(data.payload).count)
        unacknowledged = 0
        for index, piece in enumerate(pieces):
            last = index == len(pieces) - 1
            await wire.send(ncprog.build_nc_parameter(NcParameter(
                ncprog.NC_PUSH, NcSubfunction.DOWNLOAD_BLOCK, sequence, long=True, data_unit_ref=(index + 1) & 0xFF,
                last_data_unit=ncprog.LAST_DATA_UNIT if last else ncprog.MORE_DATA_UNITS)),
                ncprog.build_nc_data(NcData(ncprog.build_chunk(piece))))
            unacknowledged += 1
            if not last and unacknowledged == window:
                push, push_data = await wire.receive(what)
                if push.type != ncprog.NC_PUSH or push.subfunction != NcSubfunction.CONTINUE_DOWNLOAD:
                    raise NckProtocolError(f"{what}: expected continue download, got {ncprog.describe(push)}")
                unacknowledged = 0
                # libnodave goes on with 8 whatever the push says; the count it carries is taken
                # here, which is the same with an NC that announces 8 (nckemu's default).
                window = max(1, ncprog.parse_window(push_data.payload).count) if len(push_data.payload) == 2 \
                    else DOWNLOAD_WINDOW_AFTER_FIRST
        await wire.send(ncprog.build_nc_parameter(NcParameter(ncprog.NC_REQUEST, NcSubfunction.DOWNLOAD_ENDED,
                                                              sequence)),
                        ncprog.build_nc_data(NcData(b"\x00\x00")))
        ended, _ = await wire.receive(what)
        if ended.subfunction != NcSubfunction.DOWNLOAD_ENDED:
            raise NckProtocolError(f"{what}: answered with subfunction {ended.subfunction}")
        return path

    return await _on_wire(nck, f"download of {name}", transfer)


async def get_file(nck: AsyncNckClient, name: str, *, mark: bool = True) -> ncprog.TransferContent:
    """Upload a file or directory: PI ``_N_F_XFER`` (``mark``) then start upload of its last part;
    the transfer content (directory, text, time stamp) as the NC sent it."""
    path = directory_path(name) or program_path(name)
    if mark:
        try:
            await nck.pi_service("_N_F_XFER", FILE_PI_IDENT, path)
        except NckServiceError as exc:
            raise service_error_for(exc.error_class, exc.error_code, f"{path}: _N_F_XFER refused ({exc})") from None
    leaf = path.rsplit("/", 1)[-1]

    async def transfer(wire: _Wire) -> ncprog.TransferContent:
        what = f"upload of {user_name(path)}"
        await wire.send(ncprog.build_nc_parameter(NcParameter(ncprog.NC_REQUEST, NcSubfunction.START_UPLOAD)),
                        ncprog.build_nc_data(NcData(ncprog.build_start_upload(ncprog.StartUpload(leaf)))))
        answer, data = await wire.receive(what)
        if answer.subfunction != NcSubfunction.START_UPLOAD:
            raise NckProtocolError(f"{what}: answered with subfunction {answer.subfunction}")
        pieces = [ncprog.parse_chunk(data.payload)]
        last, pushes = answer.is_last, 0
        while not last:
            push, data = await wire.receive(what)
            if push.subfunction != NcSubfunction.UPLOAD or push.sequence != answer.sequence:
                raise NckProtocolError(f"{what}: expected an upload piece, got {ncprog.describe(push)}")
            chunk = ncprog.parse_chunk(data.payload)
            if not chunk and not push.is_last:
                raise NckProtocolError(f"{what}: an empty piece")
            pieces.append(chunk)
            last, pushes = push.is_last, pushes + 1
            if not last and pushes % ncprog.UPLOAD_WINDOW == 0:
                await wire.send(ncprog.build_nc_parameter(NcParameter(
                    ncprog.NC_PUSH, NcSubfunction.CONTINUE_UPLOAD, answer.sequence)),
                    ncprog.build_nc_data(NcData(ncprog.build_window(ncprog.Window(ncprog.UPLOAD_WINDOW)))))
        return ncprog.parse_transfer_content(b"".join(pieces))

    return await _on_wire(nck, f"upload of {name}", transfer)


async def get_program(nck: AsyncNckClient, name: str) -> bytes:
    """The text of the program ``name`` (``DAILY.MPF``, ``_N_DAILY_MPF``, a full path)."""
    return (await get_file(nck, name)).text


async def get_file_by_blocks(nck: AsyncNckClient, name: str) -> bytes:
    """libnodave's ``daveGetNCProgram``: start upload (0x1D) naming the NC file, upload (0x1E) until
    the answer's status says no more, end upload (0x1F); the bytes as the NC sent them (nckemu sends
    the transfer content, header included; what a real NC sends is unconfirmed)."""
    path = program_path(name)
    leaf = path.rsplit("/", 1)[-1]
    start = await nck.exchange(blocks.build_block_control(blocks.BlockControl(blocks.START_UPLOAD, 0, 0, 0, leaf)))
    upload_id = blocks.parse_block_control(start.parameter).session
    received, more = [], True
    try:
        while more:
            answer = await nck.exchange(blocks.build_block_control(
                blocks.BlockControl(blocks.UPLOAD, 0, 0, upload_id, None)))
            more = len(answer.parameter) > 1 and bool(answer.parameter[1] & 0x01)
            received.append(ncprog.parse_upload_data(answer.data).content)
    finally:
        await nck.exchange(blocks.build_block_control(blocks.BlockControl(blocks.END_UPLOAD, 0, 0, upload_id, None)))
    return b"".join(received)


def parse_listing(content: ncprog.TransferContent) -> Listing:
    """A directory upload's lines ``<name> <size>`` (nckemu's format; a name alone where no size)."""
    entries: list[tuple[str, int | None]] = []
    for line in content.text.decode("ascii", "replace").splitlines():
        fields = line.split()
        if not fields:
            continue
        size = int(fields[1]) if len(fields) > 1 and fields[1].isdigit() else None
        entries.append((fields[0], size))
    return Listing(content.path, tuple(entries), content.text)


async def list_directory(nck: AsyncNckClient, directory: str = "_N_MPF_DIR") -> Listing:
    """The files of ``directory`` (``_N_MPF_DIR``, ``MPF_DIR``, ``/_N_WKS_DIR/_N_PART_WPD``)."""
    text = directory.strip()
    path = directory_path(text) or directory_path(f"_N_{text.strip('/').replace('.', '_')}".upper())
    if path is None:
        raise NckConfigError(f"{directory!r} is not an NC directory (e.g. _N_MPF_DIR, SPF_DIR, /_N_WKS_DIR)")
    return parse_listing(await get_file(nck, path))


async def select_program(nck: AsyncNckClient, name: str, *, ident: str = SELECT_IDENT) -> str:
    """PI ``_N_SELECT(ident, path)``: the program the channel runs at the next NC start."""
    path = program_path(name)
    await nck.pi_service("_N_SELECT", ident, path)
    return path


async def delete_program(nck: AsyncNckClient, name: str) -> str:
    path = program_path(name)
    await nck.pi_service("_N_F_DELE", FILE_PI_IDENT, path)
    return path


def signal_address(signal: str, channel: int = 1) -> str:
    """``DB21.DBX7.1`` for NC start of channel 1 (stop 7.3, reset 7.7; DB21 + channel - 1)."""
    if signal not in SIGNAL_BITS:
        raise NckConfigError(f"{signal!r}: expected one of {', '.join(SIGNAL_BITS)}")
    if not 1 <= channel <= 10:
        raise NckConfigError(f"channel {channel}: expected 1..10")
    return f"DB{CHANNEL_DB_BASE + channel - 1}.DBX7.{SIGNAL_BITS[signal]}"


async def pulse(nck: AsyncNckClient, signal: str, channel: int = 1) -> str:
    """A rising edge on the channel's signal (write 1, then 0), as a PLC program gives one."""
    address = signal_address(signal, channel)
    await nck.put({address: True})
    await nck.put({address: False})
    return address


# ---------------------------------------------------------------- sync twins
# A transfer's telegrams each wait at most the client's timeout; the whole may take long (megabytes
# over a slow link), so the sync twins wait for it this long rather than the client's job bound.
SYNC_TRANSFER_WAIT_S = 3600.0


def _run(nck: NckClient, coroutine: Coroutine[Any, Any, T]) -> T:
    return nck.submit(coroutine).result(SYNC_TRANSFER_WAIT_S)


def put_program_sync(nck: NckClient, name: str, text: bytes) -> str:
    return _run(nck, put_program(nck.async_client, name, text))


def get_file_sync(nck: NckClient, name: str, *, mark: bool = True) -> ncprog.TransferContent:
    return _run(nck, get_file(nck.async_client, name, mark=mark))


def get_file_by_blocks_sync(nck: NckClient, name: str) -> bytes:
    return _run(nck, get_file_by_blocks(nck.async_client, name))


def get_program_sync(nck: NckClient, name: str) -> bytes:
    return _run(nck, get_program(nck.async_client, name))


def list_directory_sync(nck: NckClient, directory: str = "_N_MPF_DIR") -> Listing:
    return _run(nck, list_directory(nck.async_client, directory))


def select_program_sync(nck: NckClient, name: str) -> str:
    return _run(nck, select_program(nck.async_client, name))


def delete_program_sync(nck: NckClient, name: str) -> str:
    return _run(nck, delete_program(nck.async_client, name))


def pulse_sync(nck: NckClient, signal: str, channel: int = 1) -> str:
    return _run(nck, pulse(nck.async_client, signal, channel))
