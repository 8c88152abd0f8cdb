"""Jobs to datastore calls: read var, write var, PI service, SZL read.

The dispatcher decodes job parameters with ``protocol/``, calls the NCK model or the PLC memory
with typed addresses and Python values, and encodes the answer. Item errors stay per item: one bad
item never spoils the others. Anything else a job raises is the session's business (it answers
with a header error).
"""

from __future__ import annotations

import logging
import weakref
from collections.abc import Callable

from nckemu.emulator.faces.s7.datastore import NckDatastore, PlcDatastore
from nckemu.emulator.faces.s7.nc_transfer import DEFAULT_STORE_BYTES, DOWNLOAD_WINDOW, NcTransfers
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.emulator.machine.nck.programs import Programs
from nckemu.errors import (
    HeaderError,
    NckAddressOutOfRange,
    NckError,
    NckItemError,
    NckObjectDoesNotExist,
    NckServiceError,
    NckTypeInconsistent,
    ReturnCode,
)
from nckemu.protocol import cotp, pi, s7, szl, tpkt
from nckemu.protocol.addresses import (
    BIG_ENDIAN_AREAS,
    NCK_SYNTAX_IDS,
    NckAddress,
    S7AnyAddress,
    S7Area,
    S7TransportSize,
)
from nckemu.protocol.values import NCK_TRANSPORT_SIZE, decode_nck_values, encode_nck_values

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.dispatch")

# Plain ints on the hot path (an IntEnum member costs more to compare and to pack).
RC_SUCCESS = int(ReturnCode.SUCCESS)
RC_HARDWARE_ERROR = int(ReturnCode.HARDWARE_ERROR)
RC_OBJECT_DOES_NOT_EXIST = int(ReturnCode.OBJECT_DOES_NOT_EXIST)
# Read jobs by parameter bytes: clients poll the same items; the parsed request is immutable.
MAX_CACHED_READ_REQUESTS = 1024

# Data-item transport sizes of answers to S7ANY reads (the length counts bits for 0x03/0x04/0x05),
# as C snap7's PerformFunctionRead answers them: BIT 0x03; BYTE, WORD, DWORD 0x04; INT and DINT 0x05;
# REAL 0x07; CHAR, TIMER, COUNTER 0x09 (notes/catalogue.md 5 (e); no capture of a real CPU found).
DATA_TS_BIT = 0x03
DATA_TS_BYTE_WORD_DWORD = 0x04
DATA_TS_INTEGER = 0x05
DATA_TS_REAL = 0x07
DATA_TS_OCTET_STRING = 0x09
# Userdata groups and subfunctions we do not serve: a userdata answer with this error in its parameter
# and data 0A 00 00 00 (the form C snap7 gives unavailable SZLs and tshark decodes; what a real CPU
# answers for an unserved group was not found: the machine's settings.userdata_not_served_error).
USERDATA_NOT_SERVED = 0x8104
# PI services that change retained data (the program store): answered once it is saved, as a write.
RETAINED_PI_SERVICES = frozenset({"_N_F_DELE"})

_ELEMENT_BYTES: dict[int, int] = {
    S7TransportSize.BYTE: 1, S7TransportSize.CHAR: 1, S7TransportSize.WORD: 2,
    S7TransportSize.INT: 2, S7TransportSize.DWORD: 4, S7TransportSize.DINT: 4,
    S7TransportSize.REAL: 4, S7TransportSize.COUNTER: 2, S7TransportSize.TIMER: 2,
}
_ANSWER_TRANSPORT_SIZE: dict[int, int] = {
    S7TransportSize.BYTE: DATA_TS_BYTE_WORD_DWORD, S7TransportSize.CHAR: DATA_TS_OCTET_STRING,
    S7TransportSize.WORD: DATA_TS_BYTE_WORD_DWORD, S7TransportSize.DWORD: DATA_TS_BYTE_WORD_DWORD,
    S7TransportSize.INT: DATA_TS_INTEGER, S7TransportSize.DINT: DATA_TS_INTEGER,
    S7TransportSize.REAL: DATA_TS_REAL, S7TransportSize.COUNTER: DATA_TS_OCTET_STRING,
    S7TransportSize.TIMER: DATA_TS_OCTET_STRING,
}


PlanPart = tuple[bytes, Callable[[], bytes], int, bytes]  # data item header, value reader, size, fill
# A read job's answer as a whole frame (TPKT, COTP DT, S7 PDU), given the job's PDU reference as its
# two bytes on the wire and the connection's access context.
FramedAnswer = Callable[[bytes, AccessContext], bytes]
# A frame holding one read job, known by its bytes from 13 on: with bytes 0..10 they fix every byte
# but the PDU reference (11 and 12). Bytes 0..10 and the job's answer.
FramedRead = tuple[bytes, FramedAnswer]
FRAME_PDU_OFFSET = cotp.DATA_FRAME_PDU_OFFSET
FRAME_PDU_REF_END = FRAME_PDU_OFFSET + 6
_FRAME_HEAD_BYTES = FRAME_PDU_OFFSET + 4


def _planned_answer(item_count: int, parts: list[PlanPart], general: FramedAnswer) -> FramedAnswer:
    """The answer frame to a read job of byte-sized S7ANY items (``Dispatcher._plan_read``): TPKT,
    DT and ACK_DATA header with the PDU reference put in, then per item its header, value and fill
    byte. A value that cannot be read (or has another size) sends the job the general way."""
    data_length = sum(len(header) + size + len(fill) for header, _read, size, fill in parts)
    # The answer with zeros for the PDU reference and the data items: all of it up to them is fixed.
    blank = cotp.build_data_frame(s7.build_read_var_answer(0, item_count, bytes(data_length)))
    before = blank[:_FRAME_HEAD_BYTES]
    after = blank[FRAME_PDU_REF_END:FRAME_PDU_OFFSET + s7.READ_ANSWER_DATA_OFFSET]
    if len(parts) == 1:
        ((header, read, size, _fill),) = parts
        after += header

        def answer_one(pdu_ref: bytes, ctx: AccessContext) -> bytes:
            try:
                value = read()
            except Exception:  # noqa: BLE001 - the general path gives the item its error
                return general(pdu_ref, ctx)
            if len(value) != size:
                return general(pdu_ref, ctx)
            return b"".join((before, pdu_ref, after, value))

        return answer_one

    def answer(pdu_ref: bytes, ctx: AccessContext) -> bytes:
        out = [before, pdu_ref, after]
        try:
            for header, read, size, fill in parts:
                value = read()
                if len(value) != size:
                    return general(pdu_ref, ctx)
                out += (header, value, fill)
        except Exception:  # noqa: BLE001 - the general path gives the item its error
            return general(pdu_ref, ctx)
        return b"".join(out)

    return answer


def _error_item(return_code: int) -> s7.DataItem:
    return s7.DataItem(return_code, 0x00, b"")


_BY_MACHINE: weakref.WeakKeyDictionary[Emulator, Dispatcher] = weakref.WeakKeyDictionary()


class Dispatcher:
    """Turns S7 jobs into calls on the NCK model and the PLC memory."""

    def __init__(self, nck: NckDatastore, plc: PlcDatastore, *,
                 persist: Callable[[], None] | None = None,
                 default_access_level: int = 7,
                 userdata_not_served_error: int = USERDATA_NOT_SERVED,
                 unsupported_function_error: int = HeaderError.NOT_IMPLEMENTED,
                 drive_transport_size: int = NCK_TRANSPORT_SIZE,
                 programs: Programs | None = None, program_store_bytes: int = DEFAULT_STORE_BYTES,
                 nc_download_window: int = DOWNLOAD_WINDOW) -> None:
        self.nck = nck
        # The program store NC transfers read and write (None: the NC programming group is not served).
        self.programs = programs
        self.program_store_bytes = program_store_bytes
        self.nc_download_window = nc_download_window
        # The transport size of answers from the drive areas V and H (the machine's [drives]
        # answer_transport_size: 0x09 as all NCK answers, or 0x07 REAL; docs/assumptions.md).
        self.drive_transport_size = drive_transport_size
        self._answer_ts_by_area = tuple(drive_transport_size if area in BIG_ENDIAN_AREAS else NCK_TRANSPORT_SIZE
                                        for area in range(8))
        self.plc = plc
        self.userdata_not_served_error = userdata_not_served_error
        # The session answers a job this dispatcher returns None for with an ACK carrying this error.
        self.unsupported_function_error = unsupported_function_error
        self._persist = persist
        # Set by a server that holds its answers until a save ends (machine/saves.py): a write of
        # retained data then only asks for the save, and the server sends the answer after it.
        self.persist_later: Callable[[], None] | None = None
        self.default_access_level = default_access_level
        self._read_requests: dict[bytes, s7.ReadVarRequest] = {}
        # Read jobs by parameter bytes -> the function answering them (see ``_plan_read``).
        self._read_plans: dict[bytes, FramedAnswer] = {}
        # Polled read jobs by frame (``framed_read``): the session answers them without parsing.
        self.framed_reads: dict[bytes, FramedRead] = {}
        self._plc_reader = plc.reader

    @classmethod
    def for_machine(cls, emulator: Emulator) -> Dispatcher:
        """The machine's dispatcher: one per machine, shared by its connections (the read plans and the
        parsed requests it keeps serve every client polling the same items)."""
        dispatcher = _BY_MACHINE.get(emulator)
        if dispatcher is None:
            settings = emulator.machine.settings
            dispatcher = cls(emulator.nck, emulator.plc, persist=emulator.persist,
                             default_access_level=emulator.default_access_level,
                             userdata_not_served_error=settings.userdata_not_served_error,
                             unsupported_function_error=settings.unsupported_function_error,
                             drive_transport_size=emulator.machine.drive_settings.answer_transport_size,
                             programs=emulator.nck.programs,
                             program_store_bytes=settings.program_store_bytes,
                             nc_download_window=settings.nc_download_window)
            _BY_MACHINE[emulator] = dispatcher
        return dispatcher

    def new_access_context(self, peer: str) -> AccessContext:
        return AccessContext(level=self.default_access_level, client=peer)

    # ------------------------------------------------------------------ jobs
    def job(self, pdu: s7.S7Pdu, ctx: AccessContext) -> s7.S7Pdu | None:
        function = pdu.parameter[0]
        if function == s7.Function.READ_VAR:
            parameter, data = s7.build_read_var_response(self.read_var(self._read_request(pdu.parameter), ctx))
        elif function == s7.Function.WRITE_VAR:
            write = s7.parse_write_var_request(pdu.parameter, pdu.data)
            parameter, data = s7.build_write_var_response(self.write_var(write, ctx))
        elif function == s7.Function.PI_SERVICE:
            parameter, data = self.pi_service(pi.parse_pi_request(pdu.parameter), ctx), b""
        elif function == s7.Function.PLC_STOP:
            pi.parse_plc_stop_request(pdu.parameter)
            self._plc_control("stop")
            parameter, data = bytes([s7.Function.PLC_STOP]), b""
        else:
            return None
        return s7.S7Pdu(s7.Rosctr.ACK_DATA, pdu.pdu_ref, parameter, data)

    def _read_request(self, parameter: bytes) -> s7.ReadVarRequest:
        request = self._read_requests.get(parameter)
        if request is None:
            request = s7.parse_read_var_request(parameter)
            if len(self._read_requests) < MAX_CACHED_READ_REQUESTS:
                self._read_requests[parameter] = request
        return request

    def read_answer(self, pdu_ref: int, parameter: bytes, ctx: AccessContext) -> bytes:
        """The whole ACK_DATA PDU answering a read-var job: what ``job`` answers, without the S7Pdu
        objects on the way (clients poll; this is most of the traffic). Raises as ``job`` does."""
        plan = self._read_plans.get(parameter)
        if plan is None:
            plan = self._plan_read(parameter)
        return plan(pdu_ref.to_bytes(2, "big"), ctx)[FRAME_PDU_OFFSET:]

    def framed_read(self, frame: bytes) -> FramedRead | None:
        """For a frame that is one read-var job in one DT (EOT): its bytes 0..10 and the function
        answering it with a whole frame; None for any other frame, and for jobs whose parameters do
        not parse (the general path answers those). Kept in ``framed_reads`` by the frame's bytes
        from 13 on, where a polled job finds it again."""
        if len(frame) <= FRAME_PDU_OFFSET or frame[0] != tpkt.TPKT_VERSION \
                or (frame[2] << 8 | frame[3]) != len(frame) or frame[4:FRAME_PDU_OFFSET] != cotp.DT_HEADER_EOT:
            return None
        job = s7.peek_read_var_job(frame, FRAME_PDU_OFFSET)
        if job is None:
            return None
        plan = self._read_plans.get(job[1])
        if plan is None:
            try:
                plan = self._plan_read(job[1])
            except Exception:  # noqa: BLE001 - the general path answers it with its error
                return None
        entry = (frame[:_FRAME_HEAD_BYTES], plan)
        if len(self.framed_reads) < MAX_CACHED_READ_REQUESTS:
            self.framed_reads[frame[FRAME_PDU_REF_END:]] = entry
        return entry

    def _plan_read(self, parameter: bytes) -> FramedAnswer:
        """The function answering the read job with these parameter bytes (raises as ``job`` does
        for parameters that do not parse). Where every item is a byte-sized S7ANY read, the answer
        but for the PDU reference and the values is known before the values are: it is built once,
        each job joins the values in (the PLC's ``reader`` gives each item's value). Anything else,
        and any exception on the way, goes the general way (which also gives item errors)."""
        request = self._read_request(parameter)
        item_count = len(request.items)

        read_item, build_data_items, build_answer = self._read_item, s7.build_data_items, s7.build_read_var_answer
        build_frame = cotp.build_data_frame
        items = request.items

        def general(pdu_ref: bytes, ctx: AccessContext) -> bytes:
            # ``read_var`` and ``build_read_var_response`` without the response objects.
            ref = pdu_ref[0] << 8 | pdu_ref[1]
            if item_count == 1:
                return build_frame(build_answer(ref, 1, build_data_items((read_item(items[0], ctx),))))
            return build_frame(build_answer(ref, item_count,
                                            build_data_items(tuple(read_item(item, ctx) for item in items))))

        if len(self._read_plans) >= MAX_CACHED_READ_REQUESTS:
            return general
        plan: FramedAnswer = general
        parts = self._s7any_plan_parts(request.items)
        if parts is not None:
            plan = _planned_answer(item_count, parts, general)
        self._read_plans[parameter] = plan
        return plan

    def _s7any_plan_parts(self, items: tuple[object, ...]) -> list[PlanPart] | None:
        """Per item: data item header, value reader, size, fill byte; None unless all are byte-sized
        S7ANY reads whose answers fit in a data item."""
        parts: list[PlanPart] = []
        last = len(items) - 1
        total = 0
        for index, address in enumerate(items):
            if not isinstance(address, S7AnyAddress) or address.transport_size == S7TransportSize.BIT:
                return None
            answer_size = _ANSWER_TRANSPORT_SIZE.get(address.transport_size)
            try:
                size = self._s7any_size(address)
            except NckError:
                return None
            if answer_size is None:
                return None
            length = s7.data_item_length_field(s7.DataItem(RC_SUCCESS, answer_size, bytes(size)))
            if length > 0xFFFF:
                return None
            header = s7.DATA_ITEM_HEADER.build({"return_code": RC_SUCCESS, "transport_size": answer_size,
                                                "length": length})
            fill = b"\x00" if index < last and size % 2 else b""
            total += len(header) + size + len(fill)
            if total > 0xFFFF:
                return None  # no S7 PDU carries it: the general path fails it as ``job`` does
            parts.append((header, self._plc_reader(address.area, address.db_number, address.byte_address, size),
                           size, fill))
        return parts

    def read_var(self, request: s7.ReadVarRequest, ctx: AccessContext) -> s7.ReadVarResponse:
        return s7.ReadVarResponse(tuple(self._read_item(item, ctx) for item in request.items))

    def write_var(self, request: s7.WriteVarRequest, ctx: AccessContext) -> s7.WriteVarResponse:
        codes: list[int] = []
        any_changed = False
        for address, value in zip(request.items, request.values, strict=True):
            code, changed = self._write_item(address, value, ctx)
            codes.append(code)
            any_changed = any_changed or changed
        if any_changed:
            self.retained_changed()
        return s7.WriteVarResponse(tuple(codes))

    def retained_changed(self) -> None:
        """Retained data changed (a write job, or a program transfer that ended): durability before
        acknowledgement, the answer leaves only after the state is on disk."""
        if self.persist_later is not None:
            self.persist_later()
        elif self._persist is not None:
            self._persist()

    def new_nc_transfers(self, peer: str) -> NcTransfers | None:
        """A connection's NC transfer state (None when this dispatcher has no program store)."""
        if self.programs is None:
            return None
        return NcTransfers(self.programs, store_bytes=self.program_store_bytes, stored=self.retained_changed,
                           now=self.plc.now, peer=peer, download_window=self.nc_download_window)

    def pi_service(self, request: pi.PiServiceRequest, ctx: AccessContext) -> bytes:
        service = request.service
        if service.startswith("_N_"):
            self.nck.pi_service(service, request.arguments, ctx)
            if service in RETAINED_PI_SERVICES:
                self.retained_changed()
        elif service == "P_PROGRAM":
            self._plc_control("start")
        else:
            raise NckServiceError(f"PI service {service!r} is not supported")
        return pi.build_pi_response(pi.PiServiceResponse())

    def _plc_control(self, action: str) -> None:
        self.plc.plc_control(action)

    # ------------------------------------------------------------------ userdata
    def userdata(self, pdu: s7.S7Pdu, ctx: AccessContext) -> s7.S7Pdu | None:
        """Read SZL, list blocks, read clock; any other group or subfunction gets a userdata answer
        with ``userdata_not_served_error`` in its parameter (a parameter that does not parse raises,
        and the session answers 0x8500 as for any job)."""
        request = szl.parse_userdata_request(pdu.parameter, pdu.data)
        service = (request.group, request.subfunction)
        if service == (szl.GROUP_CPU_FUNCTIONS, szl.SUBFUNCTION_READ_SZL):
            szl_request = szl.szl_request_of(request)
            try:
                records = self.plc.szl(szl_request.szl_id, szl_request.szl_index)
            except NckError as exc:
                log.info("SZL 0x%04X/0x%04X refused: %s", szl_request.szl_id, szl_request.szl_index, exc)
                parameter, data = szl.build_userdata_error_response(request, exc.header_error)
            else:
                parameter, data = szl.build_szl_response(szl_request, records)
        elif service == (szl.GROUP_BLOCK_FUNCTIONS, szl.SUBFUNCTION_LIST_BLOCKS):
            parameter, data = szl.build_userdata_response(request, szl.build_block_counts(self.plc.block_counts()))
        elif service == (szl.GROUP_TIME_FUNCTIONS, szl.SUBFUNCTION_READ_CLOCK):
            parameter, data = szl.build_userdata_response(request, szl.build_clock(self.plc.now()))
        else:
            log.info("userdata group %d subfunction %d not served", request.group, request.subfunction)
            parameter, data = szl.build_userdata_error_response(request, self.userdata_not_served_error)
        return s7.S7Pdu(s7.Rosctr.USERDATA, pdu.pdu_ref, parameter, data)

    # ------------------------------------------------------------------ items
    def _read_item(self, address: object, ctx: AccessContext) -> s7.DataItem:
        try:
            if isinstance(address, NckAddress):
                return self._read_nck(address, ctx)
            if isinstance(address, S7AnyAddress):
                return self._read_s7any(address)
            # UnsupportedAddress (syntax IDs we do not serve) and anything else
            return _error_item(RC_OBJECT_DOES_NOT_EXIST)
        except NckItemError as exc:
            return _error_item(exc.return_code or RC_HARDWARE_ERROR)
        except Exception:
            log.exception("read of %s failed inside the emulator", address)
            return _error_item(RC_HARDWARE_ERROR)

    def _write_item(self, address: object, value: s7.DataItem, ctx: AccessContext) -> tuple[int, bool]:
        try:
            if isinstance(address, NckAddress):
                return RC_SUCCESS, self._write_nck(address, value, ctx)
            if isinstance(address, S7AnyAddress):
                self._write_s7any(address, value)
                return RC_SUCCESS, False
            return RC_OBJECT_DOES_NOT_EXIST, False
        except NckItemError as exc:
            return exc.return_code or RC_HARDWARE_ERROR, False
        except Exception:
            log.exception("write of %s failed inside the emulator", address)
            return RC_HARDWARE_ERROR, False

    def _read_nck(self, address: NckAddress, ctx: AccessContext) -> s7.DataItem:
        if address.syntax_id not in NCK_SYNTAX_IDS:
            raise NckObjectDoesNotExist(f"syntax ID 0x{address.syntax_id:02X}")
        nck_type, string_length, values = self.nck.read_typed(address, ctx)
        data = encode_nck_values(nck_type, values, area=address.area, string_length=string_length, answer=True)
        return s7.DataItem(RC_SUCCESS, self._answer_ts_by_area[address.area], data)

    def _write_nck(self, address: NckAddress, value: s7.DataItem, ctx: AccessContext) -> bool:
        if address.syntax_id not in NCK_SYNTAX_IDS:
            raise NckObjectDoesNotExist(f"syntax ID 0x{address.syntax_id:02X}")
        nck_type, string_length = self.nck.variable_type(address)
        values = decode_nck_values(nck_type, value.data, area=address.area,
                                   line_count=address.line_count, string_length=string_length)
        return bool(self.nck.write(address, values, ctx))

    @staticmethod
    def _s7any_size(address: S7AnyAddress) -> int:
        if address.transport_size == S7TransportSize.BIT:
            if address.count != 1:
                raise NckAddressOutOfRange("a BIT item addresses exactly one bit")
            return 1
        element = _ELEMENT_BYTES.get(address.transport_size)
        if element is None:
            raise NckTypeInconsistent(f"transport size 0x{address.transport_size:02X}")
        return element * address.count

    def _read_s7any(self, address: S7AnyAddress) -> s7.DataItem:
        size = self._s7any_size(address)
        if address.transport_size == S7TransportSize.BIT:
            bit = self.plc.read_bit(address.area, address.db_number, address.byte_address, address.bit_address)
            return s7.DataItem(RC_SUCCESS, DATA_TS_BIT, b"\x01" if bit else b"\x00")
        data = self.plc.read(address.area, address.db_number, address.byte_address, size)
        return s7.DataItem(RC_SUCCESS, _ANSWER_TRANSPORT_SIZE[address.transport_size], data)

    def _write_s7any(self, address: S7AnyAddress, value: s7.DataItem) -> None:
        size = self._s7any_size(address)
        if len(value.data) != size:
            raise NckTypeInconsistent(f"{len(value.data)} bytes written to an item of {size}")
        if address.transport_size == S7TransportSize.BIT:
            self.plc.write_bit(address.area, address.db_number, address.byte_address, address.bit_address,
                               bool(value.data[0] & 1))
            return
        self.plc.write(address.area, address.db_number, address.byte_address, value.data)


__all__ = ["Dispatcher", "S7Area"]
