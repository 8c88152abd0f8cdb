"""``nckemu get | put | pi | comp840c | lec``: one-shot client calls from the shell."""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import math
import sys
from pathlib import Path
from typing import Any, TypeVar

from nckemu.catalogue.edges import TOOL_OFFSETS
from nckemu.catalogue.names import PlcVariable, Variable, parse_item
from nckemu.cliutil import default_host, default_port, port_number
from nckemu.errors import NckConfigError, NckError
from nckemu.protocol.addresses import NckArea, NckType
from nckemu.protocol.codes import describe_return_code

from .async_client import MAX_VARIABLES, AsyncNckClient, ItemResult
from .channel840c import Channel840C
from .refusals import lines_context, ranges, tool_context, unit_context

log = logging.getLogger(__name__)
T = TypeVar("T")


def _connection_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", default=None,
                        help="controller or emulator address (default: $NCKEMU_HOST, else 127.0.0.1)")
    parser.add_argument("--port", type=port_number, default=None,
                        help="TCP port (default: $NCKEMU_PORT, else 102; make serve uses 1102)")
    parser.add_argument("--rack", type=int, default=0, help="rack of the called TSAP (0, as on every NCU)")
    parser.add_argument("--slot", type=int, default=4, help="4 = 840D sl NCK (some use 3), 2 = PLC")
    parser.add_argument("--timeout", type=float, default=5.0, help="seconds to wait for an answer")
    parser.add_argument("--json", action="store_true", help="print the result as JSON on stdout")


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    raw = argparse.RawDescriptionHelpFormatter
    names = ("Names (docs/addresses.md; nckemu vars shows each variable's range in both counts):\n"
             "  NC syntax counts indices from 0: R4, MD10000[1] (the second entry), SD43900[AX4],\n"
             "    actToolBasePos[AX4] = actToolBasePos[3], actSpeed[SP1] = actSpeed[0]\n"
             "  BTSS and OPC UA ids count lines from 1: /Channel/Parameter/R[u1,5] = R[u1,5] = R4,\n"
             "    R[u1,1,#5] = R0..R4 as an array\n"
             "  S7 names PLC memory: DB130.DBW0, M5.0, MB10, PIW420, DB130.DBD0:REAL")
    get = subparsers.add_parser(
        "get", help="read NCK variables (FB2 GET) and PLC memory (S7ANY)", formatter_class=raw,
        description=f"Read NCK variables or PLC addresses: up to 8 in one job (FB2's NumVar), more in several "
                    f"jobs one after the other (-v says so).\n\n{names}",
        epilog="examples:\n  nckemu get --port 1102 SD43900[AX4] SD43910[AX4] R5\n"
               "  nckemu get --port 1102 '/Channel/State/progStatus[u1]' "
               "'/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]'\n"
               "  nckemu get --port 1102 'R[u1,1,#5]' 'actToolBasePos[AX4]' 'MD10000[1]'\n"
               "  nckemu get --port 1102 DB130.DBW0 M5.0 PIW420\n")
    get.add_argument("variables", nargs="+", metavar="VAR",
                     help="e.g. SD43900[AX4], MD32750[AX4], R5 (axis variables need their axis), an OPC "
                          "UA node id ('/Channel/State/progStatus[u1]') or an S7 address (DB130.DBW0)")
    _connection_options(get)
    get.set_defaults(func=run_get)

    put = subparsers.add_parser(
        "put", help="write NCK variables and PLC memory in one job (FB3 PUT, S7ANY)", formatter_class=raw,
        description=f"Write NCK variables or PLC addresses: up to 8 in one job (FB3's NumVar), more in several "
                    f"jobs one after the other (-v says so; a refused item does not stop the later jobs); an "
                    f"array takes comma-separated values.\n\n{names}",
        epilog="examples:\n  nckemu put --port 1102 SD43900[AX4]=0.3 SD43920[AX4]=0\n"
               "  nckemu put --port 1102 'R[u1,1,#3]=1,2,3' DB130.DBW0=7 M5.0=1\n")
    put.add_argument("assignments", nargs="+", metavar="VAR=VALUE",
                     help="e.g. SD43900[AX4]=0.3 (a value in the variable's unit: mm, degC, ...) or DB130.DBW0=7; "
                          "up to 8 in one job")
    put.add_argument("--password", help="log in first (_N_LOGIN_), e.g. EVENING for machine data")
    put.add_argument("--real32", action="store_true", help="round REAL8 values through a 32-bit REAL, as a PLC")
    _connection_options(put)
    put.set_defaults(func=run_put)

    pi = subparsers.add_parser("pi", help="start a PI service (FB4 PI_SERV)", formatter_class=raw,
                               epilog="example: nckemu pi --port 1102 _N_SELECT 201 /_N_MPF_DIR/_N_TEST_MPF\n")
    pi.add_argument("service", help="the PI service's name, e.g. _N_SELECT, _N_LOGIN_, _N_CONFIG")
    pi.add_argument("arguments", nargs="*",
                    help="its arguments as strings, e.g. 201 /_N_MPF_DIR/_N_TEST_MPF for _N_SELECT")
    _connection_options(pi)
    pi.set_defaults(func=run_pi)

    comp = subparsers.add_parser(
        "comp840c", help="send 840C temperature compensation (user DB + DB41 function 9)", formatter_class=raw,
        epilog="examples:\n"
               "  nckemu comp840c --port 1102 --axis 4 --k0 0.3\n"
               "  nckemu comp840c --port 1102 --slot 2 --axis 4 --k0 0.3 --slope 0.00001 --p0 100 --flags UA\n")
    comp.add_argument("--axis", type=int, required=True, help="machine axis number, e.g. 4 (Z1 of the default machine)")
    comp.add_argument("--k0", type=float, default=0.0, help="K_TCabs in mm")
    comp.add_argument("--slope", type=float, default=0.0, help="tan(beta), dimensionless")
    comp.add_argument("--p0", type=float, default=None,
                      help="reference position P0 in mm, not the axis zero (needed with --flags A)")
    comp.add_argument("--flags", default=None,
                      help="U: position independent, A: position dependent (default: UA with --slope or "
                           "--p0, else U)")
    comp.add_argument("--db", type=int, default=131,
                      help="user DB number (131; the default machine has DB2, DB8, DB41, DB100, DB130, DB131)")
    comp.add_argument("--dw", type=int, default=0, help="first data word n in the user DB (0)")
    _connection_options(comp)
    comp.set_defaults(func=run_comp840c, slot=2)

    lec = subparsers.add_parser(
        "lec", help="load a leadscrew compensation table program into a running emulator", formatter_class=raw,
        description="Sends nckemu's PI service _N_NCKEMU_LEC with the program's path: the emulator reads the "
                    "file on its own host (the same machine for a loopback emulator). As on the control, tables "
                    "load only while MD32700 = 0 and act after power-on with MD32700 = 1 and the axis referenced.",
        epilog="example: nckemu lec --port 1102 --password EVENING --power-on fixtures/lec/z_axis.mpf\n")
    lec.add_argument("program", help="NC program with $AA_ENC_COMP[...] lines")
    lec.add_argument("--password", help="log in first (_N_LOGIN_): loading needs MD32700's write level")
    lec.add_argument("--power-on", action="store_true", help="then power on the NCK (_N_NCKRES)")
    _connection_options(lec)
    lec.set_defaults(func=run_lec)


def _client(args: argparse.Namespace) -> AsyncNckClient:
    if args.host is None:
        args.host = default_host()
    if args.port is None:
        args.port = default_port()
    if not args.timeout > 0:
        raise NckConfigError(f"--timeout {args.timeout}: expected a positive number of seconds")
    return AsyncNckClient(args.host, args.port, rack=args.rack, slot=args.slot, timeout_s=args.timeout,
                          plc_real32=getattr(args, "real32", False))


def _spec(variable: Variable | PlcVariable) -> Any:
    """The catalogue's row for a variable (limits, unit, access levels), None for an unknown address or
    PLC memory."""
    from nckemu.catalogue.table import spec_at

    return spec_at(variable.address) if isinstance(variable, Variable) else None


def _limits_text(spec: Any) -> str:
    unit = f" {spec.unit}" if spec.unit not in ("", "1") else ""
    low = "-inf" if spec.minimum is None else f"{spec.minimum:g}"
    high = "inf" if spec.maximum is None else f"{spec.maximum:g}"
    return f"{low}..{high}{unit}"


def _plc_refusal(variable: PlcVariable, code: str, return_code: int) -> str:
    where = f"DB{variable.db}" if variable.area == "DB" else f"the {variable.area} area"
    if return_code == 0x0A:
        return (f"{where} does not exist on the controller (an emulator's DBs: nckemu machine show; on an "
                f"840D sl the PLC is --slot 2): {code}")
    if return_code == 0x05:
        return f"bytes {variable.byte}..{variable.byte + max(1, variable.size_bytes) - 1} lie beyond the end of {where}: {code}"
    return code


def _why_refused(result: ItemResult, value: Any, context: str = "") -> str:
    """What a refused item means in words, then the controller's code."""
    code = describe_return_code(result.return_code)
    if isinstance(result.variable, PlcVariable):
        return _plc_refusal(result.variable, code, result.return_code)
    spec = _spec(result.variable)
    if spec is None:
        return code
    notes = []
    if value is not None and _outside_limits(spec, value):
        numbers = value if isinstance(value, list | tuple) else [value]
        unit = f" {spec.unit}" if spec.unit not in ("", "1") else ""
        if any(isinstance(v, float) and not math.isfinite(v) for v in numbers):
            notes.append(f"{value!r} is not a finite number (limits {_limits_text(spec)})")
        else:
            shown = ", ".join(f"{v:g}" for v in numbers)
            notes.append(f"{shown}{unit} is outside its limits {_limits_text(spec)}")
    elif result.return_code == 0x05 or (result.return_code == 0x0A and context):
        notes.append(_range_note(result.variable, spec, context))
    if result.return_code == 0x03:
        notes.append(f"writing it needs access level {spec.write_level} or higher (give --password)"
                     if spec.write_level >= 0 else "it is read-only")
    return f"{'; '.join(notes)}; the controller answered {code}" if notes else code


def _outside_limits(spec: Any, value: Any) -> bool:
    """A written value the variable's limits refuse (not finite, or outside min..max)."""
    numbers = value if isinstance(value, list | tuple) else [value]
    return any(isinstance(v, float) and not math.isfinite(v) for v in numbers) or any(
        isinstance(v, int | float) and ((spec.minimum is not None and v < spec.minimum)
                                        or (spec.maximum is not None and v > spec.maximum)) for v in numbers)


def _range_note(variable: Variable, spec: Any, context: str) -> str:
    """A refused address (0x05, 0x0A) in words: which line or unit the machine lacks, and the valid range."""
    from nckemu.catalogue.grammar import display_btss, index_ranges

    machine = f": {context}" if context else " (it may have fewer than the catalogue)"
    return (f"not on this machine (BTSS {display_btss(spec, variable.address)}){machine}; {spec.name} takes "
            f"{index_ranges(spec)}")


async def _machine_context(client: AsyncNckClient, variable: Variable) -> str:
    """What a machine has where a refused address points: its axes (with their names, from MD10000)
    for an axis variable or a line that is a machine axis, its spindles for a spindle line. Read from
    the controller; "" where it does not answer."""
    from nckemu.catalogue.table import line_kind, spec_at

    spec = spec_at(variable.address)
    if spec is None:
        return ""
    kind = "machine axis" if variable.address.area == NckArea.A else line_kind(spec)
    try:
        if kind == "machine axis":
            (highest,) = await client.get("maxnumGlobMachAxes")
            highest = max(0, min(int(highest), 31))
            names: list[str] = []
            for first in range(1, highest + 1, 16):  # 16 names of 32 bytes fit any PDU
                count = min(16, highest - first + 1)
                (chunk,) = await client.get(f"MD10000[u1,{first},#{count}]")
                names += chunk if isinstance(chunk, list) else [chunk]
            axes = [f"AX{number} {name}" for number, name in enumerate(names, start=1) if name]
            numbers = [number for number, name in enumerate(names, start=1) if name]
            btss = ranges(numbers, "u") if variable.address.area == NckArea.A else f"lines {ranges(numbers, '')}"
            return f"its machine axes are {', '.join(axes)} (BTSS {btss})" if axes else "it has no machine axes"
        if kind == "spindle":
            (count,) = await client.get(f"numSpindles[C{variable.address.unit}]")
            count = int(count)
            if count < 1:
                return f"channel {variable.address.unit} has no spindle"
            return (f"channel {variable.address.unit} has {count} spindle{'s' if count > 1 else ''}: "
                    f"SP1{f'..SP{count}' if count > 1 else ''}")
        if spec.name == TOOL_OFFSETS:
            return await tool_context(client, variable)
        if variable.address.area in (NckArea.V, NckArea.H):
            return await unit_context(client, spec, variable, "drive", "drives")
        if variable.address.area == NckArea.C:
            (count,) = await client.get("numChannels")
            count = int(count)
            if 1 <= variable.address.unit <= count and spec.lines > 1 and kind is None:
                return await lines_context(client, spec, variable)
            return (f"this machine has {count} channel{'s' if count != 1 else ''}: C1"
                    f"{f'..C{count}' if count > 1 else ''} (NC) or u1{f'..{count}' if count > 1 else ''} (BTSS)")
    except (NckError, ValueError, TypeError):
        return ""
    return ""


def _record(result: ItemResult) -> dict[str, Any]:
    variable = result.variable
    if isinstance(variable, PlcVariable):
        return {"name": str(variable), "plc": {"area": variable.area, "db": variable.db, "byte": variable.byte,
                                               "bit": variable.bit, "type": variable.kind, "count": variable.count},
                "return_code": result.return_code, "ok": result.ok, "value": result.value}
    from nckemu.catalogue.grammar import display_btss, display_node_id

    address = variable.address
    spec = _spec(variable)
    forms = {"btss": display_btss(spec, address), "opcua": display_node_id(spec, address)} if spec else {}
    return {"name": str(variable), **forms, "area": address.area, "unit": address.unit,
            "column": address.column, "line": address.line, "module": address.module,
            "line_count": address.line_count, "return_code": result.return_code,
            "ok": result.ok, "value": result.value, "unit_of_measure": variable.unit_of_measure}


def _print_results(results: list[ItemResult], as_json: bool, written: list[Any] | None = None,
                   contexts: dict[int, str] | None = None) -> int:
    failed = [(r, written[i] if written else None, (contexts or {}).get(i, ""))
              for i, r in enumerate(results) if not r.ok]
    if as_json:
        print(json.dumps([_record(r) for r in results]))
    else:
        for result in results:
            if result.ok:
                value = result.value
                shown = f"{value:.6f}" if isinstance(value, float) else value
                measure = getattr(result.variable, "unit_of_measure", "")
                suffix = f" {measure}" if measure not in ("", "1") else ""
                print(f"{result.variable} = {shown}{suffix}" if result.value is not None
                      else f"{result.variable}: ok")
    for result, value, context in failed:
        print(f"nckemu: {result.variable}: {_why_refused(result, value, context)}", file=sys.stderr)
    return 1 if failed else 0


def _parse(text: str) -> Variable | PlcVariable:
    """A variable name; an axis variable without its axis is refused (it would silently be AX1)."""
    variable = parse_item(text)
    spec = _spec(variable)
    if spec is not None and spec.areas == {NckArea.A} and "[" not in text and not text.strip().startswith("/"):
        raise NckConfigError(f"{text!r}: {spec.number or spec.name} is an axis variable: say which axis, "
                             f"e.g. {text.strip()}[AX4]")
    return variable


async def _contexts(client: AsyncNckClient, results: list[ItemResult],
                    written: list[Any] | None = None) -> dict[int, str]:
    """For each item refused as an invalid address (0x05) or a missing object (0x0A), what the machine
    has there (not for a written value outside its limits: that is why it was refused)."""
    contexts = {}
    for index, result in enumerate(results):
        if result.return_code not in (0x05, 0x0A) or not isinstance(result.variable, Variable):
            continue
        spec = _spec(result.variable)
        if written is not None and spec is not None and _outside_limits(spec, written[index]):
            continue
        contexts[index] = await _machine_context(client, result.variable)
    return contexts


def _jobs(items: list[T], verb: str) -> list[list[T]]:
    """Items in jobs of at most 8 (NumVar of FB2/FB3, and what a controller takes in one job), in
    order; -v says when there is more than one."""
    jobs = [items[first:first + MAX_VARIABLES] for first in range(0, len(items), MAX_VARIABLES)]
    if len(jobs) > 1:
        log.info("%d names %s in %d jobs of up to %d (one job takes at most %d)", len(items), verb, len(jobs),
                 MAX_VARIABLES, MAX_VARIABLES)
    return jobs


def run_get(args: argparse.Namespace) -> int:
    variables = [_parse(v) for v in args.variables]

    async def go() -> tuple[list[ItemResult], dict[int, str]]:
        async with _client(args) as client:
            results = []
            for chunk in _jobs(variables, "read"):
                results += await client.get_items(*chunk)
            return await _with_edge_units(client, results), await _contexts(client, results)

    results, contexts = asyncio.run(go())
    return _print_results(results, args.json, contexts=contexts)


async def _with_edge_units(client: AsyncNckClient, results: list[ItemResult]) -> list[ItemResult]:
    """Tool offsets carry each parameter's own unit (mm for lengths and radii, none for the type or a
    count), which needs the machine's numCuttEdgeParams to tell the parameter from the line."""
    from dataclasses import replace

    from nckemu.catalogue.edges import STANDARD_EDGE_PARAMS, lines_unit

    edges = [index for index, result in enumerate(results)
             if isinstance(result.variable, Variable) and (spec := _spec(result.variable)) is not None
             and spec.name == TOOL_OFFSETS]
    if not edges:
        return results
    try:
        (per_edge,) = await client.get("numCuttEdgeParams")
        per_edge = max(1, int(per_edge))
    except (NckError, ValueError, TypeError):
        per_edge = STANDARD_EDGE_PARAMS
    changed = list(results)
    for index in edges:
        variable = results[index].variable
        unit = lines_unit(variable.address.line, variable.address.line_count, per_edge)
        changed[index] = replace(results[index], variable=replace(variable, unit_of_measure=unit))
    return changed


_INTEGER_RANGES = {NckType.BOOL: (0, 1), NckType.BYTE: (0, 0xFF), NckType.WORD: (0, 0xFFFF),
                   NckType.INT: (-0x8000, 0x7FFF), NckType.DWORD: (0, 0xFFFFFFFF),
                   NckType.DINT: (-0x80000000, 0x7FFFFFFF), NckType.INT64: (-(1 << 63), (1 << 63) - 1)}
_TRUE, _FALSE = ("1", "true", "on"), ("0", "false", "off")


def _parse_one(variable: Variable | PlcVariable, text: str) -> Any:
    if isinstance(variable, PlcVariable):
        if variable.kind == "STRING":
            return text
        if variable.kind == "BOOL":
            if text.strip().lower() not in _TRUE + _FALSE:
                raise NckConfigError(f"{variable}: {text!r} is not a bit (0/1, true/false, on/off)")
            return text.strip().lower() in _TRUE
        kind = variable.kind
        number: Any = float(text) if kind == "REAL" else int(text, 0)
        if kind != "REAL":
            from nckemu.catalogue.names import PLC_RANGES

            low, high = PLC_RANGES[kind]
            if not low <= number <= high:
                raise NckConfigError(f"{variable}: {number} is not a {kind} ({low}..{high})")
        return number
    if variable.nck_type in (NckType.REAL4, NckType.REAL8):
        return float(text)
    if variable.nck_type == NckType.STRING:
        return text
    value = int(text, 0)
    low, high = _INTEGER_RANGES.get(variable.nck_type, (value, value))
    if not low <= value <= high:
        raise NckConfigError(f"{variable}: {value} is not a {variable.nck_type.name} ({low}..{high})")
    return value


def _parse_value(variable: Variable | PlcVariable, text: str) -> Any:
    """One value, or comma-separated values for an array (``R[u1,1,#3]=1,2,3``, ``DB2.DBD0:REAL[2]=1,2``)."""
    count = variable.address.line_count if isinstance(variable, Variable) else \
        (variable.count if variable.array else 1)
    kind = variable.kind if isinstance(variable, PlcVariable) else variable.nck_type.name
    try:
        if count == 1:
            return _parse_one(variable, text)
        parts = text.split(",")
        if len(parts) != count:
            raise NckConfigError(f"{variable}: {len(parts)} values for {count} elements (comma-separated)")
        return [_parse_one(variable, part) for part in parts]
    except ValueError:
        raise NckConfigError(f"{variable}: {text!r} is not a {kind} value") from None


def run_put(args: argparse.Namespace) -> int:
    pairs = []
    for assignment in args.assignments:
        name, sep, text = assignment.partition("=")
        if not sep:
            raise NckConfigError(f"{assignment!r}: expected VAR=VALUE")
        variable = _parse(name)
        pairs.append((variable, _parse_value(variable, text)))

    async def go() -> tuple[list[ItemResult], dict[int, str]]:
        async with _client(args) as client:
            if args.password:
                await client.login(args.password)
            results = []
            for chunk in _jobs(pairs, "written"):
                results += await client.put_items(chunk)
            return results, await _contexts(client, results, [v for _, v in pairs])

    results, contexts = asyncio.run(go())
    return _print_results([ItemResult(r.variable, r.return_code, v if r.ok else None)
                           for r, (_, v) in zip(results, pairs, strict=True)], args.json,
                          written=[v for _, v in pairs], contexts=contexts)


def run_pi(args: argparse.Namespace) -> int:
    async def go() -> None:
        async with _client(args) as client:
            await client.pi_service(args.service, *args.arguments)

    try:
        asyncio.run(go())
    except NckError as exc:
        if args.json:
            print(json.dumps({"service": args.service, "ok": False, "error": str(exc),
                              "error_class": exc.error_class, "error_code": exc.error_code}))
        raise
    print(json.dumps({"service": args.service, "ok": True}) if args.json else f"{args.service}: done")
    return 0


def run_comp840c(args: argparse.Namespace) -> int:
    if args.flags is None:
        args.flags = "UA" if args.slope or args.p0 is not None else "U"
    flags = args.flags.upper()
    if not flags or set(flags) - {"U", "A"}:
        raise NckConfigError(f"--flags {args.flags!r}: only U and A")
    if "A" in flags and not args.p0:
        raise NckConfigError("--flags A (position dependent) needs --p0, a reference position other than 0: "
                             "the 840C refuses P0 at the axis zero point (channel error 10)")
    p0_mm = args.p0 or 0.0

    async def go() -> None:
        async with _client(args) as client:
            try:
                await Channel840C(client, user_db=args.db, data_word=args.dw).send(
                    args.axis, args.k0, args.slope, p0_mm, "U" in flags, "A" in flags)
            except NckError as exc:
                if exc.return_code != 0x0A:
                    raise
                raise type(exc)(f"user DB{args.db} does not exist on the controller (--db names it; "
                                f"`nckemu machine show` lists an emulator's DBs): "
                                f"{describe_return_code(0x0A)}", return_code=0x0A) from None

    asyncio.run(go())
    print(json.dumps({"axis": args.axis, "ok": True}) if args.json else f"840C TC sent for axis {args.axis}")
    return 0


def _check_leadscrew_program(path: Path) -> None:
    """Syntax, index gaps and parameters, checked here so that errors name the line; the axes and
    MD38000 are checked by the controller."""
    from nckemu.catalogue.leadscrew import parse_leadscrew_program

    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise NckConfigError(f"cannot read: {exc}", path=str(path)) from None
    axes: dict[str, int] = {}
    tables = parse_leadscrew_program(text, str(path), lambda ref: axes.setdefault(ref.upper(), len(axes) + 1),
                                     lambda _axis, _encoder: 1 << 30)
    if not tables:
        raise NckConfigError("no leadscrew table in it (expected $AA_ENC_COMP[...] lines); nothing sent",
                             path=str(path))


def run_lec(args: argparse.Namespace) -> int:
    from nckemu.catalogue.pi_services import PI_LOAD_LEADSCREW, PI_POWER_ON

    path = Path(args.program).resolve()
    _check_leadscrew_program(path)

    async def go() -> None:
        async with _client(args) as client:
            if args.password:
                await client.login(args.password)
            try:
                await client.pi_service(PI_LOAD_LEADSCREW, "/NC", str(path))
            except NckError as exc:
                if exc.header_error == 0x8703:
                    why = ("the access level is too low: loading needs MD32700's write level "
                           "(log in with --password, e.g. EVENING)")
                else:
                    why = "the controller refused the table; the emulator's log (nckemu serve) says why"
                raise type(exc)(f"{path}: {why} ({exc})",
                                error_class=exc.error_class, error_code=exc.error_code) from None
            if args.power_on:
                await client.pi_service(PI_POWER_ON, "/NC")

    asyncio.run(go())
    done = "loaded and powered on" if args.power_on else "loaded; active after power-on"
    print(json.dumps({"program": str(path), "ok": True, "power_on": args.power_on}) if args.json
          else f"{path}: {done}")
    return 0
