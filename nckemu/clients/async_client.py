"""AsyncNckClient: GET/PUT (FB2/FB3) and PI_SERV (FB4) as one S7 job each, on python-snap7's connection.

The bytes are the same a PLC's FB3 or an HMI sends: one read or write job with up to 8 NCK items
(syntax 0x82), REAL8 little-endian, transport size 0x09. PLC memory named among them (``DB130.DBW0``,
``M5.0``, ``PIW420``: ``catalogue.names.PlcVariable``) goes in the same job as S7ANY items (syntax 0x10),
big-endian, as any S7 tool reads it; an S7 STRING's maximum length is read first. The connection (COTP, setup
communication) is python-snap7's ``AsyncClient``; our PDUs go through its ``iso_exchange_buffer``,
so the same code talks to the emulator or to a real NCU (rack 0, slot 4 for an 840D sl NCK).
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import re
import struct
from collections.abc import Awaitable, Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

from snap7.async_client import AsyncClient
from snap7.error import S7ProtocolError
from snap7.type import Area

from nckemu.catalogue.names import (
    STRING_HEADER,
    PlcVariable,
    Variable,
    as_item,
    plc_address,
    plc_decode,
    plc_encode,
)
from nckemu.errors import (
    NckConfigError,
    NckConnectionError,
    NckError,
    NckItemError,
    NckServiceError,
    NckTimeoutError,
    ReturnCode,
    item_error_for,
    service_error_for,
)
from nckemu.protocol import pi, s7
from nckemu.protocol.addresses import NckType, S7AnyAddress, S7TransportSize
from nckemu.protocol.codes import (
    HEADER_ERROR_TEXTS,
    SERVICE_HEADER_ERROR_TEXTS,
    describe_return_code,
    describe_service_header_error,
)
from nckemu.protocol.errors import NckProtocolError
from nckemu.protocol.values import NCK_TRANSPORT_SIZE, decode_nck_values, encode_nck_values

log = logging.getLogger(__name__)
T = TypeVar("T")

MAX_VARIABLES = 8  # NumVar of FB2/FB3
DATA_TS_BIT = 0x03    # data transport sizes of S7ANY write data: one bit, bytes (length in bits)
DATA_TS_BYTES = 0x04
RC_SUCCESS = ReturnCode.SUCCESS
PASSWORD_REFUSED = (0xD602, 0x0119)  # "incorrect password entered" (PI, block services)
# python-snap7's text for a refused item, e.g. "Write operation failed: Object does not exist (0x0a)"
_SNAP7_ITEM_ERROR = re.compile(r"operation failed: .*\(0x(?P<code>[0-9a-fA-F]{2})\)\s*$")


@dataclass(frozen=True)
class ItemResult:
    """One variable of a GET or PUT: its value (GET) or None, and the item return code."""

    variable: Variable | PlcVariable
    return_code: int
    value: Any = None

    @property
    def ok(self) -> bool:
        return self.return_code == RC_SUCCESS

    def error(self, index: int) -> NckItemError:
        return item_error_for(self.return_code, f"variable {index} ({self.variable}): "
                                                f"{describe_return_code(self.return_code)}")


def to_real32(value: float) -> float:
    """What a value is after the PLC's 32-bit REAL (about 7 significant digits)."""
    return struct.unpack("<f", struct.pack("<f", value))[0]


class AsyncNckClient:
    """``async with AsyncNckClient("127.0.0.1", port=1102) as nck: await nck.get("SD43900[AX4]")``."""

    def __init__(self, host: str, port: int = 102, *, rack: int = 0, slot: int = 4,
                 timeout_s: float = 5.0, plc_real32: bool = False) -> None:
        self.host = host
        self.port = port
        self.rack = rack
        self.slot = slot
        self.timeout_s = timeout_s
        # Pass REAL8 values through a 32-bit REAL, as a PLC's FB3 does with an SD of type REAL.
        self.plc_real32 = plc_real32
        self._client: AsyncClient | None = None
        self._refs = itertools.cycle(range(1, 0x10000))
        self._lock = asyncio.Lock()

    # ------------------------------------------------------------------ connection
    @property
    def connected(self) -> bool:
        return self._client is not None

    async def connect(self) -> AsyncNckClient:
        client = AsyncClient()
        try:
            await asyncio.wait_for(client.connect(self.host, self.rack, self.slot, self.port), self.timeout_s)
        except TimeoutError:
            await self._drop(client)
            raise NckTimeoutError(f"no connect confirm from {self.host}:{self.port} within "
                                  f"{self.timeout_s} s") from None
        except Exception as exc:
            await self._drop(client)
            raise NckConnectionError(f"cannot connect to {self.host}:{self.port} "
                                     f"(rack {self.rack}, slot {self.slot}): {exc}") from None
        self._client = client
        return self

    @staticmethod
    async def _drop(client: AsyncClient) -> None:
        try:
            await client.disconnect()
        except Exception:  # the connection is being discarded anyway
            log.debug("disconnect of a failed connection failed", exc_info=True)

    async def disconnect(self) -> None:
        client, self._client = self._client, None
        if client is not None:
            await self._drop(client)

    async def reconnect(self) -> None:
        await self.disconnect()
        await self.connect()

    async def __aenter__(self) -> AsyncNckClient:
        return await self.connect()

    async def __aexit__(self, *exc: object) -> None:
        await self.disconnect()

    async def _on_connection(self, what: str, operation: Callable[[AsyncClient], Awaitable[T]]) -> T:
        """Run one exchange; a timeout or a lost connection closes it (the next call reconnects)."""
        async with self._lock:
            if self._client is None:
                await self.connect()
            assert self._client is not None
            try:
                return await asyncio.wait_for(operation(self._client), self.timeout_s)
            except TimeoutError:
                await self.disconnect()
                raise NckTimeoutError(f"{what}: {self.host}:{self.port} did not answer within "
                                      f"{self.timeout_s} s; the connection was closed") from None
            except NckError:
                raise
            except S7ProtocolError as exc:
                refused = _SNAP7_ITEM_ERROR.search(str(exc))
                if refused is None:
                    await self.disconnect()
                    raise NckConnectionError(f"{what}: connection to {self.host}:{self.port} lost ({exc}); "
                                             "the next call reconnects") from None
                # python-snap7 raises the item's return code as a protocol error; the connection is fine
                code = int(refused["code"], 16)
                raise item_error_for(code, f"{what}: the controller refused it: "
                                           f"{describe_return_code(code)}") from None
            except Exception as exc:
                await self.disconnect()
                raise NckConnectionError(f"{what}: connection to {self.host}:{self.port} lost ({exc}); "
                                         "the next call reconnects") from None

    async def exchange(self, parameter: bytes, data: bytes = b"") -> s7.S7Pdu:
        """Send one S7 job, return its answer; a header error becomes NckServiceError."""
        ref = next(self._refs)
        request = bytearray(s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, ref, parameter, data)))
        raw = await self._on_connection(f"job 0x{parameter[0]:02X}",
                                        lambda client: client.iso_exchange_buffer(request))
        answer = s7.parse_pdu(bytes(raw))
        if answer.error_class or answer.error_code:
            code = (answer.error_class << 8) | answer.error_code
            if code in SERVICE_HEADER_ERROR_TEXTS.get(parameter[0], {}):
                text = describe_service_header_error(parameter[0], answer.error_class, answer.error_code)
            else:
                text = f"{HEADER_ERROR_TEXTS.get(code, 'an error without a known text')} (header error 0x{code:04X})"
            raise service_error_for(answer.error_class, answer.error_code,
                                    f"the controller refused the job: {text}")
        if answer.parameter[:1] != parameter[:1]:
            raise NckProtocolError(f"answer to function 0x{parameter[0]:02X} carries function "
                                   f"0x{answer.parameter[0] if answer.parameter else 0:02X}")
        return answer

    # ------------------------------------------------------------------ GET / PUT
    @staticmethod
    def _variables(items: Iterable[object]) -> list[Variable | PlcVariable]:
        variables = [as_item(item) for item in items]
        if not 1 <= len(variables) <= MAX_VARIABLES:
            raise NckConfigError(f"NumVar = {len(variables)}: GET/PUT take 1..{MAX_VARIABLES} variables")
        return variables

    async def _string_maxima(self, variables: list[Variable | PlcVariable]) -> dict[int, int]:
        """The maximum length of each S7 STRING among ``variables`` (by position), read in one job; a
        refused header leaves its string out (its own read or write then answers the refusal)."""
        strings = [(index, v) for index, v in enumerate(variables)
                   if isinstance(v, PlcVariable) and v.kind == "STRING"]
        if not strings:
            return {}
        request = s7.ReadVarRequest(tuple(plc_address(v, STRING_HEADER) for _, v in strings))
        answer = await self.exchange(s7.build_read_var_request(request))
        response = s7.parse_read_var_response(answer.parameter, answer.data)
        return {index: item.data[0] for (index, _), item in zip(strings, response.items, strict=False)
                if item.return_code == RC_SUCCESS and item.data}

    async def get_items(self, *items: object) -> list[ItemResult]:
        """FB2 GET: one read job; each variable's value or its own return code."""
        variables = self._variables(items)
        for variable in variables:
            if isinstance(variable, PlcVariable) and variable.area == "PQ":
                raise NckConfigError(f"{variable}: the peripheral outputs are written, not read; read the "
                                     f"outputs' process image ({str(variable)[1:]})")
        maxima = await self._string_maxima(variables)
        addresses = tuple(v.address if isinstance(v, Variable) else
                          plc_address(v, STRING_HEADER + maxima.get(index, 0))
                          for index, v in enumerate(variables))
        answer = await self.exchange(s7.build_read_var_request(s7.ReadVarRequest(addresses)))
        response = s7.parse_read_var_response(answer.parameter, answer.data)
        if len(response.items) != len(variables):
            raise NckProtocolError(f"{len(variables)} variables read, {len(response.items)} answered")
        results = []
        for variable, item in zip(variables, response.items, strict=True):
            if item.return_code != RC_SUCCESS:
                results.append(ItemResult(variable, item.return_code))
                continue
            if isinstance(variable, PlcVariable):
                results.append(ItemResult(variable, RC_SUCCESS, plc_decode(variable, item.data)))
                continue
            values = decode_nck_values(variable.nck_type, item.data, area=variable.address.area,
                                       line_count=variable.address.line_count, string_length=variable.length)
            results.append(ItemResult(variable, RC_SUCCESS, values[0] if len(values) == 1 else values))
        return results

    async def get(self, *items: object) -> list[Any]:
        """Values of 1..8 variables; the first failing variable raises its item error."""
        results = await self.get_items(*items)
        for index, result in enumerate(results, start=1):
            if not result.ok:
                raise result.error(index)
        return [result.value for result in results]

    def _encode(self, variable: Variable, value: Any) -> bytes:
        values = value if isinstance(value, list | tuple) and variable.address.line_count > 1 else [value]
        if self.plc_real32 and variable.nck_type in (NckType.REAL8, NckType.REAL4):
            values = [to_real32(float(v)) for v in values]
        return encode_nck_values(variable.nck_type, values, area=variable.address.area,
                                 string_length=variable.length)

    @staticmethod
    def _plc_item(variable: PlcVariable, value: Any, maximum: int | None) -> tuple[S7AnyAddress, s7.DataItem]:
        """The S7ANY item and its data: a bit (transport size BIT), bytes (BYTE/WORD/DWORD, length in
        bits), or a STRING's length and characters after its maximum length byte."""
        if variable.kind == "BOOL":
            return plc_address(variable), s7.DataItem(0x00, DATA_TS_BIT, plc_encode(variable, [value]))
        if variable.kind == "STRING":
            if maximum is None:
                raise NckConfigError(f"{variable}: its maximum length could not be read (does it exist?)")
            text = str(value).encode("latin-1", "replace")
            if len(text) > maximum:
                raise NckConfigError(f"{variable}: {len(text)} characters in an S7 string of at most {maximum} "
                                     f"(its first byte, the maximum length, says so"
                                     f"{'; set it first, e.g. ' + str(variable).split(':')[0] + '=254' if not maximum else ''})")
            data = bytes([len(text)]) + text
            return (S7AnyAddress(S7TransportSize.BYTE, len(data), variable.db, variable.s7_area, variable.byte + 1),
                    s7.DataItem(0x00, DATA_TS_BYTES, data))
        values = list(value) if isinstance(value, list | tuple) else [value]
        return plc_address(variable), s7.DataItem(0x00, DATA_TS_BYTES, plc_encode(variable, values))

    async def put_items(self, values: Mapping[object, Any] | Iterable[tuple[object, Any]]) -> list[ItemResult]:
        """FB3 PUT: one write job; each variable's return code (valid items land, bad ones say why)."""
        pairs = list(values.items()) if isinstance(values, Mapping) else list(values)
        variables = self._variables(item for item, _ in pairs)
        maxima = await self._string_maxima(variables)
        addresses: list[object] = []
        data: list[s7.DataItem] = []
        for index, (variable, (_, value)) in enumerate(zip(variables, pairs, strict=True)):
            if isinstance(variable, PlcVariable):
                address, item = self._plc_item(variable, value, maxima.get(index))
                addresses.append(address)
                data.append(item)
            else:
                addresses.append(variable.address)
                data.append(s7.DataItem(0x00, NCK_TRANSPORT_SIZE, self._encode(variable, value)))
        request = s7.WriteVarRequest(tuple(addresses), tuple(data))  # type: ignore[arg-type]
        answer = await self.exchange(*s7.build_write_var_request(request))
        response = s7.parse_write_var_response(answer.parameter, answer.data)
        if len(response.return_codes) != len(variables):
            raise NckProtocolError(f"{len(variables)} variables written, {len(response.return_codes)} answered")
        return [ItemResult(v, rc) for v, rc in zip(variables, response.return_codes, strict=True)]

    async def put(self, values: Mapping[object, Any] | Iterable[tuple[object, Any]]) -> None:
        """Write 1..8 variables in one job; raises the first failing variable's item error."""
        for index, result in enumerate(await self.put_items(values), start=1):
            if not result.ok:
                raise result.error(index)

    # ------------------------------------------------------------------ PI service
    async def pi_service(self, service: str, *arguments: str) -> None:
        """FB4 PI_SERV: arguments are checked against the service's list before anything is sent."""
        spec = pi.PI_SERVICES.get(service)
        if spec is not None and pi.is_nc_service(service) and len(arguments) != len(spec.argument_names):
            raise NckConfigError(f"{service} takes {len(spec.argument_names)} arguments "
                                 f"({', '.join(spec.argument_names)}), got {len(arguments)}")
        if any(not a.isascii() or len(a) > 255 for a in arguments):
            raise NckConfigError("PI arguments are ASCII strings of at most 255 characters")
        await self.exchange(pi.build_pi_request(pi.PiServiceRequest(service, tuple(arguments))))

    async def login(self, password: str) -> None:
        try:
            await self.pi_service("_N_LOGIN_", "/NC", password)
        except NckServiceError as exc:
            if exc.header_error not in PASSWORD_REFUSED:
                raise
            raise service_error_for(exc.error_class, exc.error_code,
                                    f"password refused: the controller does not know this password "
                                    f"(header error 0x{exc.header_error:04X})") from None

    # ------------------------------------------------------------------ PLC memory (S7ANY)
    async def db_read(self, db_number: int, start: int, size: int) -> bytes:
        return bytes(await self._on_connection(f"DB{db_number}.DBB{start} read ({size} bytes)",
                                               lambda client: client.db_read(db_number, start, size)))

    async def plc_read(self, area: int, db_number: int, start: int, size: int) -> bytes:
        """Bytes of a PLC area (inputs, outputs, flags, a DB), as python-snap7's ``read_area``."""
        try:
            snap7_area = Area(int(area))
        except ValueError:
            raise NckConfigError(f"python-snap7 cannot read area 0x{int(area):02X}") from None
        return bytes(await self._on_connection(f"area 0x{int(area):02X} byte {start} read ({size} bytes)",
                                               lambda client: client.read_area(snap7_area, db_number, start, size)))

    async def db_write(self, db_number: int, start: int, data: bytes) -> None:
        await self._on_connection(f"DB{db_number}.DBB{start} write ({len(data)} bytes)",
                                  lambda client: client.db_write(db_number, start, bytearray(data)))
