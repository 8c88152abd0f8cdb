"""`nckemu machine fit` and `nckemu machine compare` (docs/heat.md): thin; the work is thermal/heat's."""

from __future__ import annotations

import argparse
import json
import re
import sys
import tomllib

from nckemu.cliutil import check_output, command_group, working, write_atomically, write_json
from nckemu.errors import NckConfigError

FIT_EXAMPLE = ("example:\n  nckemu machine fit fixtures/thermal/heat_table.csv --inputs spindle_rpm,coolant "
               "--out fitted.toml\n")
COMPARE_EXAMPLE = ("example:\n  nckemu machine compare fixtures/thermal/heat_table.csv --machine "
                   "fixtures/machines/heat_fitted.toml --figure compare.png\n")


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    group = command_group(subparsers, "machine", "show a machine; fit its heat from recordings")
    fit = group.add_parser(
        "fit", help="fit each sensor's heat response from recordings into a machine file", epilog=FIT_EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Each sensor's temperature as a response to the spindle's speed (a power of it, or running "
                    "at all, one or two time constants), the axes' path speed, a switched input (coolant), the "
                    "room (a reference sensor) and a neighbour's heat, each term admitted on held-out data. "
                    "Writes the machine file (--machine, or the built-in machine) with the fitted [[sensor]] "
                    "tables.")
    fit.add_argument("recording", nargs="*", help="recordings (CSV or Parquet; several: runs of one machine)")
    fit.add_argument("--fleet", metavar="ROOT", help="one folder per machine under ROOT: each machine's fit as a "
                     "Dask task, the heat terms tabulated across the fleet (no --out)")
    fit.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="with --fleet: a running Dask cluster")
    fit.add_argument("--workers", type=int, metavar="N", help="with --fleet: the local cluster's processes")
    fit.add_argument("--inputs", default="spindle_rpm", metavar="NAMES",
                     help="the machine's inputs, comma-separated: spindle_rpm, axes (path speed from pos_ "
                          "columns), or a column's name such as coolant (spindle_rpm)")
    fit.add_argument("--reference", metavar="SENSORS", default="",
                     help="the sensors that read the room, comma-separated (default: one named ambient/room/..., "
                          "else the sensor the spindle explains least)")
    fit.add_argument("--sensors", metavar="NAMES", default="", help="fit only these sensors (comma-separated)")
    fit.add_argument("--train", type=float, default=0.6, metavar="SHARE",
                     help="one recording: fit on this first share, judge on the rest (0.6)")
    fit.add_argument("--step", type=float, default=60.0, metavar="S", help="the fit's time step in s (60)")
    fit.add_argument("--machine", help="the machine file whose sensors the fit replaces (default: built-in)")
    fit.add_argument("--out", metavar="MACHINE.toml", help="write the machine file with the fitted sensors")
    fit.add_argument("--json", action="store_true", help="print the fit as JSON on stdout")
    fit.set_defaults(func=run_fit)
    compare = group.add_parser(
        "compare", help="replay a recording's inputs through a machine's heat and say where they part",
        epilog=COMPARE_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="The recording's spindle speed (and other inputs the machine's responses name, and the room "
                    "as recorded) through the machine file's [[sensor.response]] terms, as the twin steps them; "
                    "per sensor the RMS against the recording and the windows where they part, with what the "
                    "machine was doing there.")
    compare.add_argument("recording", nargs="+", help="recordings (CSV or Parquet)")
    compare.add_argument("--machine", required=True, help="machine TOML with fitted responses")
    compare.add_argument("--figure", metavar="FILE.png", help="recorded against simulated per sensor (first run)")
    compare.add_argument("--model", metavar="MODEL.toml",
                         help="an error model (discover --write-model): the recorded err_<axis>_um against the "
                              "model fed the recorded temperatures and fed the twin's")
    compare.add_argument("--json", action="store_true", help="print the comparison as JSON on stdout")
    compare.set_defaults(func=run_compare)


def _names(text: str) -> list[str]:
    return [name.strip() for name in text.split(",") if name.strip()]


def _base_text(path: str | None) -> tuple[str, str]:
    from nckemu.emulator.machine.machine_file import machine_text

    return machine_text(path)


def without_sensors(text: str, names: set[str]) -> str:
    """The machine file's text without the [[sensor]] tables (and their subtables) named ``names``."""
    lines = text.splitlines(keepends=True)
    out: list[str] = []
    block: list[str] | None = None

    def close() -> None:
        if block is None:
            return
        try:
            name = tomllib.loads("".join(block[1:]).split("[[sensor.")[0].split("[sensor.")[0]).get("name")
        except tomllib.TOMLDecodeError:
            name = None
        if name not in names:
            out.extend(block)

    for line in lines:
        header = line.strip()
        if header == "[[sensor]]":
            close()
            block = [line]
        elif block is not None and re.match(r"^\[", header) and not header.startswith(("[[sensor.", "[sensor.")):
            close()
            block = None
            out.append(line)
        elif block is not None:
            block.append(line)
        else:
            out.append(line)
    close()
    return "".join(out)


def run_fit(args: argparse.Namespace) -> int:
    from nckemu.emulator.machine.machine_file import parse_machine
    from nckemu.thermal.heat.fit import fit_heat
    from nckemu.thermal.heat.judge import Settings
    from nckemu.thermal.heat.table import load_heat_runs
    from nckemu.thermal.heat.words import explain_left, fit_lines, machine_section

    if args.fleet:
        return _run_fit_fleet(args)
    if args.scheduler or args.workers:
        raise NckConfigError("--scheduler and --workers go with --fleet ROOT")
    if not args.recording:
        raise NckConfigError("give recordings, or --fleet ROOT")
    check_output(args.out, "--out")
    if not 0.2 <= args.train <= 0.9:
        raise NckConfigError(f"--train {args.train:g}: expected a share 0.2..0.9")
    if args.step <= 0:
        raise NckConfigError(f"--step {args.step:g}: expected seconds > 0")
    base_text, base_source = _base_text(args.machine)
    runs = load_heat_runs(args.recording, _names(args.inputs), args.step)
    settings = Settings(train_share=args.train, reference=tuple(_names(args.reference)))
    missing = [name for name in (*settings.reference, *_names(args.sensors)) if name not in runs[0].sensors_C]
    if missing:
        raise NckConfigError(f"no temp_{missing[0]}_C in the recordings (sensors: {', '.join(sorted(runs[0].sensors_C))})")
    with working("machine fit", enabled=not args.json):
        fit = fit_heat(runs, settings, _names(args.sensors) or None)
    for result in fit.sensors:
        if result.terms:
            result.left = explain_left(result, runs, fit.judge)
    if args.out:
        section = machine_section(fit, ", ".join(args.recording))
        text = without_sensors(base_text, {s.sensor for s in fit.sensors}).rstrip() + "\n\n" + section
        parse_machine(text, args.out)   # what is written loads: the fitted sensors with the base's axes
        write_atomically(args.out, lambda path: path.write_text(text, encoding="utf-8"))
    if args.json:
        print(json.dumps({**fit.to_json(), "machine": base_source, "out": args.out}))
        return 0
    for line in fit_lines(fit):
        print(line)
    if args.out:
        print(f"wrote {args.out} (the sensors of {base_source} replaced by the fitted ones)")
    return 0


def _run_fit_fleet(args: argparse.Namespace) -> int:
    from nckemu.cliutil import progress
    from nckemu.thermal.fleet.discover import scan_root
    from nckemu.thermal.fleet.heat import fit_fleet

    if args.recording or args.out or args.machine:
        raise NckConfigError("--fleet fits each machine folder: give no recordings, --out or --machine with it")
    if args.scheduler and args.workers:
        raise NckConfigError("--workers sizes the local cluster; a --scheduler's cluster has its own workers")
    if args.workers is not None and args.workers < 1:
        raise NckConfigError(f"--workers {args.workers}: at least 1")
    machines = scan_root(args.fleet)

    def bar(finished: object, total: int) -> object:
        return progress(finished, total=total, description="machines", enabled=not args.json, unit="machine")

    document = fit_fleet(machines, _names(args.inputs), scheduler=args.scheduler, workers=args.workers, progress=bar)
    if args.json:
        print(json.dumps(document))
    else:
        for machine in document["machines"]:
            if "error" in machine:
                print(f"{machine['machine']}: failed: {machine['error']}")
                continue
            named = sum(1 for s in machine["sensors"] if s["terms"])
            print(f"{machine['machine']}: {named} of {len(machine['sensors'])} sensors with heat terms")
        print(f"fleet of {len(document['machines'])} on {document['engine']}:")
        for row in document["table"]:
            k, tau = row["K"], row["tau_s"]
            print(f"  {row['sensor']}: {row['term']} on {row['machines']} of {row['of']} machines; K {k['median']:.3g} "
                  f"({k['min']:.3g}..{k['max']:.3g}), tau {tau['median'] / 60:.0f} min "
                  f"({tau['min'] / 60:.0f}..{tau['max'] / 60:.0f})")
    for name, error in document["failed"].items():
        print(f"nckemu machine fit: machine {name}: {error}", file=sys.stderr)
    return 1 if document["failed"] else 0


def run_compare(args: argparse.Namespace) -> int:
    from nckemu.emulator.machine.machine_file import load_machine
    from nckemu.heat_response import PATH, SENSOR, SPINDLE
    from nckemu.thermal.heat.compare import compare, comparison_lines, error_lines, write_figure
    from nckemu.thermal.heat.table import load_heat_runs

    check_output(args.figure, "--figure")
    machine = load_machine(args.machine)
    model = None
    if args.model:
        from nckemu.thermal.model.terms import load_model

        model = load_model(args.model)
    responses = {sensor.name: sensor.response for sensor in machine.sensors if sensor.response}
    if not responses:
        raise NckConfigError("no [[sensor.response]] in this machine: fit one with `nckemu machine fit`",
                             path=args.machine)
    recorded = set(load_heat_runs(args.recording, [], step_s=60.0)[0].sensors_C)
    responses = {name: terms for name, terms in responses.items() if name in recorded}
    if not responses:
        raise NckConfigError(f"none of the machine's fitted sensors is in the recording (it has: "
                             f"{', '.join(sorted(recorded))})", path=args.recording[0])
    needed = sorted({term.input for terms in responses.values() for term in terms} - {SENSOR})
    inputs = ["axes" if name == PATH else name for name in needed]
    if SPINDLE not in inputs:
        inputs.append(SPINDLE)
    runs = load_heat_runs(args.recording, inputs, step_s=60.0)
    base = {sensor.name: sensor.temperature_C for sensor in machine.sensors}
    result = compare(runs, base, responses)
    if args.figure:
        write_atomically(args.figure, lambda path: write_figure(path, runs, result))
    document = {"machine": args.machine, "runs": [run.name for run in runs], "sensors": [r.to_json() for r in result.rows]}
    errors = error_lines(runs, result, model) if model is not None else []
    if errors:
        document["error"] = errors
    if args.json:
        write_json(document, "-")
        return 0
    for line in comparison_lines(result) + errors:
        print(line)
    if args.figure:
        print(f"wrote {args.figure}", file=sys.stderr)
    return 0
