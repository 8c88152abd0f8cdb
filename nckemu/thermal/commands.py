"""``nckemu simulate`` and ``nckemu discover``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from nckemu.cliutil import check_output, working, write_atomically, write_json
from nckemu.errors import NckConfigError

# numpy/scipy and the modules on them load when a command runs, not for every `nckemu` call
# (importing scipy.signal takes over a second and `nckemu serve` does not need it).


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    raw = argparse.RawDescriptionHelpFormatter
    simulate = subparsers.add_parser(
        "simulate", help="the model's prediction on a recording's inputs", formatter_class=raw,
        epilog="example: nckemu simulate --model fixtures/thermal/baseline_spindle_bed.toml "
               "--inputs fixtures/thermal/runs/day1.csv --out sim.csv\n"
               "  (a recording: t_s, temp_<sensor>_C for the model's sensors, spindle_rpm, pos_<axis>_mm, err_<axis>_um)\n")
    simulate.add_argument("--model", required=True, help="model TOML (a sum of named terms)")
    simulate.add_argument("--inputs", required=True, help="recording CSV with the model's sensors")
    simulate.add_argument("--out", help="write the recording with a sim_<axis>_um column (default: stdout)")
    simulate.add_argument("--json", action="store_true", help="print summary figures as JSON on stdout")
    simulate.set_defaults(func=run_simulate)

    find = subparsers.add_parser(
        "discover", help="locate model mismatch, name the missing physics, fit it", formatter_class=raw,
        epilog="examples:\n"
               "  nckemu discover fixtures/thermal/seed003_spindle_elongation.csv --axis Z "
               "--json-out out.json --report out.html\n"
               "  nckemu discover fixtures/thermal/seed003_spindle_elongation.csv --json\n"
               "  nckemu discover fixtures/thermal/runs/day1.csv fixtures/thermal/runs/day2.csv "
               "fixtures/thermal/runs/day3.csv --model fixtures/thermal/baseline_spindle_bed.toml --report runs.html\n"
               "  nckemu discover 'fixtures/thermal/runs/*.csv' --axis Z --json\n"
               "  nckemu discover fixtures/thermal/runs --axis Z\n"
               "  nckemu discover fixtures/thermal/loop_bed_program_spindle_lag.csv --split-runs --axis Z\n"
               "Without --model and without a sim_<axis>_um column the baseline is a constant offset: "
               "discover then says which sensors explain the axis on their own.\n"
               "Several runs (files, a directory, a glob): each run has its own offset, fitted on that run; "
               "everything else is fitted on the other runs, and each run is held out in turn.\n")
    find.add_argument("recording", nargs="?", help="recording (CSV or Parquet), a directory of them or a glob "
                                                   "(or --fleet ROOT)")
    find.add_argument("more", nargs="*", metavar="RUN", help="more runs of the same machine")
    find.add_argument("--model", help="baseline model TOML (default: the recording's sim_<axis>_um column, "
                                      "else a constant offset)")
    find.add_argument("--axis", help="which err_<axis>_um to explain (default: the model's axis, or the "
                                     "recording's only one)")
    find.add_argument("--split-runs", action="store_true",
                      help="cut each recording into runs at spindle-speed blocks and gaps over 1 h, then "
                           "discover over the runs")
    find.add_argument("--group-by", metavar="REGEX|column:NAME",
                      help="several runs: a part of the run names (a regular expression, its first group: a date "
                           "'(2017-0[23])', a cycle name '_(light|heavy)'), or a column of the recordings "
                           "('column:spindle_rpm', 'column:coolant': each run's mean, cut into two groups where "
                           "they are tightest) whose groups a term may be fitted apart on; without it, discover "
                           "finds a stretch of dates that follows another relation")
    find.add_argument("--structure", metavar="MATERIAL[:LENGTH_M]",
                      help="what the machine's structure lets a term be (docs/thermal.md): its material (steel, "
                           "cast_iron, mineral_cast, granite, aluminium) or its expansion in um/(m K), and the "
                           "longest structure from the heat to the tool in metres, e.g. 'cast_iron:1.2' or "
                           "'11.5:2' (default: the model's [structure], else 3 m of steel)")
    find.add_argument("--map", metavar="MAP.toml", help="read foreign files (workbooks, other column names) "
                                                        "through this map (docs/recordings.md)")
    find.add_argument("--json", action="store_true", help="print the findings as JSON on stdout")
    find.add_argument("--json-out", metavar="FILE", help="write the findings as JSON to FILE (- for stdout)")
    find.add_argument("--report", metavar="OUT.html", help="write a self-contained HTML report")
    find.add_argument("--write-model", metavar="IMPROVED.toml", help="write the improved model")
    # fleet discovery (thermal/fleet/discover.py): one Dask task per machine folder
    find.add_argument("--fleet", metavar="ROOT", help="one folder per machine under ROOT (its runs as CSV or "
                                                     "Parquet, optionally its model TOML); each machine a Dask task")
    find.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                      help="with --fleet: a running Dask scheduler (default: a local cluster in this process)")
    find.add_argument("--workers", type=int, metavar="N", help="with --fleet: local cluster workers (default: cores)")
    find.add_argument("--reduce", metavar="60s",
                      help="with --fleet: first reduce each run file to window means (one Dask task per file, "
                           "into ROOT/_60s/; files already reduced are kept), then discover on them")
    find.set_defaults(func=run_discover)


def run_simulate(args: argparse.Namespace) -> int:
    import numpy as np

    from nckemu.thermal.model.terms import load_model
    from nckemu.thermal.recordings.recording import Recording, load_recording, write_recording

    check_output(args.out, "--out")
    model = load_model(args.model)
    recording = load_recording(args.inputs)
    # the model's sums carry float noise past any meaning (0.06899999999999551 um): 12 digits are a
    # femtometre at a millimetre's error, and the file then says 0.069
    prediction = np.array([float(f"{value:.12g}") for value in model.predict_um(recording).tolist()])
    out = Recording(recording.source, recording.t_s, recording.temperatures_C, recording.spindle_rpm,
                    recording.positions_mm, recording.errors_um, {**recording.simulated_um, model.axis: prediction})
    if args.out:
        write_atomically(args.out, lambda path: write_recording(path, out))
    if args.json:
        print(json.dumps({"axis": model.axis, "samples": len(prediction), "min_um": float(np.min(prediction)),
                          "max_um": float(np.max(prediction)), "out": args.out}))
    elif not args.out:
        write_recording("/dev/stdout", out)
    else:
        print(f"sim_{model.axis}_um written to {args.out} ({len(prediction)} samples, "
              f"{float(np.min(prediction)):.2f}..{float(np.max(prediction)):.2f} um)")
    return 0


def _is_one_file(spec: str) -> bool:
    return not any(ch in spec for ch in "*?[") and not Path(spec).is_dir()


def run_discover(args: argparse.Namespace) -> int:
    if args.fleet and getattr(args, "map", None):
        raise NckConfigError("--fleet reads the project's format only: write each machine's runs with "
                             "`nckemu recording import SOURCE --map MAP.toml --out ROOT/<machine>` first")
    if args.fleet or args.scheduler or args.workers or args.reduce:
        if getattr(args, "structure", None) is not None:
            raise NckConfigError("--fleet reads each machine's structure from the [structure] table of its "
                                 "model TOML, not from --structure")
        from nckemu.thermal.fleet.commands import run_fleet_discover

        return run_fleet_discover(args)
    if args.recording is None:
        raise NckConfigError("give a recording CSV, or --fleet ROOT")
    from nckemu.thermal.discovery.discover import discover_runs
    from nckemu.thermal.model.terms import load_model
    from nckemu.thermal.recordings.recording_map import load_recording, load_runs

    for option, path in (("--json-out", args.json_out), ("--report", args.report),
                         ("--write-model", args.write_model)):
        check_output(path, option)
    model = load_model(args.model) if args.model else None
    args.settings = None
    if getattr(args, "structure", None) is not None:
        model, args.settings = _with_structure_option(model, args.structure)
    specs = [args.recording, *getattr(args, "more", [])]
    if getattr(args, "map", None):  # foreign files: a workbook may hold several runs
        mapped = load_runs(specs, args.axis or (model.axis if model is not None else None), map_path=args.map)
        if len(mapped) > 1 or getattr(args, "split_runs", False):
            return _run_discover_runs(args, specs, model, discover_runs, lambda *_: mapped)
        return _run_discover_one(args, mapped[0], model)
    if len(specs) > 1 or not _is_one_file(args.recording) or getattr(args, "split_runs", False):
        return _run_discover_runs(args, specs, model, discover_runs, load_runs)
    return _run_discover_one(args, load_recording(args.recording), model)


def parse_structure_option(text: str) -> Any:
    """``--structure MATERIAL[:LENGTH_M]`` (a material's name or its expansion in um/(m K)) as a
    model file's ``[structure]`` table would give it."""
    from nckemu.thermal.model.structure import parse_structure

    material, _, length = text.partition(":")
    table: dict[str, Any] = {}
    try:
        table["expansion_um_per_m_K"] = float(material)
        table["material"] = "a_material"  # words: "2 m of a material at 9 um/(m K)"
    except ValueError:
        table["material"] = material.strip()
    if length:
        try:
            table["length_m"] = float(length)
        except ValueError:
            raise NckConfigError(f"the length in --structure {text!r} is not a number of metres",
                                 path="--structure", field="structure.length_m") from None
    return parse_structure(table, "--structure")


def _with_structure_option(model: Any, text: str) -> tuple[Any, Any]:
    """(the model, discovery's settings) with the structure ``--structure`` gives, in place of the
    model's own ``[structure]`` (the improved model written then carries it)."""
    from dataclasses import replace

    from nckemu.thermal.discovery.settings import Settings

    structure = parse_structure_option(text)
    return (replace(model, structure=structure) if model is not None else None), Settings(structure=structure)


def _run_discover_one(args: argparse.Namespace, recording: Any, model: Any) -> int:
    """Discovery on one recording (one file, or a recording that ``--split-runs`` left whole)."""
    from nckemu.thermal.discovery.discover import discover
    from nckemu.thermal.discovery.report import write_report
    from nckemu.thermal.model.terms import Term, ThermalModel

    axis = args.axis or (model.axis if model is not None else None)
    if axis is None:
        if len(recording.errors_um) != 1:
            raise NckConfigError(f"which axis? give --axis ({', '.join(sorted(recording.errors_um))})",
                                 path=recording.source)
        axis = next(iter(recording.errors_um))
    if axis not in recording.errors_um:
        raise NckConfigError(f"no err_{axis}_um column (it has: "
                             f"{', '.join(sorted(recording.errors_um)) or 'none'})", path=recording.source)
    baseline = f"the sim_{axis}_um column of {recording.source}"
    if model is None and axis not in recording.simulated_um:
        # No baseline at all: start from a constant offset, so the sensors explain the axis on their own.
        model = ThermalModel(axis, [Term("offset", {"value_um": 0.0})], "<constant offset>")
        baseline = "a constant offset (no --model, no sim column)"
        print(f"nckemu discover: baseline: {baseline}", file=sys.stderr)
    with working("discover", enabled=not args.json):
        result = discover(recording, axis=axis, model=model, settings=getattr(args, "settings", None))
    args.discovery = result  # for options other components add to discover (plcsim: --write-stl)
    document = result.to_json()
    findings = None
    if model is None:  # the baseline is a program's compensation: say what it did and left out
        from nckemu.thermal.discovery.wording import program_findings

        findings = program_findings(result)
        document["program"] = dict(findings)
    write_json(document, args.json_out)
    if args.report:
        write_report(args.report, result, f"nckemu discover: {Path(recording.source).name}", findings)
    text = _write_model_and_json(args, document, result, "" if args.model else f"# baseline: {baseline}\n")
    if text is None:
        return 0
    print(f"axis {result.axis}: RMS as given {result.baseline_rms_um:.3f} um, recalibrated "
          f"{result.recalibrated_rms_um:.3f} um, held-out {result.heldout_rms_before_um:.3f} -> "
          f"{result.heldout_rms_after_um:.3f} um (before: {result.before_is})", file=text)
    for heading, sentence in findings or []:
        print(f"  {heading}: {sentence}", file=text)
    _print_findings(result, text)
    return 0


def _write_model_and_json(args: argparse.Namespace, document: dict[str, Any], result: Any, note: str) -> Any:
    """--write-model and --json; the stream for the text (None when the JSON went to stdout)."""
    from nckemu.thermal.model.terms import render_model

    if args.write_model:
        text = note + render_model(result.improved_model)
        write_atomically(args.write_model, lambda path: path.write_text(text, encoding="utf-8"))
    if args.json:
        print(json.dumps(document))
        return None
    return sys.stderr if args.json_out == "-" else sys.stdout


def _print_findings(result: Any, text: Any) -> None:
    from nckemu.thermal.discovery.wording import finding_lines

    for line in finding_lines(result):
        print(f"  {line}", file=text)


def _run_discover_runs(args: argparse.Namespace, specs: list[str], model: Any, discover_runs: Any,
                       load_runs: Any) -> int:
    from nckemu.thermal.discovery.report import write_report
    from nckemu.thermal.discovery.wording import runs_table

    runs = load_runs(specs, args.axis or (model.axis if model is not None else None))
    if getattr(args, "split_runs", False):
        from nckemu.thermal.recordings.recording import split_runs

        runs = [part for run in runs for part in split_runs(run)]
        if len(runs) == 1:  # nothing to cut: discovery on the recording, exactly as without --split-runs
            if not args.json:
                print(f"nckemu discover: {runs[0].name} stays one run after splitting", file=sys.stderr)
            return _run_discover_one(args, runs[0], model)
        if not args.json:
            print(f"nckemu discover: {len(runs)} runs after splitting: {', '.join(r.name for r in runs)}",
                  file=sys.stderr)
    with working("discover", enabled=not args.json):
        result = discover_runs(runs, axis=args.axis, model=model, settings=getattr(args, "settings", None),
                               group_by=getattr(args, "group_by", None))
    args.discovery = result
    document = result.to_json()
    write_json(document, args.json_out)
    title = f"nckemu discover: {len(runs)} runs ({', '.join(r.name for r in runs[:3])}{', ...' if len(runs) > 3 else ''})"
    if args.report:
        write_report(args.report, result, title)
    note = ("" if args.model else "# baseline: each run's own offset\n") + \
        "# plus each run's own offset, fitted on that run\n"
    text = _write_model_and_json(args, document, result, note)
    if text is None:
        return 0
    from nckemu.thermal.discovery.wording import headline_lines

    for line in headline_lines(result):
        print(line, file=text)
    print(f"axis {result.axis} over {len(runs)} runs: RMS as given {result.baseline_rms_um:.3f} um, held-out "
          f"(each run left out, median over runs) {result.heldout_rms_before_um:.3f} -> "
          f"{result.heldout_rms_after_um:.3f} um (before: {result.before_is})", file=text)
    for line in runs_table(result):
        print(f"  {line}", file=text)
    _print_findings(result, text)
    return 0
