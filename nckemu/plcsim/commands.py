"""``nckemu plc run``."""

from __future__ import annotations

import argparse
import json
import math

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
    run.add_argument("--machine", help="machine TOML for the in-process emulator (sensor profiles drive the "
                                       "analog inputs)")
    run.add_argument("--emulator", metavar="HOST:PORT",
                     help="run against this controller (a running `nckemu serve` or a real NCK) in real time, "
                          "instead of an in-process emulator on simulated time")
    run.add_argument("--speed", default="max",
                     help="simulated time per real time, e.g. 1000x or 1x; max runs as fast as possible (max)")
    run.add_argument("--duration", default="2h", help="simulated time, e.g. 2h, 30min, 600s (2h)")
    run.add_argument("--cycle", default="1s", help="simulated PLC cycle time (1s)")
    run.add_argument("--axis", default=None,
                     help="machine axis whose compensation is reported (4); with --inputs also a recording "
                          "letter, e.g. Z (default: the axis of the recording's only err_ column)")
    run.add_argument("--inputs", metavar="REC.csv",
                     help="drive sensors and axes from this recording on its own time base (needs --machine)")
    run.add_argument("--out", metavar="SIM.csv",
                     help="with --inputs: write the recording plus sim_<axis>_um, the compensation the NCK "
                          "applied (err - sim is the error left)")
    run.add_argument("--json", action="store_true")
    run.set_defaults(func=run_plc)
    stubs = commands.add_parser("stubs", help="write the FB2/FB3/FB4 stub sources (for awlsim with -H nckemu)")
    stubs.add_argument("directory", help="where to write fb2_get.awl, fb3_put.awl and fb4_pi_serv.awl")
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
    target.mkdir(parents=True, exist_ok=True)
    for source in STUB_SOURCES:
        shutil.copyfile(source, target / source.name)
        print(target / source.name)
    return 0


def run_plc(args: argparse.Namespace) -> int:
    from .run import run_program

    if args.inputs or args.out:
        return run_plc_on_recording(args)
    axis = 4 if args.axis is None else args.axis
    if not str(axis).isdigit():
        raise NckConfigError(f"--axis {axis}: without --inputs give a machine axis number, e.g. 4")
    args.axis = int(axis)

    try:
        duration_s, cycle_s = _duration_s(args.duration), _duration_s(args.cycle)
    except ValueError:
        raise NckConfigError("--duration and --cycle take e.g. 2h, 30min, 600s") from None
    if duration_s <= 0 or cycle_s <= 0:
        raise NckConfigError("--duration and --cycle must be positive")
    speed = _speed(args.speed)
    if args.emulator and speed not in (None, 1.0):
        raise NckConfigError("--speed applies to the in-process emulator; --emulator runs in real time")
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


def run_plc_on_recording(args: argparse.Namespace) -> int:
    import sys

    import numpy as np

    from nckemu.thermal.recording import load_recording

    from .replay import check_output_path, run_on_recording, with_simulation, write_atomically

    if not args.inputs or not args.machine:
        raise NckConfigError("--out needs --inputs, and --inputs needs --machine (the sensors' PLC inputs)")
    if args.emulator:
        raise NckConfigError("--inputs runs an in-process emulator on the recording's time; drop --emulator")
    try:
        cycle_s = _duration_s(args.cycle)
    except ValueError:
        raise NckConfigError("--cycle takes e.g. 1s, 15s, 1min") from None
    if args.out:
        check_output_path(args.out)
    recording = load_recording(args.inputs)
    letter = args.axis
    if letter is None:
        if len(recording.errors_um) != 1:
            raise NckConfigError(f"several err_ columns ({', '.join(recording.axes())}): name one with --axis",
                                 path=args.inputs)
        letter = recording.axes()[0]
    run = run_on_recording(args.program, args.machine, recording, letter, cycle_s=cycle_s)
    for warning in run.warnings:
        print(f"nckemu plc run: warning: {warning}", file=sys.stderr)
    column = run.axis.recording
    if args.out:
        write_atomically(args.out, with_simulation(recording, column, run.sim_um))
    error = recording.errors_um.get(column)
    summary = {"axis": column, "machine_axis": run.axis.number, "rows": len(run.sim_um), "cycles": run.cycles,
               "puts": len(run.log.puts), "errors": run.log.errors[:10], "out": args.out,
               "sim_min_um": round(float(np.nanmin(run.sim_um)), 4), "sim_max_um": round(float(np.nanmax(run.sim_um)), 4)}
    if error is not None:
        measured = ~np.isnan(error)
        summary["rms_error_um"] = round(float(np.sqrt(np.mean(error[measured] ** 2))), 4)
        summary["rms_residual_um"] = round(float(np.sqrt(np.mean((error - run.sim_um)[measured] ** 2))), 4)
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"axis {column} (machine axis {run.axis.number}): {run.cycles} PLC cycles, {len(run.log.puts)} FB3 PUT "
              f"jobs, {len(run.log.errors)} errors; sim_{column}_um {summary['sim_min_um']:.2f}.."
              f"{summary['sim_max_um']:.2f} um" + (f" -> {args.out}" if args.out else ""))
        if error is not None:
            print(f"RMS error {summary['rms_error_um']:.3f} um before compensation, "
                  f"{summary['rms_residual_um']:.3f} um left after it (err - sim)")
        for message in run.log.errors[:10]:
            print(f"error: {message}")
    return 1 if run.log.errors else 0
