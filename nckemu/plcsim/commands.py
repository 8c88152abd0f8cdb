"""``nckemu plc run``."""

from __future__ import annotations

import argparse
import json

from nckemu.protocol.errors import NckConfigError


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
               "--duration 2h")
    run.add_argument("program", help="STL source with OB1 (FB3 \"PUT\" is provided by nckemu)")
    run.add_argument("--machine", help="machine TOML (sensor profiles drive the analog inputs)")
    run.add_argument("--duration", default="2h", help="simulated time, e.g. 2h, 30min, 600s (2h)")
    run.add_argument("--cycle", default="1s", help="simulated PLC cycle time (1s)")
    run.add_argument("--axis", type=int, default=4, help="machine axis whose compensation is reported (4)")
    run.add_argument("--json", action="store_true")
    run.set_defaults(func=run_plc)
    plc.set_defaults(func=lambda args: plc.print_help() or 2)


def run_plc(args: argparse.Namespace) -> int:
    from .run import run_program

    duration_s, cycle_s = _duration_s(args.duration), _duration_s(args.cycle)
    if duration_s <= 0 or cycle_s <= 0:
        raise NckConfigError("--duration and --cycle must be positive")
    result = run_program(args.program, machine=args.machine, duration_s=duration_s, cycle_s=cycle_s, axis=args.axis)
    if args.json:
        print(json.dumps({"samples": [vars(s) for s in result.samples],
                          "puts": [vars(p) for p in result.log.puts], "errors": result.log.errors}))
    else:
        print(f"{len(result.log.puts)} FB3 PUT jobs, {len(result.log.errors)} errors")
        for sample in result.samples[:: max(1, len(result.samples) // 12)]:
            print(f"t = {sample.time_s / 60:6.1f} min  sensor {sample.sensor_C:6.2f} degC  "
                  f"TC of axis {args.axis}: {sample.tc_value_mm:.4f} mm")
        for error in result.log.errors[:10]:
            print(f"error: {error}")
    return 1 if result.log.errors else 0
