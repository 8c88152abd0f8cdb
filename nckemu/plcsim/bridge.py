"""Running a user's STL program in awlsim against the emulator.

awlsim has no FB2/FB3/FB4 and no S7 server. The FB3 stub (``stl/fb3_put.awl``) writes its instance
DB number to PQW 500 on every call; ``NckBridgeHardware`` sees that write, reads the block's
parameters out of the instance DB (Req, NumVar, the ANY pointers to the NCVar-selector entries and to
the values), and on a rising edge of Req starts the NCK write without blocking the cycle. When the
write has finished it sets Done (or Error and State) in the instance DB for one cycle, which awlsim
copies to the caller's operands as the block returns. PIW reads come from the emulator's PLC, so the
program sees the machine's sensors. The CPU runs on the emulator's simulated clock.
"""

from __future__ import annotations

import concurrent.futures
import logging
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

# awlsim's core must be imported before its compiler, or its CPU module misses the compiler's
# block classes (a circular import inside awlsim 0.77.1).
from awlsim.core.main import AwlSim  # isort: split

from awlsim.awlcompiler import AwlParser
from awlsim.common.sources import AwlSource
from awlsim.core.hardware import AbstractHardwareInterface

from nckemu.clients.async_client import ItemResult
from nckemu.clients.fb import STATE_CONNECTION_LOST, STATE_NUMVAR_INVALID, item_state
from nckemu.clients.names import Variable
from nckemu.protocol.addresses import NckAddress, NckType
from nckemu.protocol.errors import NckConfigError, NckError

log = logging.getLogger(__name__)

STUB_DIR = Path(__file__).resolve().parent / "stl"
NOTIFY_PQW = 500
AREA_DB = 0x84
AREA_M = 0x83
ANY_BYTES = 10

# Byte offsets in the FB3 stub's instance DB (as awlsim lays out the interface in stl/fb3_put.awl).
FB3_REQ = 0
FB3_NUMVAR = 2
FB3_FIRST_ADDR = 4          # then per variable: Addr (10), Unit (1 + pad), Column (2), Line (2) = 16
FB3_VARIABLE_STRIDE = 16
FB3_FIRST_SD = FB3_FIRST_ADDR + 8 * FB3_VARIABLE_STRIDE
FB3_OUTPUTS = FB3_FIRST_SD + 8 * ANY_BYTES   # Error bit 0, Done bit 1; State at +2


@dataclass
class _Job:
    future: concurrent.futures.Future[Any] | None = None
    previous_req: bool = False
    report: tuple[bool, bool, int] | None = None   # (done, error, state) for the next call
    reported: bool = False


@dataclass
class PutRecord:
    time_s: float
    values: dict[str, Any]
    return_codes: list[int]


@dataclass
class BridgeLog:
    puts: list[PutRecord] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)


class NckBridgeHardware(AbstractHardwareInterface):  # type: ignore[misc]
    name = "nckemu"
    description = "nckemu bridge: FB2/FB3/FB4 stubs to NCK jobs, PIW from the emulator"

    def __init__(self, sim: AwlSim, client: Any, read_peripheral: Any, clock_s: Any, bridge_log: BridgeLog) -> None:
        super().__init__(sim=sim, parameters={})
        self.client = client
        self.read_peripheral = read_peripheral
        self.clock_s = clock_s
        self.log = bridge_log
        self.jobs: dict[int, _Job] = {}

    def doStartup(self) -> None:  # noqa: N802 - awlsim's hook names
        pass

    def doShutdown(self) -> None:  # noqa: N802
        pass

    def readInputs(self) -> None:  # noqa: N802
        pass

    def writeOutputs(self) -> None:  # noqa: N802
        pass

    def directReadInput(self, accessWidth: int, accessOffset: int) -> bytearray:  # noqa: N802, N803
        return bytearray(self.read_peripheral(accessOffset, accessWidth // 8))

    def directWriteOutput(self, accessWidth: int, accessOffset: int, data: bytearray) -> bool:  # noqa: N802, N803
        if accessOffset != NOTIFY_PQW or accessWidth != 16:
            return False
        self._fb3_call(int.from_bytes(bytes(data), "big"))
        return True

    # ------------------------------------------------------------------ memory
    def _memory(self, area: int, db_number: int) -> bytearray:
        cpu = self.sim.cpu
        if area == AREA_DB:
            return cpu.getDB(db_number).structInstance.memory.getDataBytes()
        if area == AREA_M:
            return cpu.flags.getDataBytes()
        raise NckConfigError(f"ANY pointer to area 0x{area:02X} is not supported by the bridge")

    def _any(self, raw: bytes) -> tuple[int, int, int, int, int]:
        """(data type, count, DB, area, byte offset) of a 10-byte S7 ANY pointer."""
        _syntax, data_type, count, db_number, area = struct.unpack_from(">BBHHB", raw)
        address = int.from_bytes(raw[7:10], "big")
        return data_type, count, db_number, area, address >> 3

    def _read_any(self, raw: bytes) -> bytes:
        data_type, count, db_number, area, offset = self._any(raw)
        size = count * {1: 1, 2: 1, 3: 1, 4: 2, 5: 2, 6: 4, 7: 4, 8: 4}.get(data_type, 1)
        memory = self._memory(area, db_number)
        return bytes(memory[offset:offset + size])

    # ------------------------------------------------------------------ FB3 PUT
    def _fb3_call(self, instance_db: int) -> None:
        memory = self._memory(AREA_DB, instance_db)
        job = self.jobs.setdefault(instance_db, _Job())
        req = bool(memory[FB3_REQ] & 1)
        rising = req and not job.previous_req
        job.previous_req = req
        done = error = False
        state = 0
        if job.future is not None and job.future.done():
            done, error, state = self._finish(job.future)
            job.future = None
        elif rising and job.future is None:
            try:
                job.future = self._start_put(memory)
            except NckError as exc:
                self.log.errors.append(f"FB3 in DB{instance_db}: {exc}")
                done, error, state = False, True, STATE_NUMVAR_INVALID
        outputs = memory[FB3_OUTPUTS] & ~0x03
        memory[FB3_OUTPUTS] = outputs | (0x01 if error else 0) | (0x02 if done else 0)
        memory[FB3_OUTPUTS + 2:FB3_OUTPUTS + 4] = struct.pack(">H", state)

    def _start_put(self, memory: bytearray) -> concurrent.futures.Future[Any]:
        num_var = struct.unpack_from(">h", memory, FB3_NUMVAR)[0]
        if not 1 <= num_var <= 8:
            raise NckConfigError(f"NumVar = {num_var}")
        pairs = []
        for index in range(num_var):
            base = FB3_FIRST_ADDR + index * FB3_VARIABLE_STRIDE
            entry = self._read_any(bytes(memory[base:base + ANY_BYTES]))
            if len(entry) < 10:
                raise NckConfigError(f"Addr{index + 1} does not point at a 10-byte NCVar-selector entry")
            unit = memory[base + 10]
            column, line = struct.unpack_from(">HH", memory, base + 12)
            syntax_id, area_unit, entry_column, entry_line, module, line_count, typ, length = \
                struct.unpack(">BBHHBBBB", entry)
            address = NckAddress.from_area_unit(area_unit, entry_column, entry_line, module, line_count, syntax_id)
            if unit or column or line:  # Unit/Column/Line given to the block override the entry
                address = NckAddress(address.area, unit or address.unit, column or address.column,
                                     line or address.line, address.module, address.line_count, address.syntax_id)
            value_raw = self._read_any(bytes(memory[FB3_FIRST_SD + index * ANY_BYTES:
                                                    FB3_FIRST_SD + (index + 1) * ANY_BYTES]))
            nck_type = NckType(typ)
            value = self._plc_value(value_raw, nck_type)
            pairs.append((Variable(address, nck_type, length if nck_type == NckType.STRING else None,
                                   f"Addr{index + 1}"), value))
        self.log.puts.append(PutRecord(self.clock_s(), {f"SD{i + 1}": v for i, (_a, v) in enumerate(pairs)}, []))
        return self.client.submit(self.client.async_client.put_items(pairs))

    @staticmethod
    def _plc_value(raw: bytes, nck_type: NckType) -> Any:
        """A PLC value as FB3 converts it: REAL (4 bytes) to the NCK's REAL8, integers as they are."""
        if nck_type in (NckType.REAL8, NckType.REAL4):
            return struct.unpack(">f", raw[:4])[0] if len(raw) == 4 else struct.unpack(">d", raw[:8])[0]
        if len(raw) == 1:
            return raw[0]
        if len(raw) == 2:
            return struct.unpack(">h", raw)[0]
        return struct.unpack(">i", raw[:4])[0]

    def _finish(self, future: concurrent.futures.Future[Any]) -> tuple[bool, bool, int]:
        try:
            results: list[ItemResult] = future.result()
        except NckError as exc:
            self.log.errors.append(f"FB3: {exc}")
            return False, True, STATE_CONNECTION_LOST
        if self.log.puts:
            self.log.puts[-1].return_codes = [r.return_code for r in results]
        for number, result in enumerate(results, start=1):
            if not result.ok:
                return False, True, item_state(result.return_code, number)
        return True, False, 0


def parse_sources(paths: list[Path]) -> list[Any]:
    trees = []
    for path in paths:
        parser = AwlParser()
        try:
            parser.parseSource(AwlSource(name=path.name, filepath=str(path), sourceBytes=path.read_bytes()))
        except Exception as exc:  # awlsim's parser errors carry the line
            raise NckConfigError(f"awlsim cannot parse it: {exc}", path=str(path)) from None
        trees.append(parser.getParseTree())
    return trees


class PlcRunner:
    """An awlsim CPU with the FB stubs and the bridge, on simulated time."""

    def __init__(self, program: Path, client: Any, read_peripheral: Any, clock_s: Any) -> None:
        self.log = BridgeLog()
        self.sim = AwlSim()
        self.sim.reset()
        self.clock_s = clock_s
        self.bridge = NckBridgeHardware(self.sim, client, read_peripheral, clock_s, self.log)
        self.sim.registerHardware(self.bridge)
        for tree in parse_sources([STUB_DIR / "fb3_put.awl", program]):
            self.sim.load(tree)
        self.sim.build()
        cpu = self.sim.getCPU()
        # The CPU's clock is the emulator's: timers such as S5T#1M run in simulated time.
        original = type(cpu).updateTimestamp
        cpu.updateTimestamp = lambda: original(cpu, _getTime=clock_s)
        self.sim.startup()

    def run_cycle(self) -> None:
        self.sim.runCycle()

    def pending(self) -> list[concurrent.futures.Future[Any]]:
        return [job.future for job in self.bridge.jobs.values() if job.future is not None]

    def shutdown(self) -> None:
        self.sim.shutdown()
