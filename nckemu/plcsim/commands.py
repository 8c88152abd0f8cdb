"""``nckemu plc run``."""

from __future__ import annotations

import argparse
import json
import math

from nckemu.cliutil import working
from nckemu.errors import NckConfigError


def _duration_s(text: str) -> float:
    units = {"s": 1.0, "min": 60.0, "m": 60.0, "h": 3600.0}
    for suffix, factor in sorted(units.items(), key=lambda kv: -len(kv[0])):
        if text.endswith(suffix):
            return float(text[: -len(suffix)]) * factor
    return float(text)


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    plc = subparsers.add_parser("plc", help="run a PLC program (STL/AWL) in awlsim against the emulator")
    commands = plc.add_subparsers(dest="plc_command", metavar="COMMAND")
    run = commands.add_parser(
        "run", help="run an STL program on simulated time", formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: nckemu plc run fixtures/plc/tc_z.awl --machine fixtures/machines/bed_ramp.toml "
               "--duration 2h\n")
    run.add_argument("program", help="STL source with OB1 (FB3 \"PUT\" is provided by nckemu)")
    run.add_argument("--machine", help="machine TOML for the in-process emulator (sensor profiles drive the "
                                       "analog inputs)")
    run.add_argument("--emulator", metavar="HOST:PORT",
                     help="run against this controller (a running `nckemu serve` or a real NCK) in real time, "
                          "instead of an in-process emulator on simulated time")
    run.add_argument("--speed", default="max",
                     help="simulated time per real time, e.g. 1000x or 1x; max runs as fast as possible (max)")
    run.add_argument("--duration", default="2h", help="simulated time, e.g. 2h, 30min, 600s (2h)")
    run.add_argument("--cycle", default="1s", help="simulated PLC cycle time (1s)")
    run.add_argument("--axis", type=int, default=4, help="machine axis whose compensation is reported (4)")
    run.add_argument("--json", action="store_true", help="print samples, jobs and errors as JSON on stdout")
    run.set_defaults(func=run_plc)
    stubs = commands.add_parser("stubs", help="write the FB2/FB3/FB4 stub sources (for awlsim with -H nckemu)",
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="example: nckemu plc stubs stubs/ --json\n")
    stubs.add_argument("directory", help="where to write fb2_get.awl, fb3_put.awl and fb4_pi_serv.awl "
                                         "(created if missing)")
    stubs.add_argument("--json", action="store_true", help="print the written files as JSON on stdout")
    stubs.set_defaults(func=write_stubs)
    plc.set_defaults(func=lambda args: plc.print_help() or 2)


def _speed(text: str) -> float | None:
    if text.lower() == "max":
        return None
    try:
        speed = float(text.lower().removesuffix("x"))
    except ValueError:
        raise NckConfigError(f"--speed {text!r}: expected e.g. 1000x, 1x or max") from None
    if speed <= 0:
        raise NckConfigError("--speed must be positive")
    return speed


def write_stubs(args: argparse.Namespace) -> int:
    import shutil
    from pathlib import Path

    from .bridge import STUB_SOURCES

    target = Path(args.directory)
    if target.exists() and not target.is_dir():
        raise NckConfigError("exists and is not a directory: give a directory for the stub sources",
                             path=args.directory)
    try:
        target.mkdir(parents=True, exist_ok=True)
        written = []
        for source in STUB_SOURCES:
            shutil.copyfile(source, target / source.name)
            written.append(str(target / source.name))
    except OSError as exc:
        raise NckConfigError(f"cannot write the stub sources: {exc.strerror}",
                             path=exc.filename or args.directory) from None
    print(json.dumps({"directory": str(target), "files": written}) if args.json else "\n".join(written))
    return 0


def run_plc(args: argparse.Namespace) -> int:
    from .run import run_program

    try:
        duration_s, cycle_s = _duration_s(args.duration), _duration_s(args.cycle)
    except ValueError:
        raise NckConfigError("--duration and --cycle take e.g. 2h, 30min, 600s") from None
    if duration_s <= 0 or cycle_s <= 0:
        raise NckConfigError("--duration and --cycle must be positive")
    speed = _speed(args.speed)
    if args.emulator and speed not in (None, 1.0):
        raise NckConfigError("--speed applies to the in-process emulator; --emulator runs in real time")
    with working("plc run", enabled=not args.json):
        result = run_program(args.program, machine=args.machine, emulator=args.emulator, duration_s=duration_s,
                             cycle_s=cycle_s, axis=args.axis, speed=speed)
    if args.json:
        samples = [{k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in vars(s).items()}
                   for s in result.samples]  # NaN (not measured) is not JSON
        print(json.dumps({"samples": samples,
                          "jobs": [vars(j) for j in result.log.jobs], "errors": result.log.errors}))
    else:
        print(f"{len(result.log.puts)} FB3 PUT jobs, {len(result.log.gets)} FB2 GET jobs, "
              f"{len(result.log.pi_calls)} FB4 PI_SERV jobs, {len(result.log.errors)} errors")
        for sample in result.samples[:: max(1, len(result.samples) // 12)]:
            print(f"t = {sample.time_s / 60:6.1f} min  sensor {sample.sensor_C:6.2f} degC  "
                  f"TC of axis {args.axis}: {sample.tc_value_mm:.4f} mm")
        for error in result.log.errors[:10]:
            print(f"error: {error}")
    return 1 if result.log.errors else 0
