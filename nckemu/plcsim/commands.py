"""``nckemu plc run``."""

from __future__ import annotations

import argparse
import functools
import json
import logging
import math
from typing import Any

from nckemu.cliutil import add_json_options, check_output, working, write_atomically
from nckemu.errors import NckConfigError


def _duration_s(text: str) -> float:
    units = {"s": 1.0, "min": 60.0, "m": 60.0, "h": 3600.0}
    for suffix, factor in sorted(units.items(), key=lambda kv: -len(kv[0])):
        if text.endswith(suffix):
            return float(text[: -len(suffix)]) * factor
    return float(text)


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    plc = subparsers.add_parser(
        "plc", help="run a PLC program (STL/AWL) in awlsim against the emulator",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  nckemu plc run fixtures/plc/tc_z.awl --machine fixtures/machines/bed_ramp.toml\n"
               "  nckemu plc stubs stubs/\n")
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
    run.add_argument("--axis", default=None,
                     help="machine axis whose compensation is reported (4); with --inputs also a recording "
                          "letter, e.g. Z (default: the axis of the recording's only err_ column)")
    run.add_argument("--inputs", metavar="REC.csv",
                     help="drive sensors and axes from this recording on its own time base (needs --machine)")
    run.add_argument("--map", metavar="MAP.toml", help="with --inputs: read a foreign file through this map "
                                                       "(docs/recordings.md)")
    run.add_argument("--out", metavar="SIM.csv",
                     help="with --inputs: write the recording plus sim_<axis>_um, the compensation the NCK "
                          "applied (err - sim is the error left)")
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

    loop = subparsers.add_parser(
        "loop", help="your compensation program against a recording: what it misses, and the fixed program",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: nckemu loop fixtures/plc/bed_only_z.awl --machine fixtures/machines/loop_mill.toml "
               "--inputs fixtures/thermal/loop_bed_program_spindle_lag.csv --axis Z --cycle 60s --report loop.html "
               "--json-out loop.json --write-stl fixed.awl\n")
    loop.add_argument("program", help="your STL source with OB1")
    loop.add_argument("--machine", required=True, help="machine TOML: sensors with plc_input, axes")
    loop.add_argument("--inputs", required=True, metavar="REC.csv", help="recording with temp_, pos_ and err_ columns")
    loop.add_argument("--axis", required=True, help="recording letter of the axis, e.g. Z")
    loop.add_argument("--map", metavar="MAP.toml", help="read a foreign --inputs file through this map "
                                                        "(docs/recordings.md)")
    loop.add_argument("--cycle", default="1s", help="simulated PLC cycle (1s); the generated filters are exact for it")
    loop.add_argument("--folds", type=int, default=5, help="held-out blocks of time (5)")
    loop.add_argument("--report", metavar="loop.html", help="write one self-contained HTML report")
    add_json_options(loop, out=True)
    loop.add_argument("--write-stl", metavar="NEW.awl", help="write the generated program (fitted on all data)")
    loop.add_argument("--quiet", action="store_true",
                      help="no line on stderr as each phase begins (they say how long the rest will take)")
    loop.set_defaults(func=run_loop_command)
    serve = subparsers.choices.get("serve")
    if serve is not None:  # a living machine: the recording and the PLC live here, the server never imports plcsim
        add_live_options(serve)
        serve.set_defaults(func=functools.partial(serve_live, serve.get_default("func")))
    discover = subparsers.choices.get("discover")
    if discover is not None:  # `discover --write-stl`: the PLC side lives here, thermal never imports plcsim
        discover.add_argument("--write-stl", metavar="NEW.awl",
                              help="write an STL program computing the improved model (needs --machine)")
        discover.add_argument("--machine", help="machine TOML: which sensors the PLC reads, and the axis")
        discover.add_argument("--cycle", default="1s", help="PLC cycle the generated filters are exact for (1s)")
        discover.set_defaults(func=functools.partial(discover_with_stl, discover.get_default("func")))


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
        for source in STUB_SOURCES:  # each whole or not at all
            write_atomically(target / source.name, lambda path, source=source: shutil.copyfile(source, path))
            written.append(str(target / source.name))
    except OSError as exc:
        raise NckConfigError(f"cannot write the stub sources: {exc.strerror}",
                             path=exc.filename or args.directory) from None
    print(json.dumps({"directory": str(target), "files": written}) if args.json else "\n".join(written))
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
    if not args.emulator:
        _warn_position_dependent(args.program, args.machine, args.axis)
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


def _warn_position_dependent(program: str, machine_path: str | None, axis_number: int) -> None:
    import sys
    from pathlib import Path

    from nckemu.emulator.machine.machine_file import load_machine

    from .replay import position_dependent_warning

    try:
        text = Path(program).read_text("utf-8", errors="replace")
    except OSError:
        return  # run_program names the problem
    machine = load_machine(machine_path)
    axis = machine.axis(axis_number)
    warning = position_dependent_warning(text, machine, axis) if axis is not None else None
    if warning:
        print(f"nckemu plc run: warning: {warning}", file=sys.stderr)


def run_plc_on_recording(args: argparse.Namespace) -> int:
    import sys

    import numpy as np

    from nckemu.thermal.recordings.recording_map import load_recording

    from .replay import run_on_recording, with_simulation
    from .replay import write_atomically as write_recording_atomically

    if not args.inputs or not args.machine:
        raise NckConfigError("--out needs --inputs, and --inputs needs --machine (the sensors' PLC inputs)")
    if args.emulator:
        raise NckConfigError("--inputs runs an in-process emulator on the recording's time; drop --emulator")
    try:
        cycle_s = _duration_s(args.cycle)
    except ValueError:
        raise NckConfigError("--cycle takes e.g. 1s, 15s, 1min") from None
    if args.out:
        check_output(args.out, "--out")
    recording = load_recording(args.inputs, map_path=args.map)
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
        write_recording_atomically(args.out, with_simulation(recording, column, run.sim_um))
    error = recording.errors_um.get(column)
    summary = {"axis": column, "machine_axis": run.axis.number, "rows": len(run.sim_um), "cycles": run.cycles,
               "puts": len(run.log.puts), "errors": run.log.errors[:10], "out": args.out,
               "sim_min_um": round(float(np.nanmin(run.sim_um)), 4), "sim_max_um": round(float(np.nanmax(run.sim_um)), 4)}
    previous = recording.simulated_um.get(column)  # e.g. SIM.csv of the old program as --inputs
    if error is not None:
        measured = ~np.isnan(error)
        summary["rms_error_um"] = round(float(np.sqrt(np.mean(error[measured] ** 2))), 4)
        summary["rms_residual_um"] = round(float(np.sqrt(np.mean((error - run.sim_um)[measured] ** 2))), 4)
        if previous is not None:
            rows = measured & ~np.isnan(previous)
            summary["rms_residual_before_um"] = round(float(np.sqrt(np.mean((error - previous)[rows] ** 2))), 4)
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"axis {column} (machine axis {run.axis.number}): {run.cycles} PLC cycles, {len(run.log.puts)} FB3 PUT "
              f"jobs, {len(run.log.errors)} errors; sim_{column}_um {summary['sim_min_um']:.2f}.."
              f"{summary['sim_max_um']:.2f} um" + (f" -> {args.out}" if args.out else ""))
        if error is not None:
            print(f"RMS error {summary['rms_error_um']:.3f} um before compensation, "
                  f"{summary['rms_residual_um']:.3f} um left after it (err - sim)")
        if "rms_residual_before_um" in summary:
            print(f"residual before (the recording's sim_{column}_um) {summary['rms_residual_before_um']:.3f} um, "
                  f"after (this program) {summary['rms_residual_um']:.3f} um")
        for message in run.log.errors[:10]:
            print(f"error: {message}")
    return 1 if run.log.errors else 0


def _cycle(text: str) -> float:
    try:
        cycle_s = _duration_s(text)
    except ValueError:
        raise NckConfigError("--cycle takes e.g. 1s, 15s, 1min") from None
    if not cycle_s > 0:
        raise NckConfigError("--cycle must be positive")
    return cycle_s


def _write_text_atomically(path: str, text: str) -> None:
    write_atomically(path, lambda target: target.write_text(text, encoding="utf-8"))


def run_loop_command(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from nckemu.thermal.recordings.recording_map import load_recording

    from .loop import run_loop, write_loop_report

    cycle_s = _cycle(args.cycle)
    if args.folds < 2:
        raise NckConfigError("--folds must be at least 2")
    for option, path in (("--report", args.report), ("--json-out", args.json_out), ("--write-stl", args.write_stl)):
        check_output(path, option)
    recording = load_recording(args.inputs, map_path=args.map)
    say = None if args.quiet else (lambda line: print(line, file=sys.stderr, flush=True))
    result = run_loop(args.program, args.machine, recording, args.axis, cycle_s=cycle_s, folds=args.folds,
                      on_phase=say)
    for warning in result.warnings:
        print(f"nckemu loop: warning: {warning}", file=sys.stderr)
    if args.write_stl:
        _write_text_atomically(args.write_stl, result.program.text)
    if args.json_out and args.json_out != "-":
        _write_text_atomically(args.json_out, json.dumps(result.to_json(), indent=2) + "\n")
    if args.report:
        write_loop_report(args.report, result, f"nckemu loop: {Path(args.program).name} on {Path(args.inputs).name}")
    if args.json or args.json_out == "-":
        print(json.dumps(result.to_json()))
        return 0
    print(f"axis {result.letter}: error RMS {result.rms_error_um:.3f} um; left after your program "
          f"{result.rms_before_um:.3f} um; after the generated program {result.heldout_rms_after_um:.3f} um held-out "
          f"({result.rms_after_um:.3f} um fitted on all)")
    for heading, sentence in result.findings:
        print(f"  {heading}: {sentence}")
    for item in result.program.not_compensable:
        print(f"  {item['effect']}: {item['why']}")
    return 0


def discover_with_stl(thermal_discover: Any, args: argparse.Namespace) -> int:
    if not args.write_stl:
        return int(thermal_discover(args) or 0)
    import contextlib
    import io
    import sys
    from pathlib import Path

    from nckemu.emulator.machine.machine_file import load_machine
    from nckemu.thermal.discovery.plcmodel import plc_model, terms_of
    from nckemu.thermal.recordings.recording_map import load_recording

    from .replay import plc_inputs, recording_axis
    from .stlgen import generate_program

    if not args.machine:
        raise NckConfigError("--write-stl needs --machine (which sensors the PLC reads, which axis)")
    check_output(args.write_stl, "--write-stl")
    cycle_s = _cycle(args.cycle)
    machine = load_machine(args.machine)
    recording = load_recording(args.recording, map_path=args.map)
    letter = args.axis or (recording.axes()[0] if len(recording.axes()) == 1 else None)
    if letter is None:
        raise NckConfigError("several err_ columns: name one with --axis", path=args.recording)
    axis = recording_axis(machine, letter)
    # discover's own lines are held back until the program is generated: a refusal stays one line.
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = int(thermal_discover(args) or 0)
    discovery = args.discovery
    origin = f"nckemu discover on {Path(args.recording).name}"
    if args.model or discovery.axis not in recording.simulated_um:  # the improved model carries every term
        generated = generate_program(discovery.improved_model, machine, axis, cycle_s, origin=origin)
    else:  # a program's sim_ column: its law read back, the found effects added
        plc_sensors, spindle_input = plc_inputs(machine, recording)
        model = plc_model(recording, discovery.axis, terms_of(discovery.missing_physics), plc_sensors,
                          spindle_input=spindle_input)
        generated = generate_program(model.model, machine, axis, cycle_s, extra_not_compensable=model.not_compensable,
                                     origin=origin)
    _write_text_atomically(args.write_stl, generated.text)
    stl = {"path": args.write_stl, **generated.to_json()}
    if args.json_out and args.json_out != "-":
        document = json.loads(Path(args.json_out).read_text(encoding="utf-8"))
        _write_text_atomically(args.json_out, json.dumps({**document, "stl": stl}, indent=2) + "\n")
    sys.stderr.write(err.getvalue())
    if args.json or args.json_out == "-":  # discover's JSON on stdout, with the program added
        # --json prints one compact line last; --json-out - alone prints the indented document.
        text = out.getvalue().strip()
        document = json.loads(text.splitlines()[-1] if args.json else text)
        print(json.dumps({**document, "stl": stl}))
        return status
    sys.stdout.write(out.getvalue())
    print(f"  STL written to {args.write_stl}: {', '.join(g['effect'] for g in generated.generated)}")
    for item in generated.not_compensable:
        print(f"  {item['effect']}: {item['why']}")
    if generated.position_dependent:
        print(f"  the program writes tan beta and P0: set MD32750 bit 1 for machine axis {axis.number}")
    return status


LIVE_EXAMPLE = """\
a living machine (a recording at 600 times real time, the PLC program on the same clock, a live page):
  nckemu serve --port 1102 --machine fixtures/machines/loop_mill.toml --inputs fixtures/thermal/loop_bed_program_spindle_lag.csv --speed 600x --loop --plc fixtures/plc/bed_only_z.awl --http 0 -v
"""


def add_live_options(serve: argparse.ArgumentParser) -> None:
    serve.epilog = (serve.epilog or "") + LIVE_EXAMPLE
    live = serve.add_argument_group("a living machine (docs/live.md)")
    live.add_argument("--inputs", metavar="REC.csv",
                      help="a recording drives the machine on the server's clock: sensors (PIW words), positions, "
                           "spindle speed; at its end the last row holds")
    live.add_argument("--loop", action="store_true", help="with --inputs: start the recording over at its end")
    live.add_argument("--map", metavar="MAP.toml", help="with --inputs: read a foreign file through this map "
                                                        "(docs/recordings.md)")
    live.add_argument("--plc", metavar="PROGRAM.awl",
                      help="run this STL program (with OB1) in awlsim on the server's clock; its FB2/FB3/FB4 "
                           "reach this machine")
    live.add_argument("--speed", default=None,
                      help="simulated time per real time, e.g. 60x or 60 (1x); also without --inputs/--plc")
    live.add_argument("--cycle", default="1s", help="simulated PLC and recording cycle (1s)")


def serve_live(plain_serve: Any, args: argparse.Namespace) -> int:
    """``serve`` with --inputs/--plc/--speed: the emulator on a live clock, a LiveMachine as a face."""
    if args.inputs is None and args.plc is None and args.speed is None:
        if args.loop:
            raise NckConfigError("--loop starts a recording over: it needs --inputs")
        return int(plain_serve(args) or 0)
    import sys

    from nckemu.emulator.machine.clock import LiveClock

    from .live import LiveMachine, parse_speed

    speed = parse_speed(args.speed) if args.speed is not None else 1.0
    cycle_s = _cycle(args.cycle)
    if args.loop and args.inputs is None:
        raise NckConfigError("--loop starts a recording over: it needs --inputs")
    inputs = args.inputs
    if args.map and inputs is not None:  # a foreign file: read through the map before the server starts
        from nckemu.thermal.recordings.recording_map import load_recording

        inputs = load_recording(inputs, need_errors=False, map_path=args.map)
    verbose = getattr(args, "verbose", 0) > 0
    # The program's own client (FB2/FB3/FB4 jobs, up to hundreds a second at high speed) logs every
    # frame at debug: -v is for the minute lines, not for that.

    def minute(line: str) -> None:
        print(json.dumps({"live": line}) if args.json else line, file=sys.stdout, flush=True)

    def make(emulator: Any, server: Any) -> LiveMachine:
        return LiveMachine(emulator, inputs=inputs, plc=args.plc, speed=speed, loop=args.loop, cycle_s=cycle_s,
                           server=server, on_minute=minute if verbose else None)

    snap7_log = logging.getLogger("snap7")
    level = snap7_log.level
    snap7_log.setLevel(max(logging.INFO, logging.getLogger().level))
    try:
        return int(plain_serve(args, clock=LiveClock(speed), faces=[make]) or 0)
    finally:
        snap7_log.setLevel(level)  # the level is the process's: give it back (main() may run again)
