"""Running a user's STL program in awlsim against the emulator.

awlsim has no FB2/FB3/FB4 and no S7 server. The stubs in ``stl/`` keep the SINUMERIK blocks'
parameter names; each call writes its instance DB number to a peripheral output word (FB3 to
PQW 500, FB2 to PQW 502, FB4 to PQW 504). ``NckBridge`` sees that write, reads the block's
parameters out of the instance DB by name (Req, NumVar, the ANY pointers to the NCVar-selector
entries and to the values, ...), and on a rising edge of Req starts the NCK job without blocking the
cycle. When the job has finished it sets Done/NDR (or Error and State) in the instance DB for one
call, which awlsim copies to the caller's operands as the block returns; FB2 also copies the values
read into the RD areas. PIW reads come from the emulator's PLC, so the program sees the machine's
sensors.
"""

from __future__ import annotations

import concurrent.futures
import logging
import re
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

# awlsim's core must be imported before its compiler, or its CPU module misses the compiler's
# block classes (a circular import inside awlsim 0.77.1).
from awlsim.core.main import AwlSim  # isort: split

from awlsim.awlcompiler import AwlParser
from awlsim.common.sources import AwlSource
from awlsim.core.hardware import AbstractHardwareInterface

from nckemu.catalogue.names import Variable
from nckemu.clients.async_client import MAX_VARIABLES, ItemResult
from nckemu.clients.fb import (
    STATE_CONNECTION_LOST,
    STATE_NEGATIVE_ACK,
    STATE_NUMVAR_INVALID,
    STATE_PARAMETER_ERROR,
    item_state,
)
from nckemu.errors import NckConfigError, NckError, NckServiceError
from nckemu.protocol import pi
from nckemu.protocol.addresses import NckAddress, NckType

log = logging.getLogger(__name__)

STUB_DIR = Path(__file__).resolve().parent / "stl"
STUB_SOURCES = (STUB_DIR / "fb2_get.awl", STUB_DIR / "fb3_put.awl", STUB_DIR / "fb4_pi_serv.awl")
PUT_NOTIFY_PQW = 500
GET_NOTIFY_PQW = 502
PI_NOTIFY_PQW = 504
AREA_DB = 0x84
AREA_DI = 0x85
AREA_M = 0x83
AREA_I = 0x81
AREA_Q = 0x82
ANY_BYTES = 10
NCVAR_ENTRY_BYTES = 10
PI_ARGUMENTS = 4
PI_WORDS = 10
# ASSUMPTION: FB4 sends the NC's address identification as the first argument of an NC service,
# then the wired Addr1..4 strings, then WVar1..10 (as decimal text) while the service takes more.
PI_ADDRESS_IDENT = "/NC"

# Width in bytes of the element types an ANY pointer can name (S7 data type codes).
_ANY_ELEMENT_BYTES = {1: 1, 2: 1, 3: 1, 4: 2, 5: 2, 6: 4, 7: 4, 8: 4, 0x0E: 4}
_ANY_REAL = 8
_ANY_STRING = 0x13


@dataclass
class _Job:
    future: concurrent.futures.Future[Any] | None = None
    previous_req: bool = False
    record: JobRecord | None = None


@dataclass
class JobRecord:
    """One job a block ran: what it asked for and how the NCK answered."""

    block: str                 # "GET", "PUT" or "PI"
    time_s: float
    values: dict[str, Any]     # PUT: SD1.. written; GET: RD1.. read; PI: the service and its arguments
    return_codes: list[int] = field(default_factory=list)
    error: str = ""


@dataclass
class BridgeLog:
    jobs: list[JobRecord] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    @property
    def puts(self) -> list[JobRecord]:
        return [job for job in self.jobs if job.block == "PUT"]

    @property
    def gets(self) -> list[JobRecord]:
        return [job for job in self.jobs if job.block == "GET"]

    @property
    def pi_calls(self) -> list[JobRecord]:
        return [job for job in self.jobs if job.block == "PI"]


class _Outcome(NckError):
    """A block's job ended with Error and this State."""

    def __init__(self, message: str, state: int) -> None:
        super().__init__(message)
        self.state = state


class NckBridge:
    """What the FB stubs ask of the NCK, done on a client without blocking the PLC cycle.

    ``client`` is an :class:`~nckemu.clients.NckClient` (its ``submit`` runs a coroutine on the
    client's loop and returns a future); ``read_peripheral(offset, size)`` answers PIW reads;
    ``clock_s()`` is the time stamped on the log.
    """

    def __init__(self, sim: AwlSim, client: Any, read_peripheral: Callable[[int, int], bytes],
                 clock_s: Callable[[], float], bridge_log: BridgeLog | None = None) -> None:
        self.sim = sim
        self.client = client
        self.read_peripheral = read_peripheral
        self.clock_s = clock_s
        self.log = bridge_log or BridgeLog()
        self.jobs: dict[int, _Job] = {}
        self._blocks: dict[int, tuple[str, Callable[[int], concurrent.futures.Future[Any]]]] = {
            PUT_NOTIFY_PQW: ("PUT", self._start_put),
            GET_NOTIFY_PQW: ("GET", self._start_get),
            PI_NOTIFY_PQW: ("PI", self._start_pi),
        }

    def pending(self) -> list[concurrent.futures.Future[Any]]:
        return [job.future for job in self.jobs.values() if job.future is not None]

    # ------------------------------------------------------------------ awlsim's hooks
    def read_input(self, width_bits: int, offset: int) -> bytearray:
        return bytearray(self.read_peripheral(offset, width_bits // 8))

    def write_output(self, width_bits: int, offset: int, data: bytes) -> bool:
        block = self._blocks.get(offset)
        if block is None or width_bits != 16:
            return False
        self._call(block[0], block[1], int.from_bytes(bytes(data), "big"))
        return True

    # ------------------------------------------------------------------ instance DB access
    def _instance(self, db_number: int) -> tuple[Any, bytearray]:
        db = self.sim.cpu.getDB(db_number)
        return db.structInstance._struct, db.structInstance.memory.getDataBytes()

    @staticmethod
    def _offset(struct_: Any, name: str) -> tuple[int, int]:
        offset = struct_.getField(name).offset
        return offset.byteOffset, offset.bitOffset

    def _field_bytes(self, struct_: Any, memory: bytearray, name: str, size: int) -> bytes:
        start, _bit = self._offset(struct_, name)
        return bytes(memory[start:start + size])

    def _memory(self, area: int, db_number: int) -> bytearray:
        cpu = self.sim.cpu
        if area in (AREA_DB, AREA_DI):
            return cpu.getDB(db_number).structInstance.memory.getDataBytes()
        if area == AREA_M:
            return cpu.flags.getDataBytes()
        if area == AREA_I:
            return cpu.inputs.getDataBytes()
        if area == AREA_Q:
            return cpu.outputs.getDataBytes()
        raise _Outcome(f"an ANY pointer to area 0x{area:02X} is not supported by the bridge", STATE_PARAMETER_ERROR)

    def _any_target(self, raw: bytes) -> tuple[bytearray, int, int, int] | None:
        """(memory, byte offset, size, data type) an ANY pointer designates; None when not wired."""
        _syntax, data_type, count, db_number, area = struct.unpack_from(">BBHHB", raw)
        if data_type == 0 or count == 0:
            return None
        offset = int.from_bytes(raw[7:10], "big") >> 3
        memory = self._memory(area, db_number)
        if data_type == _ANY_STRING:  # an S7 STRING: its first byte is the maximum length
            size = count * ((memory[offset] if offset < len(memory) else 0) + 2)
        else:
            size = count * _ANY_ELEMENT_BYTES.get(data_type, 1)
        if offset + size > len(memory):
            raise _Outcome(f"an ANY pointer reaches beyond its area (byte {offset}, {size} bytes)",
                           STATE_PARAMETER_ERROR)
        return memory, offset, size, data_type

    def _read_any(self, raw: bytes) -> tuple[bytes, int] | None:
        target = self._any_target(raw)
        if target is None:
            return None
        memory, offset, size, data_type = target
        return bytes(memory[offset:offset + size]), data_type

    # ------------------------------------------------------------------ the common block cycle
    def _call(self, block: str, start: Callable[[int], concurrent.futures.Future[Any]], instance_db: int) -> None:
        struct_, memory = self._instance(instance_db)
        job = self.jobs.setdefault(instance_db, _Job())
        req_byte, req_bit = self._offset(struct_, "Req")
        req = bool(memory[req_byte] >> req_bit & 1)
        rising = req and not job.previous_req
        job.previous_req = req
        done = error = False
        state = 0
        if job.future is not None and job.future.done():
            done, error, state = self._finish(block, instance_db, job)
            job.future = None
        elif rising and job.future is None:
            try:
                job.future = start(instance_db)
                job.record = self.log.jobs[-1]
            except NckError as exc:
                self.log.errors.append(f"{block} in DB{instance_db}: {exc}")
                error, state = True, exc.state if isinstance(exc, _Outcome) else STATE_PARAMETER_ERROR
        self._set_bit(struct_, memory, "Error", error)
        self._set_bit(struct_, memory, "NDR" if block == "GET" else "Done", done)
        state_at, _bit = self._offset(struct_, "State")
        memory[state_at:state_at + 2] = struct.pack(">H", state)

    def _set_bit(self, struct_: Any, memory: bytearray, name: str, value: bool) -> None:
        byte, bit = self._offset(struct_, name)
        memory[byte] = (memory[byte] | (1 << bit)) if value else (memory[byte] & ~(1 << bit))

    def _finish(self, block: str, instance_db: int, job: _Job) -> tuple[bool, bool, int]:
        assert job.future is not None
        record = job.record
        try:
            result = job.future.result()
        except _Outcome as exc:
            return self._failed(block, instance_db, record, str(exc), exc.state)
        except NckServiceError as exc:
            return self._failed(block, instance_db, record, str(exc), STATE_NEGATIVE_ACK)
        except NckError as exc:
            return self._failed(block, instance_db, record, str(exc), STATE_CONNECTION_LOST)
        if block == "PI":
            return True, False, 0
        results: list[ItemResult] = result
        if record is not None:
            record.return_codes = [r.return_code for r in results]
        for number, item in enumerate(results, start=1):
            if not item.ok:
                return self._failed(block, instance_db, record, f"variable {number}: return code "
                                    f"0x{item.return_code:02X}", item_state(item.return_code, number))
        if block == "GET":
            try:
                self._store_read_values(instance_db, results, record)
            except _Outcome as exc:
                return self._failed(block, instance_db, record, str(exc), exc.state)
        return True, False, 0

    def _failed(self, block: str, instance_db: int, record: JobRecord | None, message: str,
                state: int) -> tuple[bool, bool, int]:
        if record is not None:
            record.error = message
        self.log.errors.append(f"{block} in DB{instance_db}: {message} (State W#16#{state:04X})")
        return False, True, state

    # ------------------------------------------------------------------ FB2 / FB3 variables
    def _variables(self, instance_db: int) -> list[Variable]:
        struct_, memory = self._instance(instance_db)
        num_var = struct.unpack(">h", self._field_bytes(struct_, memory, "NumVar", 2))[0]
        if not 1 <= num_var <= MAX_VARIABLES:
            raise _Outcome(f"NumVar = {num_var}, but GET/PUT take 1..{MAX_VARIABLES}", STATE_NUMVAR_INVALID)
        variables = []
        for number in range(1, num_var + 1):
            entry = self._read_any(self._field_bytes(struct_, memory, f"Addr{number}", ANY_BYTES))
            if entry is None or len(entry[0]) < NCVAR_ENTRY_BYTES:
                raise _Outcome(f"Addr{number} does not point at a 10-byte NCVar-selector entry",
                               STATE_PARAMETER_ERROR)
            syntax_id, area_unit, column, line, module, line_count, typ, length = \
                struct.unpack(">BBHHBBBB", entry[0][:NCVAR_ENTRY_BYTES])
            address = NckAddress.from_area_unit(area_unit, column, line, module, line_count, syntax_id)
            unit = self._field_bytes(struct_, memory, f"Unit{number}", 1)[0]
            column_override, line_override = (
                struct.unpack(">H", self._field_bytes(struct_, memory, f"{name}{number}", 2))[0]
                for name in ("Column", "Line"))
            if unit or column_override or line_override:  # wired Unit/Column/Line override the entry
                address = NckAddress(address.area, unit or address.unit, column_override or address.column,
                                     line_override or address.line, address.module, address.line_count,
                                     address.syntax_id)
            try:
                nck_type = NckType(typ)
            except ValueError:
                raise _Outcome(f"Addr{number}: type byte 0x{typ:02X} is not an NCK type",
                               STATE_PARAMETER_ERROR) from None
            variables.append(Variable(address, nck_type, length if nck_type == NckType.STRING else None,
                                      f"Addr{number}"))
        return variables

    def _start_put(self, instance_db: int) -> concurrent.futures.Future[Any]:
        struct_, memory = self._instance(instance_db)
        pairs = []
        for number, variable in enumerate(self._variables(instance_db), start=1):
            source = self._read_any(self._field_bytes(struct_, memory, f"SD{number}", ANY_BYTES))
            if source is None:
                raise _Outcome(f"SD{number} is not wired", STATE_PARAMETER_ERROR)
            pairs.append((variable, plc_to_nck_value(*source, variable.nck_type)))
        self.log.jobs.append(JobRecord("PUT", self.clock_s(), {f"SD{i}": v for i, (_, v) in enumerate(pairs, 1)}))
        return self.client.submit(self.client.async_client.put_items(pairs))

    def _start_get(self, instance_db: int) -> concurrent.futures.Future[Any]:
        variables = self._variables(instance_db)
        struct_, memory = self._instance(instance_db)
        for number in range(1, len(variables) + 1):
            if self._read_any(self._field_bytes(struct_, memory, f"RD{number}", ANY_BYTES)) is None:
                raise _Outcome(f"RD{number} is not wired", STATE_PARAMETER_ERROR)
        self.log.jobs.append(JobRecord("GET", self.clock_s(), {}))
        return self.client.submit(self.client.async_client.get_items(*variables))

    def _store_read_values(self, instance_db: int, results: list[ItemResult], record: JobRecord | None) -> None:
        struct_, memory = self._instance(instance_db)
        for number, item in enumerate(results, start=1):
            target = self._any_target(self._field_bytes(struct_, memory, f"RD{number}", ANY_BYTES))
            assert target is not None  # checked when the job started
            area, offset, size, data_type = target
            area[offset:offset + size] = nck_to_plc_bytes(item.value, item.variable.nck_type, size, data_type, number)
            if record is not None:
                record.values[f"RD{number}"] = item.value

    # ------------------------------------------------------------------ FB4
    def _start_pi(self, instance_db: int) -> concurrent.futures.Future[Any]:
        struct_, memory = self._instance(instance_db)
        named = self._read_any(self._field_bytes(struct_, memory, "PIService", ANY_BYTES))
        if named is None:
            raise _Outcome("PIService is not wired", STATE_PARAMETER_ERROR)
        service = pi_service_name(plc_string(named[0]))
        texts = []
        for number in range(1, PI_ARGUMENTS + 1):
            argument = self._read_any(self._field_bytes(struct_, memory, f"Addr{number}", ANY_BYTES))
            if argument is not None:
                texts.append(plc_string(argument[0]))
        words = [struct.unpack(">H", self._field_bytes(struct_, memory, f"WVar{n}", 2))[0]
                 for n in range(1, PI_WORDS + 1)]
        arguments = pi_arguments(service, texts, words)
        self.log.jobs.append(JobRecord("PI", self.clock_s(), {"service": service, "arguments": arguments}))
        return self.client.submit(self.client.async_client.pi_service(service, *arguments))


# ---------------------------------------------------------------------- value conversions
def plc_to_nck_value(raw: bytes, data_type: int, nck_type: NckType) -> Any:
    """A PLC value as FB3 converts it: a REAL (4 bytes) or 8 bytes to the NCK's REAL8, integers as they are."""
    if nck_type in (NckType.REAL8, NckType.REAL4):
        if len(raw) == 4:
            return struct.unpack(">f", raw)[0] if data_type in (_ANY_REAL, 6, 2) else float(
                struct.unpack(">i", raw)[0])
        if len(raw) == 8:
            return struct.unpack(">d", raw)[0]
    if nck_type == NckType.STRING:
        return plc_string(raw)
    if len(raw) == 1:
        return raw[0]
    if len(raw) == 2:
        return struct.unpack(">h", raw)[0]
    return struct.unpack(">i", raw[:4])[0]


def nck_to_plc_bytes(value: Any, nck_type: NckType, size: int, data_type: int, number: int) -> bytes:
    """What FB2 puts into an RD area: REAL8 to a PLC REAL (4 bytes) or 8 bytes, integers big-endian."""
    if isinstance(value, list | tuple):
        raise _Outcome(f"variable {number} has {len(value)} lines; RD{number} takes one value", STATE_PARAMETER_ERROR)
    if nck_type in (NckType.REAL8, NckType.REAL4):
        if size == 4 and data_type in (_ANY_REAL, 2, 6):
            return struct.pack(">f", float(value))
        if size == 8:
            return struct.pack(">d", float(value))
        raise _Outcome(f"RD{number}: a REAL needs 4 (REAL) or 8 bytes, the area has {size}", STATE_PARAMETER_ERROR)
    if nck_type == NckType.STRING:
        text = str(value).encode("ascii", "replace")[:size]
        return text.ljust(size, b"\x00")
    if isinstance(value, bool):
        value = int(value)
    try:
        return int(value).to_bytes(size, "big", signed=int(value) < 0)
    except OverflowError:
        raise _Outcome(f"RD{number}: {value} does not fit in {size} bytes", STATE_PARAMETER_ERROR) from None


def plc_string(raw: bytes) -> str:
    """An S7 STRING (max length, actual length, characters) or plain characters up to a NUL byte."""
    if len(raw) >= 2 and raw[1] <= raw[0] and raw[1] <= len(raw) - 2:
        return raw[2:2 + raw[1]].decode("ascii", "replace")
    return raw.split(b"\x00", 1)[0].decode("ascii", "replace").strip()


def pi_service_name(text: str) -> str:
    """``_N_SETUDT``, ``PI.SETUDT`` and ``SETUDT`` all name the NCK's ``_N_SETUDT``."""
    name = text.strip()
    if name.upper().startswith("PI."):
        name = name[3:]
    if not name.startswith("_N_"):
        name = "_N_" + name
    return name


def pi_arguments(service: str, texts: list[str], words: list[int]) -> list[str]:
    spec = pi.PI_SERVICES.get(service)
    arguments = [PI_ADDRESS_IDENT] if spec is None or pi.is_nc_service(service) else []
    arguments += texts
    wanted = len(spec.argument_names) if spec is not None else len(arguments)
    for word in words:
        if len(arguments) >= wanted:
            break
        arguments.append(str(word))
    return arguments


# ---------------------------------------------------------------------- awlsim glue
class NckBridgeHardware(AbstractHardwareInterface):  # type: ignore[misc]
    """awlsim hardware interface around an :class:`NckBridge` built by the caller."""

    name = "nckemu"
    description = "nckemu bridge: FB2/FB3/FB4 stubs to NCK jobs, PIW from the emulator"

    def __init__(self, sim: AwlSim, bridge: NckBridge, parameters: dict[str, Any] | None = None) -> None:
        super().__init__(sim=sim, parameters=parameters or {})
        self.bridge = bridge

    def doStartup(self) -> None:  # noqa: N802 - awlsim's hook names
        pass

    def doShutdown(self) -> None:  # noqa: N802
        pass

    def readInputs(self) -> None:  # noqa: N802
        pass

    def writeOutputs(self) -> None:  # noqa: N802
        pass

    def directReadInput(self, accessWidth: int, accessOffset: int) -> bytearray:  # noqa: N802, N803
        return self.bridge.read_input(accessWidth, accessOffset)

    def directWriteOutput(self, accessWidth: int, accessOffset: int, data: bytearray) -> bool:  # noqa: N802, N803
        return self.bridge.write_output(accessWidth, accessOffset, bytes(data))


_AWLSIM_LINE = re.compile(r"at line (?P<line>\d+):\s*(?P<rest>.*)", re.DOTALL)


def awlsim_error_text(exc: BaseException) -> str:
    """awlsim's error text on one line: its message spans lines (source hash, the statement, a CPU
    dump); keep the line number, the statement and what is wrong with it."""
    text = str(exc)
    found = _AWLSIM_LINE.search(text)
    if found is None:
        return " ".join(text.split())[:300]
    rest = found["rest"].split("[S7-CPU]", 1)[0]
    return f"line {found['line']}: " + " ".join(rest.split())[:300]


def parse_sources(paths: list[Path]) -> list[Any]:
    trees = []
    for path in paths:
        parser = AwlParser()
        try:
            parser.parseSource(AwlSource(name=path.name, filepath=str(path), sourceBytes=path.read_bytes()))
        except OSError as exc:
            raise NckConfigError(f"cannot read: {exc.strerror}", path=str(path)) from None
        except Exception as exc:  # awlsim's parser errors carry the line
            raise NckConfigError(f"awlsim cannot parse it: {awlsim_error_text(exc)}", path=str(path)) from None
        trees.append(parser.getParseTree())
    return trees


class PlcRunner:
    """An awlsim CPU with the FB stubs and the bridge; its clock is ``clock_s``."""

    def __init__(self, program: Path, client: Any, read_peripheral: Callable[[int, int], bytes],
                 clock_s: Callable[[], float], watchdog_wall_s: float | None = None) -> None:
        self.sim = AwlSim()
        self.sim.reset()
        self.clock_s = clock_s
        self.bridge = NckBridge(self.sim, client, read_peripheral, clock_s)
        self.log = self.bridge.log
        self.sim.registerHardware(NckBridgeHardware(self.sim, self.bridge))
        try:
            for tree in parse_sources([*STUB_SOURCES, program]):
                self.sim.load(tree)
            self.sim.build()
        except NckConfigError:
            raise
        except Exception as exc:  # awlsim's translator errors name the block and the statement
            raise NckConfigError(f"awlsim cannot load it: {awlsim_error_text(exc)}", path=str(program)) from None
        cpu = self.sim.getCPU()
        # The CPU's clock is the caller's: timers such as S5T#1M run in simulated time.
        original = type(cpu).updateTimestamp
        self._cycle_wall_s = time.monotonic()
        if watchdog_wall_s is None:
            cpu.updateTimestamp = lambda: original(cpu, _getTime=clock_s)
        else:
            # Simulated time stands still within a cycle, so awlsim's own cycle-time watchdog would
            # never see an endless loop: past watchdog_wall_s of wall time in one cycle its clock
            # jumps, and awlsim stops the program with its "cycle time exceeded" error.
            def watched_s() -> float:
                if time.monotonic() - self._cycle_wall_s > watchdog_wall_s:
                    return clock_s() + 1e6
                return clock_s()

            cpu.updateTimestamp = lambda: original(cpu, _getTime=watched_s)
        self.sim.startup()

    def run_cycle(self) -> None:
        self._cycle_wall_s = time.monotonic()
        self.sim.runCycle()

    def pending(self) -> list[concurrent.futures.Future[Any]]:
        return self.bridge.pending()

    def flags(self) -> bytes:
        """The CPU's flag (M) area as it is now."""
        return bytes(self.sim.cpu.flags.getDataBytes())

    def shutdown(self) -> None:
        self.sim.shutdown()


_OB1 = re.compile(r"^\s*ORGANIZATION_BLOCK\s+OB\s*1\b", re.IGNORECASE | re.MULTILINE)


def check_program(program: Path) -> str:
    """The program's text, or one clear error: unreadable, empty, or without the OB1 a PLC cycle runs."""
    try:
        text = program.read_text("utf-8", errors="replace")
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=str(program)) from None
    if not text.strip():
        raise NckConfigError("the program is empty: the PLC would run nothing", path=str(program))
    if not _OB1.search(text):
        raise NckConfigError("no ORGANIZATION_BLOCK OB 1: the PLC would run nothing", path=str(program))
    return text
