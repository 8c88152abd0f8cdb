"""PLC memory for ordinary S7ANY clients: DBs, inputs, outputs, flags, peripheral inputs, SZL.

Peripheral input words wired to machine sensors (e.g. PIW 420) return the sensor temperature
through the sensor's analog scaling. A write that sets the DB41 request bit runs the 840C command
channel at once.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Callable
from datetime import datetime, timedelta
from typing import Any

from nckemu.emulator.machine.clock import Clock, MonotonicClock
from nckemu.emulator.machine.machine_file import PLC_AREA_BYTES
from nckemu.emulator.machine.plc.channel_signals import ChannelSignals
from nckemu.errors import NckAddressOutOfRange, NckError, NckObjectDoesNotExist, NckServiceError
from nckemu.protocol import c840, db41, szl
from nckemu.protocol.addresses import S7Area

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.plc.memory")

_SENSOR_WORD = struct.Struct(">h")

ORDER_NUMBER = "6FC5372-0AA30-0AA0"  # NCU 720.3 PN; the PLC part answers as the NCU
HARDWARE_VERSION = 3
FIRMWARE_VERSION = (3, 2, 6)  # of the PLC part (a CPU 317-2 PN/DP); not a measured value
MODULE_NAME = "nckemu NCU"
# SZL 0x001C (component identification): index -> the width of its text; the rest of the 32-byte text
# field is reserved and stays zero (python-snap7's get_cpu_info reads the name and the serial number
# 24 bytes wide).
COMPONENT_TEXT_BYTES = {1: 24, 2: 24, 3: 32, 4: 26, 5: 24, 7: 32, 8: 32, 9: 32, 10: 32}
COPYRIGHT = "Original Siemens Equipment"
MODULE_TYPE_NAME = "CPU 317-2 PN/DP (NCU PLC)"
# SZL 0x0424 record: event ID 0x5144, "ae" 0xFF, then the mode (0x08 RUN, 0x03 STOP), as the record
# C snap7 took "from a physical CPU" (s7_firmware.h SZL_ID_0424_IDX_XXXX, node-snap7 1.0.9); bytes
# 12..19 are the time of the last mode change as an S7 DATE_AND_TIME (same source).
SZL_0424_EVENT_ID = 0x5144
# SZL 0x0131 index 1 (communication): MPI and K-bus rates in bit/s as the same physical CPU's record
# (s7_firmware.h SZL_ID_0131_IDX_0001); max connections 16 is that CPU's value (snap7 exposes 1024).
MAX_CONNECTIONS = 16
MPI_RATE_BPS = 12_000_000
KBUS_RATE_BPS = 187_500
# SZL 0x0232 index 4 (protection): key-switch level 1, no password level, effective level 1, mode
# switch position 2 (RUN-P), as the physical CPU's record (s7_firmware.h SZL_ID_0232_IDX_0004).
PROTECTION = (1, 0, 1, 2, 0)


def _text(value: str, size: int) -> bytes:
    # A name from a fleet file may hold any letter; the SZL's texts are ASCII.
    return value.encode("ascii", "replace")[:size].ljust(size, b"\x00")


class PlcModel:
    """The PLC part of the emulated NCU."""

    def __init__(self, machine: Any = None, nck: Any = None, *,
                 data_blocks: dict[int, int] | None = None, layout: c840.C840Layout | None = None,
                 clock: Clock | None = None,
                 identity: Callable[[], tuple[str, str]] = lambda: ("nckemu", "")) -> None:
        self.machine = machine
        self.nck = nck
        self.layout = layout or c840.C840Layout()
        settings = getattr(machine, "settings", None)
        self.szl_unknown_id_error = getattr(settings, "szl_unknown_id_error", szl.ERROR_SZL_NOT_AVAILABLE)
        self.szl_unknown_index_error = getattr(settings, "szl_unknown_index_error", szl.ERROR_SZL_INVALID_INDEX)
        self.szl_index0_python_snap7 = getattr(settings, "szl_index0_python_snap7", True)
        self.c840_refuse_p0_at_zero = getattr(settings, "c840_refuse_p0_at_zero", False)
        self.pdu_size_max = int(getattr(machine, "pdu_size_max", 960))
        # The PLC's clock: the wall time at start, advanced by the emulator's clock (a simulated clock
        # moves it as it moves everything else).
        self.clock = clock or MonotonicClock()
        self._clock_epoch = datetime.now() - timedelta(seconds=self.clock.now_s())
        self._mode_changed = self.now()
        blocks = data_blocks if data_blocks is not None else (
            dict(getattr(machine, "data_blocks", {})) if machine is not None else {41: 64, 100: 256})
        blocks.setdefault(db41.CHANNEL_DB, 64)
        self.data_blocks: dict[int, bytearray] = {number: bytearray(size) for number, size in blocks.items()}
        self.areas: dict[int, bytearray] = {area: bytearray(PLC_AREA_BYTES)
                                            for area in (S7Area.I, S7Area.Q, S7Area.M)}
        self.running = True
        # The machine's name and serial number as every face shows them (SZL 0x001C): the emulator
        # gives its own name (a fleet's machine's name) and MD18030.
        self.identity = identity
        # Told of every write (area, DB number, first byte, byte count) after it landed: the OPC UA face
        # pushes each change to its subscriptions instead of hoping a periodic sample catches it.
        self.write_listeners: list[Callable[[int, int, int, int], None]] = []
        self._sensor_inputs: dict[int, Any] = {}
        for sensor in getattr(machine, "sensors", ()) if machine is not None else ():
            if sensor.plc_input:
                self._sensor_inputs[int(sensor.plc_input[3:])] = sensor
        # NC start/stop/reset and mode requests in DB21../DB11, the channels' state back (channel_signals.py).
        self.channel_signals = ChannelSignals(self.data_blocks, nck.channels, self._tell_written) \
            if nck is not None and getattr(nck, "channels", None) else None
        if nck is not None:
            nck.add_power_on_hook(self.power_on)

    # ------------------------------------------------------------------ memory
    def _block(self, area: int, db_number: int) -> bytearray:
        if area in (S7Area.DB, S7Area.DI):
            block = self.data_blocks.get(db_number)
            if block is None:
                raise NckObjectDoesNotExist(f"DB{db_number} does not exist")
            return block
        block = self.areas.get(area)
        if block is None:
            raise NckObjectDoesNotExist(f"area 0x{area:02X} is not served")
        return block

    @staticmethod
    def _check(block: bytearray, start: int, size: int, what: str) -> None:
        if start < 0 or size < 0 or start + size > len(block):
            raise NckAddressOutOfRange(f"{what}: bytes {start}..{start + size - 1} beyond its "
                                       f"{len(block)} bytes")

    def read(self, area: int, db_number: int, start_byte: int, size_bytes: int) -> bytes:
        if area == S7Area.P:
            return self._read_peripheral(start_byte, size_bytes)
        block = self._block(area, db_number)
        self._check(block, start_byte, size_bytes, f"DB{db_number}" if area == S7Area.DB else f"area {area:#x}")
        if area == S7Area.I and self._sensor_inputs:
            # The process image of the inputs holds what the peripheral words read.
            return self._read_peripheral(start_byte, size_bytes)
        return bytes(block[start_byte:start_byte + size_bytes])

    def reader(self, area: int, db_number: int, start_byte: int, size_bytes: int) -> Callable[[], bytes]:
        """A function of no arguments that returns what ``read(area, db_number, start_byte, size_bytes)``
        returns now, or raises (any exception: the caller then reads through ``read`` for the proper
        error). For polled items: the area is decided once, a DB read is a slice of its block, a
        sensor word is the sensor's value packed."""
        end = start_byte + size_bytes
        if area in (S7Area.DB, S7Area.DI) and start_byte >= 0 and size_bytes >= 0:
            blocks = self.data_blocks

            def read_block() -> bytes:
                block = blocks[db_number]
                if end > len(block):  # also where nothing is read, as ``_check``
                    raise NckAddressOutOfRange(f"DB{db_number}: bytes beyond its end")
                return block[start_byte:end]  # a bytearray slice: a copy, as bytes-like as ``read``'s bytes

            return read_block
        sensor = self._sensor_inputs.get(start_byte)
        if size_bytes == 2 and sensor is not None and (area == S7Area.P or area == S7Area.I) \
                and start_byte + 1 not in self._sensor_inputs and end <= len(self.areas[S7Area.I]):
            # A whole sensor word (PIW 420): what ``_read_peripheral`` packs byte by byte.
            raw_value, pack = sensor.raw_value, _SENSOR_WORD.pack
            if self.nck is None:
                return lambda: pack(raw_value(sensor.temperature_C))
            temperature_C = self.nck.sensor_temperature_reader(sensor.name)
            return lambda: pack(raw_value(temperature_C()))
        read = self.read
        return lambda: read(area, db_number, start_byte, size_bytes)

    def write(self, area: int, db_number: int, start_byte: int, data: bytes) -> None:
        if area == S7Area.P:
            area = S7Area.Q  # peripheral outputs: the process image of the outputs
        block = self._block(area, db_number)
        self._check(block, start_byte, len(data), f"DB{db_number}" if area == S7Area.DB else f"area {area:#x}")
        block[start_byte:start_byte + len(data)] = data
        if area == S7Area.DB and db_number == db41.CHANNEL_DB and \
                start_byte <= db41.OFFSET_HANDSHAKE < start_byte + len(data):
            self._run_channel()
        if self.write_listeners:
            if area == S7Area.DI:
                area = S7Area.DB  # one memory: an instance DB is a DB
            for listener in self.write_listeners:
                listener(area, db_number, start_byte, len(data))
        signals = self.channel_signals
        if signals is not None and area in (S7Area.DB, S7Area.DI) and signals.watches(db_number, start_byte, len(data)):
            signals.written(db_number)

    def _tell_written(self, db_number: int, start_byte: int, size: int) -> None:
        for listener in self.write_listeners:
            listener(S7Area.DB, db_number, start_byte, size)

    def read_bit(self, area: int, db_number: int, byte: int, bit: int) -> bool:
        return bool(self.read(area, db_number, byte, 1)[0] >> bit & 1)

    def write_bit(self, area: int, db_number: int, byte: int, bit: int, value: bool) -> None:
        current = self.read(area, db_number, byte, 1)[0]
        updated = (current | (1 << bit)) if value else (current & ~(1 << bit))
        self.write(area, db_number, byte, bytes([updated & 0xFF]))

    def _read_peripheral(self, start_byte: int, size_bytes: int) -> bytes:
        """Peripheral inputs: sensor words where a sensor is wired, the input image elsewhere."""
        out = bytearray()
        for offset in range(start_byte, start_byte + size_bytes):
            base = offset if offset in self._sensor_inputs else offset - 1
            sensor = self._sensor_inputs.get(base)
            if sensor is None:
                self._check(self.areas[S7Area.I], offset, 1, "peripheral inputs")
                out.append(self.areas[S7Area.I][offset])
                continue
            temperature_C = self.nck.sensor_temperature_C(sensor.name) if self.nck is not None \
                else sensor.temperature_C
            out.append(struct.pack(">h", sensor.raw_value(temperature_C))[offset - base])
        return bytes(out)

    # ------------------------------------------------------------------ SZL
    def szl(self, szl_id: int, szl_index: int) -> bytes:
        """The whole SZL: ID, index, record length, record count, records."""
        if szl_id == 0x0011:
            major, minor, patch = FIRMWARE_VERSION
            # Index 7 carries the firmware as 'V', major, minor, patch (python-snap7's get_order_code
            # reads its last three bytes); index 1 carries it packed, major.minor in one byte and the
            # patch in the next, where pys7's get_cpu_info looks. Indexes 1 and 6: hardware version.
            tails = {1: struct.pack(">HHBB", 0, HARDWARE_VERSION, major << 4 | minor, patch),
                     6: struct.pack(">HHH", 0, HARDWARE_VERSION, 0),
                     7: struct.pack(">HBBBB", 0, ord("V"), major, minor, patch)}
            records = [struct.pack(">H", index) + _text(ORDER_NUMBER, 20) + tail for index, tail in tails.items()]
            return self._szl(szl_id, szl_index, 28, records)
        if szl_id == 0x001C:
            # Index 1 names the automation system (the machine among others), 5 is its serial number.
            name, serial_number = self.identity()
            texts = {1: name, 2: MODULE_NAME, 3: "nckemu", 4: COPYRIGHT, 5: serial_number, 7: MODULE_TYPE_NAME,
                     8: "", 9: "", 10: ""}
            records = [struct.pack(">H", index) + _text(text, COMPONENT_TEXT_BYTES[index]).ljust(32, b"\x00")
                       for index, text in texts.items()]
            return self._szl(szl_id, szl_index, 34, records)
        if szl_id == 0x0424:
            mode = 0x08 if self.running else 0x03
            record = struct.pack(">HBB", SZL_0424_EVENT_ID, 0xFF, mode) + bytes(8) \
                + szl.build_clock(self._mode_changed)[6:]
            return self._szl(szl_id, szl_index, 20, [record])
        if szl_id == 0x0131:
            if szl_index == 1:
                record = struct.pack(">HHHII", 1, self.pdu_size_max, MAX_CONNECTIONS, MPI_RATE_BPS, KBUS_RATE_BPS)
                return self._szl(szl_id, szl_index, 40, [record])
            if szl_index == 0 and self.szl_index0_python_snap7:
                # python-snap7 3.3's get_cp_info reads index 0 and takes the four words right after ID
                # and index as max PDU, max connections, MPI and bus rate (in Mbit/s as its own server
                # sends them: 12, 12); no real CPU defines index 0 (notes/catalogue.md 5 (g), (h)).
                return struct.pack(">HHHHHH", szl_id, szl_index, self.pdu_size_max, MAX_CONNECTIONS,
                                   MPI_RATE_BPS // 1_000_000, MPI_RATE_BPS // 1_000_000)
            raise NckServiceError(f"SZL 0x0131 has no index 0x{szl_index:04X}",
                                  error_class=self.szl_unknown_index_error >> 8,
                                  error_code=self.szl_unknown_index_error & 0xFF)
        if szl_id == 0x0232:
            if szl_index == 4:
                record = struct.pack(">6H", 4, *PROTECTION)
                return self._szl(szl_id, szl_index, 40, [record])
            if szl_index == 0 and self.szl_index0_python_snap7:
                # python-snap7 3.3's get_protection reads index 0, five words after ID and index.
                return struct.pack(">7H", szl_id, szl_index, *PROTECTION)
            raise NckServiceError(f"SZL 0x0232 has no index 0x{szl_index:04X}",
                                  error_class=self.szl_unknown_index_error >> 8,
                                  error_code=self.szl_unknown_index_error & 0xFF)
        raise NckServiceError(f"SZL 0x{szl_id:04X} index 0x{szl_index:04X} is not available",
                              error_class=self.szl_unknown_id_error >> 8,
                              error_code=self.szl_unknown_id_error & 0xFF)

    # ------------------------------------------------------------------ userdata: blocks and clock
    def now(self) -> datetime:
        """The PLC's clock (read by userdata group 7, "read clock")."""
        return self._clock_epoch + timedelta(seconds=self.clock.now_s())

    def block_counts(self) -> dict[int, int]:
        """Blocks by type code for "list blocks": the DBs this PLC holds; it has no OB, FC or FB."""
        return {szl.BLOCK_TYPE_DB: len(self.data_blocks)}

    @staticmethod
    def _szl(szl_id: int, szl_index: int, record_length: int, records: list[bytes]) -> bytes:
        body = b"".join(record[:record_length].ljust(record_length, b"\x00") for record in records)
        return struct.pack(">HHHH", szl_id, szl_index, record_length, len(records)) + body

    def plc_control(self, action: str) -> None:
        running = action == "start"
        if running != self.running:
            self._mode_changed = self.now()
        self.running = running
        log.info("PLC %s", "RUN" if self.running else "STOP")

    # ------------------------------------------------------------------ 840C command channel
    def _run_channel(self) -> None:
        channel = self.data_blocks[db41.CHANNEL_DB]
        status = db41.parse_status(bytes(channel[:db41.CHANNEL_BYTES]))
        if not status.request:
            return
        error = self._execute(status)
        handshake = db41.BIT_ERROR if error else db41.BIT_DONE
        channel[db41.OFFSET_HANDSHAKE] = handshake
        channel[db41.OFFSET_ERROR:db41.OFFSET_ERROR + 2] = struct.pack(">H", error)
        if error:
            log.info("840C command channel: function %d refused with error %d", status.function, error)

    def _execute(self, status: db41.ChannelStatus) -> int:
        errors = db41.ChannelError
        if status.function != db41.FUNCTION_TEMPERATURE_COMPENSATION:
            return errors.UNKNOWN_FUNCTION
        block = self.data_blocks.get(status.user_db)
        if block is None:
            return errors.USER_DB_MISSING
        start = 2 * status.data_word
        data = bytes(block[start:start + c840.USER_DB_BYTES])
        if len(data) < c840.USER_DB_BYTES:
            return errors.USER_DB_TOO_SHORT
        try:
            user = c840.parse_user_db(data, self.layout)
        except c840.C840FormatError as exc:
            return {0: errors.BAD_LENGTH_WORD, 1: errors.BAD_FLAGS if "flag" in str(exc) else errors.BAD_AXIS_NUMBER,
                    4: errors.TAN_BETA_OUT_OF_RANGE}.get(exc.data_word, errors.VALUE_OUT_OF_RANGE)
        if self.nck is None:
            return errors.OPTION_MISSING
        p0_mm = user.p0_mm(self.layout)
        # The manual only says P0 should not coincide with the axis zero point (issue 14 2.10): accepted
        # unless the machine's settings.c840_refuse_p0_at_zero asks for the refusal.
        if self.c840_refuse_p0_at_zero and user.position_dependent and p0_mm == 0.0:
            return errors.P0_AT_AXIS_ZERO
        try:
            self.nck.apply_840c_tc(user.axis, user.k_tcabs_mm(self.layout), user.tan_beta, p0_mm,
                                   user.position_independent, user.position_dependent)
        except NckError:
            return errors.AXIS_NOT_PRESENT
        return errors.NONE

    def power_on(self) -> None:
        """840C TC data are erased at power-on (the NCK clears its copy); DBs are kept."""
        channel = self.data_blocks[db41.CHANNEL_DB]
        channel[db41.OFFSET_HANDSHAKE] = 0
