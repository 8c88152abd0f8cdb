"""``nckemu recording import`` and ``nckemu recording check``: recordings as they come (docs/recordings.md)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from nckemu.errors import NckConfigError

CHECK_EXAMPLES = """\
  nckemu recording check fixtures/thermal/foreign/days.xlsx --map fixtures/thermal/foreign/days_map.toml
  nckemu recording check fixtures/thermal/seed003_spindle_elongation.csv --json
"""
IMPORT_EXAMPLES = """\
  nckemu recording import fixtures/thermal/foreign/days.xlsx --map fixtures/thermal/foreign/days_map.toml --out runs
  nckemu recording import fixtures/thermal/foreign/seed003_eu.csv --map fixtures/thermal/foreign/seed003_eu_map.toml --out runs --format csv
"""
MAP_NOTE = """\
The map file (TOML) names the time column and its unit, the project's name of each column it keeps,
and how runs are cut (docs/recordings.md).
"""


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    raw = argparse.RawDescriptionHelpFormatter
    group = subparsers.add_parser("recording", help="read recordings as they come: workbooks, European CSV, a map "
                                                    "file", formatter_class=raw,
                                  epilog="examples:\n" + CHECK_EXAMPLES + IMPORT_EXAMPLES + MAP_NOTE)
    commands = group.add_subparsers(dest="recording_command", metavar="COMMAND")
    imports = commands.add_parser("import", help="write a foreign file's runs in the project's format",
                                  formatter_class=raw, epilog="examples:\n" + IMPORT_EXAMPLES + MAP_NOTE)
    imports.add_argument("sources", nargs="+", metavar="SOURCE", help="workbook (.xlsx), CSV or Parquet files")
    imports.add_argument("--map", required=True, metavar="MAP.toml", help="how the sources become recordings")
    imports.add_argument("--out", required=True, metavar="DIR", help="directory for one file per run (created)")
    imports.add_argument("--format", choices=("parquet", "csv"), default="parquet",
                         help="the files written (parquet)")
    imports.add_argument("--keep-going", action="store_true",
                         help="write the good runs when some fail (default: all or nothing; the summary says "
                              "which failed and why)")
    imports.add_argument("--json", action="store_true", help="print the runs written as JSON on stdout")
    imports.set_defaults(func=run_import)
    check = commands.add_parser("check", help="what a recording holds, as the tools understand it",
                                formatter_class=raw, epilog="examples:\n" + CHECK_EXAMPLES + MAP_NOTE)
    check.add_argument("file", metavar="FILE", help="a recording, or a foreign file with --map")
    check.add_argument("--map", metavar="MAP.toml", help="read FILE through this map")
    check.add_argument("--json", action="store_true", help="print what was understood as JSON on stdout")
    check.set_defaults(func=run_check)
    group.set_defaults(func=lambda args: group.print_help() or 2)


def sampling(t_s: Any) -> dict[str, float]:
    import numpy as np

    steps = np.diff(t_s)
    return {"median_s": float(np.median(steps)) if len(steps) else 0.0,
            "largest_gap_s": float(np.max(steps)) if len(steps) else 0.0}


def _duration_text(seconds: float) -> str:
    if seconds >= 2 * 3600:
        return f"{seconds / 3600:.2f} h"
    if seconds >= 120:
        return f"{seconds / 60:.1f} min"
    return f"{seconds:g} s"


def _run_document(run: Any) -> dict[str, Any]:
    recording = run.recording
    document: dict[str, Any] = {"name": run.name, "file": run.file, "sheet": run.sheet}
    if recording is None:
        document["error"] = str(run.error)
        return document
    document.update({"rows": len(recording.t_s), "duration_s": recording.duration_s, **sampling(recording.t_s)})
    return document


def _run_line(document: dict[str, Any]) -> str:
    if "error" in document:
        return f"{document['name']}: failed: {document['error']}"
    return (f"{document['name']}: {document['rows']} rows, {_duration_text(document['duration_s'])}, sampling "
            f"{document['median_s']:g} s (largest gap {document['largest_gap_s']:g} s)")


def run_import(args: argparse.Namespace) -> int:
    from .recording_map import load_map, read_sources, safe_file_name

    recording_map = load_map(args.map)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise NckConfigError("exists and is not a directory", path=args.out)
    readings = read_sources(args.sources, recording_map, need_errors=False)
    runs = [run for reading in readings for run in reading.runs]
    names: dict[str, str] = {}
    for run in runs:
        file_name = safe_file_name(run.name)
        if file_name.lower() in names:
            raise NckConfigError(f"runs {names[file_name.lower()]!r} and {run.name!r} would both be written to "
                                 f"{file_name}.{args.format}", path=run.file)
        names[file_name.lower()] = run.name
    failed = [run for run in runs if run.recording is None]
    if failed and not args.keep_going:
        documents = [_run_document(run) for run in runs]
        for run in failed:
            print(f"nckemu recording import: {run.error}", file=sys.stderr)
        summary = (f"nothing written to {out}: {len(failed)} of {len(runs)} run{'s' if len(runs) != 1 else ''} "
                   f"failed ({', '.join(run.name for run in failed)}); --keep-going writes the good ones")
        if args.json:
            print(json.dumps({"runs": documents, "written": 0, "failed": len(failed)}))
        else:
            print(summary)
        return 1
    documents = _write_runs(runs, out, args.format)
    written = len(runs) - len(failed)
    if args.json:
        print(json.dumps({"runs": documents, "written": written, "failed": len(failed)}))
    else:
        for document in documents:
            if "out" in document:
                print(f"{_run_line(document)} -> {document['out']}")
        print(f"{written} run{'s' if written != 1 else ''} written to {out}"
              + (f"; {len(failed)} failed, nothing written for them:" if failed else ""))
        for run in failed:
            print(f"  {run.name}: {run.error}")
    return 1 if failed else 0


def _write_runs(runs: list[Any], out: Path, file_format: str) -> list[dict[str, Any]]:
    """Every good run written, all or nothing: into a temporary directory beside ``out``, which becomes
    ``out`` (or whose files move into an existing ``out``) only once every file is written."""
    import shutil
    import tempfile

    from .recording import write_recording
    from .recording_map import safe_file_name

    parent = out.resolve().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=parent))
    except OSError as exc:
        raise NckConfigError(f"cannot create the directory: {exc.strerror}", path=str(out)) from None
    documents = []
    try:
        for run in runs:
            document = _run_document(run)
            if run.recording is not None:
                name = f"{safe_file_name(run.name)}.{file_format}"
                try:
                    write_recording(staging / name, run.recording)
                except OSError as exc:
                    raise NckConfigError(f"cannot write: {exc.strerror}", path=str(out / name)) from None
                document["out"] = str(out / name)
            documents.append(document)
        try:
            if not out.exists():
                staging.rename(out)
            else:
                for written in sorted(staging.iterdir()):
                    written.replace(out / written.name)
        except OSError as exc:
            raise NckConfigError(f"cannot move the written runs into place: {exc.strerror}", path=str(out)) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return documents


def _project_columns(recording: Any) -> list[dict[str, str]]:
    from .recording import column_kind
    from .recording_map import PROJECT_UNITS, ROLES

    names = ["t_s", *recording.temperatures_C]
    names += ["spindle_rpm"] if recording.spindle_rpm is not None else []
    names += [f"pos_{k}_mm" for k in recording.positions_mm]
    names += [f"err_{k}_um" for k in recording.errors_um]
    names += [f"sim_{k}_um" for k in recording.simulated_um]
    columns = []
    for name in names:
        kind = column_kind(name)
        assert kind is not None
        unit = "s" if kind[0] == "t" else PROJECT_UNITS[kind[0]]
        columns.append({"column": name, "name": name, "role": ROLES[kind[0]], "unit": unit, "project_unit": unit})
    return columns


def _width(text: str) -> int:
    """Terminal columns of ``text``: wide (East Asian) characters take two."""
    import unicodedata

    return sum(2 if unicodedata.east_asian_width(char) in "WF" else 1 for char in text)


def run_check(args: argparse.Namespace) -> int:
    from .recording import load_recording
    from .recording_map import WORKBOOK_SUFFIXES, load_map, read_sources

    document: dict[str, Any] = {"file": args.file, "map": args.map}
    if args.map:
        recording_map = load_map(args.map)
        reading = read_sources([args.file], recording_map, need_errors=False)[0]
        runs = [_run_document(run) for run in reading.runs]
        for run, summary in zip(reading.runs, runs, strict=True):
            if run.sheet is not None:
                summary["sheet"] = run.sheet
        first = reading.runs[0]
        columns = [{"column": use.column, "name": use.name, "role": use.role, "unit": use.unit,
                    "project_unit": use.project_unit} for use in first.columns]
        document["skipped_sheets"] = reading.skipped_sheets
    else:
        if Path(args.file).suffix.lower() in WORKBOOK_SUFFIXES:
            raise NckConfigError("a workbook: say how to read it with --map MAP.toml (docs/recordings.md)",
                                 path=args.file)
        recording = load_recording(args.file, need_errors=False)
        runs = [{"name": recording.name, "file": args.file, "sheet": None, "rows": len(recording.t_s),
                 "duration_s": recording.duration_s, **sampling(recording.t_s)}]
        columns = _project_columns(recording)
    document["runs"] = runs
    document["columns"] = columns
    document["ignored"] = [c["column"] for c in columns if c["role"] == "ignored"]
    failed = sum(1 for run in runs if "error" in run)
    if args.json:
        print(json.dumps(document))
        return 1 if failed else 0
    print(f"{args.file}: {len(runs)} run{'s' if len(runs) != 1 else ''}"
          + (f" (map {args.map})" if args.map else " (the project's format)"))
    for run in runs:
        print(f"  {_run_line(run)}")
    print("columns:")
    width = max(_width(repr(c["column"])) for c in columns)
    for column in columns:
        if column["role"] == "ignored":
            continue
        unit = column["unit"]
        if unit and column["project_unit"] and unit != column["project_unit"]:
            unit = f"{unit} -> {column['project_unit']}"
        target = f"-> {column['name']}" if column["name"] and column["name"] != column["column"] else ""
        shown = repr(column["column"])
        print(f"  {shown}{' ' * (width - _width(shown))} {target:<24} {column['role']}" + (f", {unit}" if unit else ""))
    if document["ignored"]:
        print(f"ignored: {', '.join(repr(c) for c in document['ignored'])}")
    if document.get("skipped_sheets"):
        print(f"sheets that are no run: {', '.join(repr(s) for s in document['skipped_sheets'])}")
    return 1 if failed else 0
