"""``nckemu discover --fleet ROOT``: every machine folder's discovery as a Dask task, and the fleet table."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from nckemu.cliutil import check_output, progress, write_json
from nckemu.errors import NckConfigError


def _step_s(text: str) -> float:
    """``60s``, ``2min``, ``60``: the reduction window in seconds."""
    units = (("min", 60.0), ("s", 1.0), ("h", 3600.0))
    number, factor = text.strip(), 1.0
    for suffix, scale in units:
        if number.endswith(suffix):
            number, factor = number[: -len(suffix)], scale
            break
    try:
        step_s = float(number) * factor
    except ValueError:
        raise NckConfigError(f"--reduce {text}: a window such as 60s or 2min") from None
    if not 1.0 <= step_s <= 86400.0:
        raise NckConfigError(f"--reduce {text}: between 1 s and one day")
    return step_s


def run_fleet_discover(args: argparse.Namespace) -> int:
    if getattr(args, "reduce", None) and not args.fleet:
        raise NckConfigError("--reduce goes with --fleet ROOT")
    if not args.fleet:
        raise NckConfigError("--scheduler and --workers go with --fleet ROOT")
    if args.recording is not None or getattr(args, "more", None):
        raise NckConfigError(f"give recordings or --fleet, not both ({args.recording})")
    if getattr(args, "split_runs", False):
        raise NckConfigError("--split-runs does not go with --fleet (a machine folder's files are its runs)")
    for option, value in (("--model", args.model), ("--write-model", args.write_model)):
        if value is not None:
            raise NckConfigError(f"{option} does not go with --fleet (each machine folder holds its own model)")
    if args.scheduler and args.workers:
        raise NckConfigError("--workers sizes the local cluster; a --scheduler's cluster has its own workers")
    if args.workers is not None and args.workers < 1:
        raise NckConfigError(f"--workers {args.workers}: at least 1")
    reduce_step_s = _step_s(args.reduce) if getattr(args, "reduce", None) else None
    for option, path in (("--json-out", args.json_out), ("--report", args.report)):
        check_output(path, option)

    from .discover import discover_fleet, scan_root, write_fleet_report

    machines = scan_root(args.fleet)
    quiet = bool(args.json) or args.json_out == "-"

    def bar(finished: object, total: int) -> object:
        return progress(finished, total=total, description="machines", enabled=not quiet, unit="machine")

    def day_bar(finished: object, total: int) -> object:
        return progress(finished, total=total, description="files reduced", enabled=not quiet, unit="file")

    document = discover_fleet(machines, axis=args.axis, scheduler=args.scheduler, workers=args.workers,
                              progress=bar, root=str(args.fleet), reduce_step_s=reduce_step_s,
                              reduce_progress=day_bar)
    write_json(document, args.json_out)
    if args.report:
        write_fleet_report(args.report, document, f"nckemu discover --fleet {Path(args.fleet).name}")
    if args.json:
        print(json.dumps(document))
    else:
        text = sys.stderr if args.json_out == "-" else sys.stdout
        for machine in document["machines"]:
            retried = f" (retried: {machine['worker_losses']} worker(s) lost)" if machine.get("worker_losses") else ""
            if "error" in machine:
                print(f"{machine['machine']}: failed: {machine['error']}{retried}", file=text)
                continue
            missing = ", ".join(effect["effect"] for effect in machine["findings"]["missing_physics"])
            print(f"{machine['machine']}: {missing or 'nothing missing'}{retried}", file=text)
        print(f"fleet of {len(document['machines'])} on {document['engine']}:", file=text)
        for row in document["table"]:
            spread = "; ".join(f"{key} {s['median']:.4g} ({s['min']:.4g}..{s['max']:.4g})"
                               for key, s in row["parameters"].items())
            print(f"  {row['effect']}: {row['machines']} of {row['of']} machines; {spread}", file=text)
        if not document["table"]:
            print("  nothing missing on any machine", file=text)
        if "reduce" in document:
            done = document["reduce"]
            print(f"reduced to {done['step_s']:g} s means: {done['reduced']} file(s) reduced, {done['up_to_date']} up "
                  f"to date, {len(done['failed'])} failed ({done['rows_in']} rows in, {done['rows_out']} out)",
                  file=text)
            for source, error in done["failed"].items():
                print(f"nckemu discover: {source}: {error}", file=sys.stderr)
    for name, error in document["failed"].items():
        print(f"nckemu discover: machine {name}: {error}", file=sys.stderr)
    return 1 if document["failed"] else 0
