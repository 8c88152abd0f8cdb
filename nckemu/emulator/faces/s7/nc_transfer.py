"""NC program transfers of one S7 connection: download and upload over the userdata group "NC
programming", and the upload of an NC file through the PLC-block jobs 0x1D/0x1E/0x1F.

Sans-IO like the session that owns it: PDUs in, PDUs out, the program store and a save request as
the only effects.

Download: request download (answered with a sequence number and a window of ``DOWNLOAD_WINDOW``),
download blocks (no answer; after every ``DOWNLOAD_WINDOW``-th block that is not the last, a "continue
download" push, which libnodave waits for), download ended (answered with the outcome). The blocks
are kept aside and the program is written whole only at "download ended": a transfer cut off
half-way leaves the old program as it was, and nobody ever sees half of the new one.

Upload: start upload is answered with the first piece; up to the client's window of further pieces
follow as pushes, then the NC waits for "continue upload". The pieces are as large as the PDU size
negotiated on the connection allows.

Error codes: no source gives the 2-byte codes an NCK puts in the parameter (programs.md §5, §12.2);
these are S7 codes whose meaning fits and that tshark names (docs/programs-transfer.md).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime

from nckemu.catalogue.program_names import program_path
from nckemu.emulator.machine.nck.programs import Programs
from nckemu.emulator.machine.program.language.definitions import DefinitionRefused
from nckemu.errors import NckError, NckNoSuchFile, NckPiBadArguments, NckPiStateError
from nckemu.protocol import blocks, ncprog, s7
from nckemu.protocol.errors import NckProtocolError
from nckemu.protocol.ncprog import NcData, NcParameter, NcSubfunction

log = logging.getLogger("nckemu.emulator.nc_transfer")

# Telegrams a client may send before waiting (announced in the answer to request download, and the
# count after which the NC pushes "continue download"; libnodave uses 8 after the first window). The
# machine file's settings.nc_download_window overrides it.
DOWNLOAD_WINDOW = 8
# Store capacity when the machine file sets none (bytes of program text; assumed, see machine_file).
DEFAULT_STORE_BYTES = 3 * 1024 * 1024
# Room in a 0x1E Ack_Data: header 12, parameter 2, length 2 and two leading bytes.
_BLOCK_ROOM = 12 + 2 + 4
# The directory listing's line for each entry (UNCONFIRMED format: docs/programs-transfer.md).
LISTING_LINE = "{name} {size}\n"


def _error_for(exc: NckError) -> int:
    if isinstance(exc, DefinitionRefused):  # a GUD/macro file with an error: its content, not its name
        return ncprog.ERROR_BAD_CONTENT
    if isinstance(exc, NckNoSuchFile):
        return ncprog.ERROR_NO_SUCH_FILE
    if isinstance(exc, NckPiBadArguments):
        return ncprog.ERROR_NOT_A_FILE_NAME
    if isinstance(exc, NckPiStateError):
        return ncprog.ERROR_IN_USE
    if isinstance(exc, NckProtocolError):
        return ncprog.ERROR_BAD_CONTENT
    return ncprog.ERROR_SEQUENCE


@dataclass
class _Download:
    sequence: int
    name: str
    pieces: list[bytes] = field(default_factory=list)
    received_bytes: int = 0
    blocks: int = 0
    room: int = 0   # the store's room when the transfer began (the store is checked exactly at its end)
    error: int = 0  # set once the transfer cannot succeed (store full): blocks are then dropped


@dataclass
class _Upload:
    sequence: int
    pieces: list[bytes]
    window: int
    sent: int = 0


class NcTransfers:
    """One connection's NC transfers (one download and one upload at a time, as a client runs them)."""

    def __init__(self, programs: Programs, *, store_bytes: int = DEFAULT_STORE_BYTES,
                 stored: Callable[[], None] | None = None, now: Callable[[], datetime] = datetime.now,
                 peer: str = "", download_window: int = DOWNLOAD_WINDOW) -> None:
        self.programs = programs
        self.store_bytes = store_bytes
        self.download_window = download_window
        self._stored = stored
        self._now = now
        self.peer = peer
        self._sequence = 0
        self._download: _Download | None = None
        self._upload: _Upload | None = None
        self._block_uploads: dict[int, list[bytes]] = {}
        self._upload_id = 0

    def _next_sequence(self) -> int:
        self._sequence = self._sequence % 255 + 1
        return self._sequence

    # ------------------------------------------------------------------ userdata
    def userdata(self, pdu: s7.S7Pdu, pdu_size: int) -> list[s7.S7Pdu]:
        """The PDUs answering one NC programming userdata PDU (none for a download block)."""
        parameter = ncprog.parse_nc_parameter(pdu.parameter)
        data = ncprog.parse_nc_data(pdu.data)
        sub = parameter.subfunction
        if sub == NcSubfunction.REQUEST_DOWNLOAD and parameter.type == ncprog.NC_REQUEST:
            return [self._request_download(pdu.pdu_ref, data.payload)]
        if parameter.type == ncprog.NC_REQUEST and sub in (NcSubfunction.DOWNLOAD_BLOCK, NcSubfunction.CONTINUE_UPLOAD):
            # pushes sent as requests: a request is always answered, and these are not requests
            return [self._answer(pdu.pdu_ref, sub, parameter.sequence, error=ncprog.ERROR_SEQUENCE)]
        if sub == NcSubfunction.DOWNLOAD_BLOCK:
            return self._download_block(pdu.pdu_ref, parameter, data.payload)
        if sub == NcSubfunction.DOWNLOAD_ENDED and parameter.type == ncprog.NC_REQUEST:
            return [self._download_ended(pdu.pdu_ref, parameter)]
        if sub == NcSubfunction.START_UPLOAD and parameter.type == ncprog.NC_REQUEST:
            return self._start_upload(pdu.pdu_ref, data.payload, pdu_size)
        if sub == NcSubfunction.CONTINUE_UPLOAD:
            return self._continue_upload(pdu.pdu_ref, parameter)
        if parameter.type == ncprog.NC_REQUEST:
            return [self._answer(pdu.pdu_ref, sub, parameter.sequence, error=ncprog.ERROR_SEQUENCE)]
        log.debug("NC programming %s from %s ignored", ncprog.describe(parameter), self.peer)
        return []

    @staticmethod
    def _answer(pdu_ref: int, sub: int, sequence: int, payload: bytes = b"", *, error: int = 0,
                kind: int = ncprog.NC_RESPONSE, last: bool = True, data_unit_ref: int = 0) -> s7.S7Pdu:
        parameter = ncprog.build_nc_parameter(NcParameter(
            kind, sub, sequence, long=True, data_unit_ref=data_unit_ref,
            last_data_unit=ncprog.LAST_DATA_UNIT if last else ncprog.MORE_DATA_UNITS, error_code=error))
        data = ncprog.ERROR_DATA if error else ncprog.build_nc_data(NcData(payload))
        return s7.S7Pdu(s7.Rosctr.USERDATA, pdu_ref, parameter, data)

    def _request_download(self, pdu_ref: int, payload: bytes) -> s7.S7Pdu:
        sub = NcSubfunction.REQUEST_DOWNLOAD
        if self._download is not None:
            log.info("NC download of %s from %s abandoned by a new one", self._download.name, self.peer)
            self._download = None
        try:
            name = ncprog.parse_name(payload)
            program_path(name)
        except (NckProtocolError, NckPiBadArguments) as exc:
            log.info("NC download from %s refused: %s", self.peer, exc)
            return self._answer(pdu_ref, sub, 0, error=ncprog.ERROR_NOT_A_FILE_NAME)
        sequence = self._next_sequence()
        self._download = _Download(sequence, name, room=self.store_bytes - self.programs.stored_bytes())
        log.info("NC download of %s from %s begins (sequence %d)", name, self.peer, sequence)
        return self._answer(pdu_ref, sub, sequence, ncprog.build_window(ncprog.Window(self.download_window)))

    def _download_block(self, pdu_ref: int, parameter: NcParameter, payload: bytes) -> list[s7.S7Pdu]:
        download = self._download
        if download is None or parameter.sequence != download.sequence:
            log.debug("NC download block with sequence %d from %s belongs to no transfer", parameter.sequence,
                     self.peer)
            return []
        chunk = ncprog.parse_chunk(payload)
        download.blocks += 1
        download.received_bytes += len(chunk)
        # The content's header and $PATH line come on top of the text: allow them beyond the store's room.
        if not download.error and download.received_bytes > download.room + 1024:
            download.error = ncprog.ERROR_STORE_FULL
            download.pieces.clear()
        if not download.error:
            download.pieces.append(chunk)
        if parameter.is_last or download.blocks % self.download_window:
            return []
        return [self._answer(pdu_ref, NcSubfunction.CONTINUE_DOWNLOAD, download.sequence,
                             ncprog.build_window(ncprog.Window(self.download_window)), kind=ncprog.NC_PUSH)]

    def _download_ended(self, pdu_ref: int, parameter: NcParameter) -> s7.S7Pdu:
        sub = NcSubfunction.DOWNLOAD_ENDED
        download = self._download
        if download is None or parameter.sequence != download.sequence:
            return self._answer(pdu_ref, sub, parameter.sequence, error=ncprog.ERROR_SEQUENCE)
        self._download = None
        error = download.error or self._store(download)
        if error:
            log.info("NC download of %s from %s refused: error 0x%04X", download.name, self.peer, error)
            return self._answer(pdu_ref, sub, download.sequence, error=error)
        return self._answer(pdu_ref, sub, download.sequence, b"\x00\x00")

    def _store(self, download: _Download) -> int:
        """Write the downloaded program whole; 0, or the error code of why not."""
        try:
            content = ncprog.parse_transfer_content(b"".join(download.pieces))
            name = download.name
            path = program_path(name if name.startswith("/") else f"{content.path.rstrip('/')}/{name}")
            old = len(self.programs.texts.get(path, b""))
            if self.programs.stored_bytes() - old + len(content.text) > self.store_bytes:
                return ncprog.ERROR_STORE_FULL
            self.programs.write(path, content.text)
        except NckError as exc:
            log.info("NC download of %s from %s: %s", download.name, self.peer, exc)
            return _error_for(exc)
        if content.stamp.strip():
            self.programs.stamps[path] = content.stamp
        log.info("NC program %s stored (%d bytes) from %s", path, len(content.text), self.peer)
        if self._stored is not None:
            self._stored()
        return 0

    def content(self, name: str) -> bytes:
        """The transfer content an upload of ``name`` sends: a program, or a directory listing."""
        path, is_directory = self.programs.transfer_path(name)
        if is_directory:
            if not self.programs.is_directory(path):
                raise NckNoSuchFile(f"no directory {path}")
            lines = []
            for child in self.programs.children(path):
                leaf = child.rsplit("/", 1)[-1]
                size = len(self.programs.texts.get(child, b""))
                lines.append(LISTING_LINE.format(name=leaf, size=size))
            return ncprog.build_transfer_content(ncprog.TransferContent(
                path, "".join(lines).encode("ascii"), self._stamp(), length=None))
        text = self.programs.read(path)
        directory = path.rsplit("/", 1)[0]
        stamp = self.programs.stamps.get(path) or self._stamp()
        return ncprog.build_transfer_content(ncprog.TransferContent(directory, text, stamp))

    def _stamp(self) -> str:
        return ncprog.stamp_at(self._now())

    def _start_upload(self, pdu_ref: int, payload: bytes, pdu_size: int) -> list[s7.S7Pdu]:
        sub = NcSubfunction.START_UPLOAD
        try:
            request = ncprog.parse_start_upload(payload)
            content = self.content(request.name)
        except NckError as exc:
            log.info("NC upload from %s refused: %s", self.peer, exc)
            return [self._answer(pdu_ref, sub, 0, error=_error_for(exc))]
        pieces = ncprog.split_content(content, pdu_size - ncprog.BLOCK_OVERHEAD)
        sequence = self._next_sequence()
        upload = _Upload(sequence, pieces, max(1, request.window))
        first = pieces[0]
        upload.sent = 1
        answers = [self._answer(pdu_ref, sub, sequence, ncprog.build_chunk(first), last=len(pieces) == 1,
                                data_unit_ref=1)]
        if len(pieces) > 1:
            self._upload = upload
            answers += self._pushes(pdu_ref, upload)
        log.info("NC upload of %s to %s: %d bytes in %d pieces", request.name, self.peer, len(content), len(pieces))
        return answers

    def _pushes(self, pdu_ref: int, upload: _Upload) -> list[s7.S7Pdu]:
        out = []
        for _ in range(upload.window):
            if upload.sent >= len(upload.pieces):
                break
            piece = upload.pieces[upload.sent]
            upload.sent += 1
            out.append(self._answer(pdu_ref, NcSubfunction.UPLOAD, upload.sequence, ncprog.build_chunk(piece),
                                    kind=ncprog.NC_PUSH, last=upload.sent == len(upload.pieces),
                                    data_unit_ref=upload.sent & 0xFF))
        if upload.sent >= len(upload.pieces):
            self._upload = None
        return out

    def _continue_upload(self, pdu_ref: int, parameter: NcParameter) -> list[s7.S7Pdu]:
        upload = self._upload
        if upload is None or parameter.sequence != upload.sequence:
            return []
        return self._pushes(pdu_ref, upload)

    # ------------------------------------------------------------------ PLC-block path
    def block_job(self, pdu: s7.S7Pdu, pdu_size: int) -> s7.S7Pdu | None:
        """The answer to a 0x1D/0x1E/0x1F job about an NC file; None for anything else (a PLC block)."""
        try:
            control = blocks.parse_block_control(pdu.parameter)
        except NckProtocolError:
            return None  # not one of ours: answered as any block job the emulator does not serve
        if control.function == blocks.START_UPLOAD:
            name = control.file_name or ""
            if not ncprog.is_nc_file_name(name):
                return None
            content = self.content(name)  # raises the NckError the session answers
            self._upload_id = self._upload_id % 0xFFFFFFFF + 1
            pieces = ncprog.split_content(content, pdu_size - _BLOCK_ROOM)
            if len(self._block_uploads) >= 4:  # uploads a client never ended: keep a few
                self._block_uploads.pop(next(iter(self._block_uploads)))
            self._block_uploads[self._upload_id] = pieces
            parameter = blocks.build_block_control(blocks.BlockControl(
                blocks.START_UPLOAD, 0, 0, self._upload_id, f"{len(content):07d}"))
            return s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref, parameter)
        pieces = self._block_uploads.get(control.session)
        if pieces is None:
            return None
        if control.function == blocks.UPLOAD:
            piece = pieces.pop(0) if pieces else b""
            more = 1 if pieces else 0
            return s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref, bytes([blocks.UPLOAD, more]),
                            ncprog.build_upload_data(ncprog.UploadData(piece)))
        if control.function == blocks.END_UPLOAD:
            del self._block_uploads[control.session]
            return s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref, bytes([blocks.END_UPLOAD]))
        return None
