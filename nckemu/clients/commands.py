"""``nckemu get | put | pi | comp840c | lec``: one-shot client calls from the shell."""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
from pathlib import Path
from typing import Any

from nckemu.catalogue.names import Variable, parse_variable
from nckemu.errors import NckConfigError, NckError
from nckemu.protocol.addresses import NckType
from nckemu.protocol.codes import describe_return_code

from .async_client import AsyncNckClient, ItemResult
from .channel840c import Channel840C


def _connection_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", default="127.0.0.1", help="controller or emulator address (127.0.0.1)")
    parser.add_argument("--port", type=int, default=102, help="TCP port (102)")
    parser.add_argument("--rack", type=int, default=0)
    parser.add_argument("--slot", type=int, default=4, help="4 = 840D sl NCK (some use 3), 2 = PLC")
    parser.add_argument("--timeout", type=float, default=5.0, help="seconds to wait for an answer")
    parser.add_argument("--json", action="store_true", help="machine-readable output")


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    raw = argparse.RawDescriptionHelpFormatter
    get = subparsers.add_parser("get", help="read NCK variables (FB2 GET)", formatter_class=raw,
                                epilog="example: nckemu get --port 1102 SD43900[AX4] SD43910[AX4] R5")
    get.add_argument("variables", nargs="+", metavar="VAR", help="e.g. SD43900[AX4], MD32750[AX4], R5")
    _connection_options(get)
    get.set_defaults(func=run_get)

    put = subparsers.add_parser("put", help="write NCK variables in one job (FB3 PUT)", formatter_class=raw,
                                epilog="example: nckemu put --port 1102 SD43900[AX4]=0.3 SD43920[AX4]=0")
    put.add_argument("assignments", nargs="+", metavar="VAR=VALUE")
    put.add_argument("--password", help="log in first (_N_LOGIN_), e.g. EVENING for machine data")
    put.add_argument("--real32", action="store_true", help="round REAL8 values through a 32-bit REAL, as a PLC")
    _connection_options(put)
    put.set_defaults(func=run_put)

    pi = subparsers.add_parser("pi", help="start a PI service (FB4 PI_SERV)", formatter_class=raw,
                               epilog="example: nckemu pi --port 1102 _N_SELECT 201 /_N_MPF_DIR/_N_TEST_MPF")
    pi.add_argument("service")
    pi.add_argument("arguments", nargs="*")
    _connection_options(pi)
    pi.set_defaults(func=run_pi)

    comp = subparsers.add_parser(
        "comp840c", help="send 840C temperature compensation (user DB + DB41 function 9)", formatter_class=raw,
        epilog="example: nckemu comp840c --port 1102 --slot 2 --axis 4 --k0 0.3 --slope 0 --p0 100 --flags UA")
    comp.add_argument("--axis", type=int, required=True)
    comp.add_argument("--k0", type=float, default=0.0, help="K_TCabs in mm")
    comp.add_argument("--slope", type=float, default=0.0, help="tan(beta), dimensionless")
    comp.add_argument("--p0", type=float, default=0.0, help="reference position P0 in mm (not the axis zero)")
    comp.add_argument("--flags", default="UA", help="U: position independent, A: position dependent")
    comp.add_argument("--db", type=int, default=131, help="user DB number (131)")
    comp.add_argument("--dw", type=int, default=0, help="first data word n in the user DB (0)")
    _connection_options(comp)
    comp.set_defaults(func=run_comp840c, slot=2)

    lec = subparsers.add_parser(
        "lec", help="load a leadscrew compensation table program into a running emulator", formatter_class=raw,
        description="Sends nckemu's PI service _N_NCKEMU_LEC with the program's path: the emulator reads the "
                    "file on its own host (the same machine for a loopback emulator). As on the control, tables "
                    "load only while MD32700 = 0 and act after power-on with MD32700 = 1 and the axis referenced.",
        epilog="example: nckemu lec --port 1102 --password EVENING --power-on fixtures/lec/x_axis.mpf")
    lec.add_argument("program", help="NC program with $AA_ENC_COMP[...] lines")
    lec.add_argument("--password", help="log in first (_N_LOGIN_): loading needs MD32700's write level")
    lec.add_argument("--power-on", action="store_true", help="then power on the NCK (_N_NCKRES)")
    _connection_options(lec)
    lec.set_defaults(func=run_lec)


def _client(args: argparse.Namespace) -> AsyncNckClient:
    return AsyncNckClient(args.host, args.port, rack=args.rack, slot=args.slot, timeout_s=args.timeout,
                          plc_real32=getattr(args, "real32", False))


def _record(result: ItemResult) -> dict[str, Any]:
    address = result.variable.address
    return {"name": str(result.variable), "area": address.area, "unit": address.unit,
            "column": address.column, "line": address.line, "module": address.module,
            "line_count": address.line_count, "return_code": result.return_code,
            "ok": result.ok, "value": result.value, "unit_of_measure": result.variable.unit_of_measure}


def _print_results(results: list[ItemResult], as_json: bool) -> int:
    failed = [r for r in results if not r.ok]
    if as_json:
        print(json.dumps([_record(r) for r in results]))
    else:
        for result in results:
            if result.ok:
                value = result.value
                shown = f"{value:.6f}" if isinstance(value, float) else value
                suffix = f" {result.variable.unit_of_measure}" if result.variable.unit_of_measure not in ("", "1") else ""
                print(f"{result.variable} = {shown}{suffix}" if result.value is not None
                      else f"{result.variable}: ok")
    for result in failed:
        print(f"nckemu: {result.variable}: {describe_return_code(result.return_code)}", file=sys.stderr)
    return 1 if failed else 0


def run_get(args: argparse.Namespace) -> int:
    variables = [parse_variable(v) for v in args.variables]

    async def go() -> list[ItemResult]:
        async with _client(args) as client:
            return await client.get_items(*variables)

    return _print_results(asyncio.run(go()), args.json)


def _parse_value(variable: Variable, text: str) -> Any:
    try:
        if variable.nck_type in (NckType.REAL4, NckType.REAL8):
            return float(text)
        if variable.nck_type == NckType.STRING:
            return text
        return int(text, 0)
    except ValueError:
        raise NckConfigError(f"{variable}: {text!r} is not a {variable.nck_type.name} value") from None


def run_put(args: argparse.Namespace) -> int:
    pairs = []
    for assignment in args.assignments:
        name, sep, text = assignment.partition("=")
        if not sep:
            raise NckConfigError(f"{assignment!r}: expected VAR=VALUE")
        variable = parse_variable(name)
        pairs.append((variable, _parse_value(variable, text)))

    async def go() -> list[ItemResult]:
        async with _client(args) as client:
            if args.password:
                await client.login(args.password)
            return await client.put_items(pairs)

    results = asyncio.run(go())
    return _print_results([ItemResult(r.variable, r.return_code, v if r.ok else None)
                           for r, (_, v) in zip(results, pairs, strict=True)], args.json)


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
    flags = args.flags.upper()
    if set(flags) - {"U", "A"}:
        raise NckConfigError(f"--flags {args.flags!r}: only U and A")

    async def go() -> None:
        async with _client(args) as client:
            await Channel840C(client, user_db=args.db, data_word=args.dw).send(
                args.axis, args.k0, args.slope, args.p0, "U" in flags, "A" in flags)

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
    parse_leadscrew_program(text, str(path), lambda ref: axes.setdefault(ref.upper(), len(axes) + 1),
                            lambda _axis, _encoder: 1 << 30)


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
                raise type(exc)(f"{path}: the controller refused the table ({exc}); its log names the line",
                                error_class=exc.error_class, error_code=exc.error_code) from None
            if args.power_on:
                await client.pi_service(PI_POWER_ON, "/NC")

    asyncio.run(go())
    done = "loaded and powered on" if args.power_on else "loaded; active after power-on"
    print(json.dumps({"program": str(path), "ok": True, "power_on": args.power_on}) if args.json
          else f"{path}: {done}")
    return 0
