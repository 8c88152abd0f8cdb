"""``nckemu simulate`` and ``nckemu discover``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from nckemu.errors import NckConfigError

# numpy/scipy and the modules on them load when a command runs, not for every `nckemu` call
# (importing scipy.signal takes over a second and `nckemu serve` does not need it).


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    raw = argparse.RawDescriptionHelpFormatter
    simulate = subparsers.add_parser(
        "simulate", help="the model's prediction on a recording's inputs", formatter_class=raw,
        epilog="example: nckemu simulate --model fixtures/thermal/baseline_spindle_bed.toml "
               "--inputs rec.csv --out sim.csv")
    simulate.add_argument("--model", required=True, help="model TOML (a sum of named terms)")
    simulate.add_argument("--inputs", required=True, help="recording CSV with the model's sensors")
    simulate.add_argument("--out", help="write the recording with a sim_<axis>_um column (default: stdout)")
    simulate.add_argument("--json", action="store_true", help="print summary figures as JSON")
    simulate.set_defaults(func=run_simulate)

    find = subparsers.add_parser(
        "discover", help="locate model mismatch, name the missing physics, fit it", formatter_class=raw,
        epilog="example: nckemu discover fixtures/thermal/seed003_spindle_elongation.csv --axis Z "
               "--json out.json --report out.html")
    find.add_argument("recording", help="recording CSV")
    find.add_argument("--model", help="baseline model TOML (default: the recording's sim_<axis>_um column)")
    find.add_argument("--axis", help="which err_<axis>_um to explain (default: the model's axis)")
    find.add_argument("--json", dest="json_out", metavar="OUT.json", help="write the findings as JSON")
    find.add_argument("--report", metavar="OUT.html", help="write a self-contained HTML report")
    find.add_argument("--write-model", metavar="IMPROVED.toml", help="write the improved model")
    find.set_defaults(func=run_discover)


def run_simulate(args: argparse.Namespace) -> int:
    import numpy as np

    from .recording import Recording, load_recording, write_recording
    from .terms import load_model

    model = load_model(args.model)
    recording = load_recording(args.inputs)
    prediction = model.predict_um(recording)
    out = Recording(recording.source, recording.t_s, recording.temperatures_C, recording.spindle_rpm,
                    recording.positions_mm, recording.errors_um, {**recording.simulated_um, model.axis: prediction})
    if args.out:
        write_recording(args.out, out)
    if args.json:
        print(json.dumps({"axis": model.axis, "samples": len(prediction), "min_um": float(np.min(prediction)),
                          "max_um": float(np.max(prediction)), "out": args.out}))
    elif not args.out:
        write_recording("/dev/stdout", out)
    else:
        print(f"sim_{model.axis}_um written to {args.out} ({len(prediction)} samples, "
              f"{float(np.min(prediction)):.2f}..{float(np.max(prediction)):.2f} um)")
    return 0


def run_discover(args: argparse.Namespace) -> int:
    from .discover import discover
    from .recording import load_recording
    from .report import write_report
    from .terms import load_model, render_model

    model = load_model(args.model) if args.model else None
    recording = load_recording(args.recording)
    if model is None and args.axis and args.axis not in recording.simulated_um:
        raise NckConfigError(f"no baseline: give --model or a sim_{args.axis}_um column", path=args.recording)
    result = discover(recording, axis=args.axis, model=model)
    document = result.to_json()
    if args.json_out:
        Path(args.json_out).write_text(json.dumps(document, indent=2) + "\n", encoding="utf-8")
    if args.report:
        write_report(args.report, result, f"nckemu discover: {Path(args.recording).name}")
    if args.write_model:
        note = "" if args.model else f"# baseline: the sim_{result.axis}_um column of {args.recording}\n"
        Path(args.write_model).write_text(note + render_model(result.improved_model), encoding="utf-8")
    print(f"axis {result.axis}: RMS as given {result.baseline_rms_um:.3f} um, recalibrated "
          f"{result.recalibrated_rms_um:.3f} um, held-out {result.heldout_rms_before_um:.3f} -> "
          f"{result.heldout_rms_after_um:.3f} um", file=sys.stderr if not args.json_out else sys.stdout)
    for effect in result.missing_physics:
        print(f"  missing: {effect['effect']} {json.dumps(effect['parameters'])}")
    if not result.missing_physics:
        print("  nothing missing")
    return 0
