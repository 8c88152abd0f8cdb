"""FB2 GET, FB3 PUT and FB4 PI_SERV as the PLC sees them, cycle by cycle.

Call ``cycle(...)`` once per simulated PLC cycle with the block's inputs; it returns the outputs.
A job starts on a rising edge of ``Req``; the network work runs in the background (the cycle never
blocks); ``Done``/``NDR`` or ``Error`` is true for exactly one cycle when the job ends, with
``State``: low byte = number of the faulty variable (1..8) or a general code, high byte = class.

ASSUMPTION: the exact State values of the SINUMERIK blocks are not in our sources. They live in
``STATE_*`` below, in one place, to be corrected from the P3 function manual.
"""

from __future__ import annotations

import concurrent.futures
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from nckemu.catalogue.names import Variable, as_variable, with_overrides
from nckemu.errors import NckConnectionError, NckError, NckServiceError, NckTimeoutError

from .async_client import MAX_VARIABLES, ItemResult, to_real32
from .sync import NckClient

STATE_OK = 0x0000
# General errors: high byte 0x80 (class "general"), low byte the code.
STATE_GENERAL_CLASS = 0x80
STATE_NUMVAR_INVALID = 0x8001
STATE_TIMEOUT = 0x8002
STATE_CONNECTION_LOST = 0x8003
STATE_NEGATIVE_ACK = 0x8004
STATE_PARAMETER_ERROR = 0x8005
# Item errors: high byte = the item return code (e.g. 0x0A object does not exist), low byte = variable.


def item_state(return_code: int, variable_number: int) -> int:
    return (return_code << 8) | variable_number


@dataclass(frozen=True)
class FbOutputs:
    Done: bool = False     # NDR for GET
    Error: bool = False
    State: int = STATE_OK
    Busy: bool = False
    values: tuple[Any, ...] = ()   # RD1..RD8 after a GET


class _Block:
    """Edge detection, background job and one-cycle result, shared by GET, PUT and PI_SERV."""

    def __init__(self, client: NckClient) -> None:
        self.client = client
        self._previous_req = False
        self._job: concurrent.futures.Future[Any] | None = None

    def _step(self, req: bool, start: Any) -> FbOutputs:
        rising = req and not self._previous_req
        self._previous_req = req
        if self._job is not None:
            if not self._job.done():
                return FbOutputs(Busy=True)
            job, self._job = self._job, None
            return self._finish(job)
        if rising:
            try:
                self._job = start()
            except NckError as exc:
                return FbOutputs(Error=True, State=_state_of(exc))
            return FbOutputs(Busy=True)
        return FbOutputs()

    def _finish(self, job: concurrent.futures.Future[Any]) -> FbOutputs:
        try:
            result = job.result()
        except NckError as exc:
            return FbOutputs(Error=True, State=_state_of(exc))
        return self._outputs(result)

    def _outputs(self, result: Any) -> FbOutputs:
        return FbOutputs(Done=True)


def _state_of(exc: NckError) -> int:
    if isinstance(exc, NumVarError):
        return STATE_NUMVAR_INVALID
    if isinstance(exc, NckTimeoutError):
        return STATE_TIMEOUT
    if isinstance(exc, NckConnectionError):
        return STATE_CONNECTION_LOST
    if isinstance(exc, NckServiceError):
        return STATE_NEGATIVE_ACK
    return STATE_PARAMETER_ERROR


def _item_outputs(results: list[ItemResult], values: bool) -> FbOutputs:
    for number, result in enumerate(results, start=1):
        if not result.ok:
            return FbOutputs(Error=True, State=item_state(result.return_code, number))
    return FbOutputs(Done=True, values=tuple(r.value for r in results) if values else ())


class NumVarError(NckError):
    """NumVar outside 1..8, or fewer Addr/SD than NumVar."""


def _pick(values: Sequence[int | None] | None, index: int) -> int | None:
    return values[index] if values is not None and index < len(values) else None


def _variables(num_var: int, addresses: Sequence[object], units: Sequence[int | None] | None,
               columns: Sequence[int | None] | None, lines: Sequence[int | None] | None) -> list[Variable]:
    if not 1 <= num_var <= MAX_VARIABLES or len(addresses) < num_var:
        raise NumVarError(f"NumVar = {num_var} with {len(addresses)} addresses")
    return [with_overrides(as_variable(addresses[i]), _pick(units, i), _pick(columns, i), _pick(lines, i))
            for i in range(num_var)]


class FbPut(_Block):
    """FB3 PUT. ``real32`` (default on) passes REAL8 values through a 32-bit REAL as the PLC does."""

    def __init__(self, client: NckClient, *, real32: bool = True) -> None:
        super().__init__(client)
        self.real32 = real32

    def cycle(self, Req: bool, NumVar: int, Addr: Sequence[object], SD: Sequence[Any],  # noqa: N803
              Unit: Sequence[int | None] | None = None, Column: Sequence[int | None] | None = None,  # noqa: N803
              Line: Sequence[int | None] | None = None) -> FbOutputs:  # noqa: N803
        def start() -> concurrent.futures.Future[Any]:
            variables = _variables(NumVar, Addr, Unit, Column, Line)
            if len(SD) < NumVar:
                raise NumVarError(f"NumVar = {NumVar} with {len(SD)} SD values")
            values = [to_real32(float(v)) if self.real32 and isinstance(v, float) else v for v in SD[:NumVar]]
            return self.client.submit(self.client.async_client.put_items(list(zip(variables, values, strict=True))))
        return self._step(Req, start)

    def _outputs(self, result: Any) -> FbOutputs:
        return _item_outputs(result, values=False)


class FbGet(_Block):
    """FB2 GET: ``Done`` of the outputs is the block's NDR; ``values`` are RD1..RDn."""

    def __init__(self, client: NckClient, *, real32: bool = True) -> None:
        super().__init__(client)
        self.real32 = real32

    def cycle(self, Req: bool, NumVar: int, Addr: Sequence[object],  # noqa: N803
              Unit: Sequence[int | None] | None = None, Column: Sequence[int | None] | None = None,  # noqa: N803
              Line: Sequence[int | None] | None = None) -> FbOutputs:  # noqa: N803
        def start() -> concurrent.futures.Future[Any]:
            variables = _variables(NumVar, Addr, Unit, Column, Line)
            return self.client.submit(self.client.async_client.get_items(*variables))
        return self._step(Req, start)

    def _outputs(self, result: Any) -> FbOutputs:
        outputs = _item_outputs(result, values=True)
        if self.real32 and outputs.values:
            converted = tuple(to_real32(v) if isinstance(v, float) else v for v in outputs.values)
            return FbOutputs(Done=True, values=converted)
        return outputs


class FbPiServ(_Block):
    """FB4 PI_SERV: ``PIService`` is the service name, ``Addr`` its string arguments."""

    def cycle(self, Req: bool, PIService: str, Addr: Sequence[str] = ()) -> FbOutputs:  # noqa: N803
        def start() -> concurrent.futures.Future[Any]:
            return self.client.submit(self.client.async_client.pi_service(PIService, *Addr))
        return self._step(Req, start)
