"""Fleet discovery: every machine's discovery as one task on a Dask cluster, and the fleet table.

ROOT holds one folder per machine: its runs (CSV or Parquet) and optionally its model TOML. A task
gets the folder's paths, never arrays: the worker reads its machine's data itself, so the client
ships a few hundred bytes per machine whatever the data's size (the paths must then be readable on
the workers: a shared file system on a cluster). Dask schedules, retries a task whose worker was lost
(``distributed.scheduler.allowed-failures``) and balances; nckemu only says what to run.
"""

from __future__ import annotations

import html
import math
import os
import socket
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nckemu.cliutil import write_atomically
from nckemu.errors import NckConfigError, NckError

RUN_SUFFIXES = (".csv", ".parquet", ".pq")
# How long to try to reach --scheduler before saying it cannot be reached.
SCHEDULER_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class MachineFolder:
    """One machine of the fleet: its name (the folder's), its runs and its model, as absolute paths."""

    name: str
    runs: tuple[str, ...]
    model: str | None = None


def scan_root(root: str | Path) -> list[MachineFolder]:
    """The machine folders under ``root``; a folder without runs, or with two models, is refused."""
    root = Path(root)
    if not root.is_dir():
        raise NckConfigError("--fleet: not a directory (one folder per machine)", path=str(root))
    # "." hidden, "_" the reduced trees (``fleet_reduce``): neither is a machine
    folders = sorted(entry for entry in root.iterdir() if entry.is_dir() and not entry.name.startswith((".", "_")))
    if not folders:
        raise NckConfigError("--fleet: no machine folders in it (one folder per machine: its runs as CSV "
                             "or Parquet, optionally its model TOML)", path=str(root))
    machines = []
    for folder in folders:
        files = sorted(entry for entry in folder.iterdir() if entry.is_file() and not entry.name.startswith("."))
        runs = tuple(str(entry.resolve()) for entry in files if entry.suffix.lower() in RUN_SUFFIXES)
        models = [str(entry.resolve()) for entry in files if entry.suffix.lower() == ".toml"]
        if not runs:
            raise NckConfigError("no recordings in this machine folder (expected runs as *.csv or *.parquet)",
                                 path=str(folder))
        if len(models) > 1:
            raise NckConfigError(f"two model TOMLs ({', '.join(Path(m).name for m in models)}): keep one",
                                 path=str(folder))
        machines.append(MachineFolder(folder.name, runs, models[0] if models else None))
    return machines


# ---------------------------------------------------------------------------- the task (on a worker)
def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def discover_machine(machine: MachineFolder, axis: str | None = None) -> dict[str, Any]:
    """The Dask task: read this machine's runs and model, discover, return the findings as JSON.

    Bad data of one machine is that machine's error in the result, not the fleet's."""
    from nckemu.thermal.discovery.discover import discover_runs
    from nckemu.thermal.model.terms import Term, ThermalModel, load_model
    from nckemu.thermal.recordings.recording import load_runs

    document: dict[str, Any] = {"machine": machine.name, "runs": [Path(run).name for run in machine.runs],
                                "model": Path(machine.model).name if machine.model else None,
                                "worker": _worker_name()}
    try:
        model = load_model(machine.model) if machine.model else None
        chosen = axis or (model.axis if model is not None else None)
        runs = load_runs(list(machine.runs), chosen)
        if chosen is None:
            axes = sorted(set.intersection(*(set(run.errors_um) for run in runs)))
            if len(axes) != 1:
                raise NckConfigError(f"which axis? give --axis ({', '.join(axes) or 'no err_<axis>_um column'})",
                                     path=machine.runs[0])
            chosen = axes[0]
        if model is None and len(runs) == 1 and chosen not in runs[0].simulated_um:
            # as `discover REC.csv` does: the sensors explain the axis on their own (several runs: each
            # run's own offset, discover_runs's baseline)
            model = ThermalModel(chosen, [Term("offset", {"value_um": 0.0})], "<constant offset>")
        result = discover_runs(runs, axis=chosen, model=model)
    except NckError as exc:
        document["error"] = str(exc)
        return document
    except Exception as exc:  # noqa: BLE001 - one machine's failure is its own, never the fleet's
        document["error"] = f"{machine.name}: discovery failed: {exc.__class__.__name__}: {exc}"
        return document
    document["findings"] = result.to_json()
    return document


# ---------------------------------------------------------------------------- the fleet table
def _spread(values: list[float]) -> dict[str, float]:
    ordered = sorted(values)
    middle = len(ordered) // 2
    median = ordered[middle] if len(ordered) % 2 else (ordered[middle - 1] + ordered[middle]) / 2
    mean = sum(ordered) / len(ordered)
    std = math.sqrt(sum((v - mean) ** 2 for v in ordered) / (len(ordered) - 1)) if len(ordered) > 1 else 0.0
    return {"min": ordered[0], "median": median, "max": ordered[-1], "std": std}


def fleet_table(machines: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Which physics is missing on how many machines, with the spread of each numeric parameter."""
    found: dict[str, list[tuple[str, dict[str, Any]]]] = {}
    analysed = [m for m in machines if "findings" in m]
    for machine in analysed:
        for effect in machine["findings"]["missing_physics"]:
            found.setdefault(effect["effect"], []).append((machine["machine"], effect.get("parameters", {})))
    rows = []
    for effect, hits in sorted(found.items(), key=lambda item: (-len(item[1]), item[0])):
        names = sorted({name for name, _ in hits})
        numeric: dict[str, list[float]] = {}
        for _, parameters in hits:
            for key, value in parameters.items():
                if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
                    numeric.setdefault(key, []).append(float(value))
        rows.append({"effect": effect, "machines": len(names), "of": len(analysed), "names": names,
                     "parameters": {key: _spread(values) for key, values in sorted(numeric.items())}})
    return rows


def fleet_document(machines: list[dict[str, Any]], root: str, axis: str | None, engine: str) -> dict[str, Any]:
    ordered = sorted(machines, key=lambda m: m["machine"])
    return {
        "fleet": root, "axis": axis, "engine": engine,
        "machines": ordered,
        "table": fleet_table(ordered),
        "nothing_missing": [m["machine"] for m in ordered if "findings" in m and not m["findings"]["missing_physics"]],
        "failed": {m["machine"]: m["error"] for m in ordered if "error" in m},
        "retried": {m["machine"]: m["worker_losses"] for m in ordered if m.get("worker_losses")},
    }


# ---------------------------------------------------------------------------- running on Dask
def _worker_losses(keys: Sequence[str], dask_scheduler: Any = None) -> dict[str, int]:
    """On the scheduler: how often each task was on a worker that died (Dask then ran it again)."""
    tasks = dask_scheduler.tasks
    return {key: int(tasks[key].suspicious) for key in keys if key in tasks}


def _connect(scheduler: str | None, workers: int | None, timeout_s: float) -> tuple[Any, Any, str]:
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return Client(scheduler, timeout=f"{timeout_s}s"), None, scheduler
        except (OSError, TimeoutError, ValueError) as exc:
            reason = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
            raise NckConfigError(f"--scheduler {scheduler}: cannot reach it within {timeout_s:g} s ({reason})") from None
    count = workers or max(1, min(os.cpu_count() or 1, 8))
    # the HTTP endpoints on a free loopback port: the default 8787 may be taken (a warning on stderr)
    cluster = LocalCluster(n_workers=count, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                           host="127.0.0.1")
    return Client(cluster), cluster, f"local cluster, {count} worker(s)"


def discover_fleet(machines: Sequence[MachineFolder], *, axis: str | None = None, scheduler: str | None = None,
                   workers: int | None = None, timeout_s: float = SCHEDULER_TIMEOUT_S,
                   progress: Callable[[Any, int], Any] | None = None, root: str = "",
                   reduce_step_s: float | None = None,
                   reduce_progress: Callable[[Any, int], Any] | None = None) -> dict[str, Any]:
    """Each machine's ``discover_machine`` as a Dask task; the fleet document (per machine + table).

    ``scheduler``: a running cluster's address (tcp://HOST:PORT), else an in-process local cluster of
    ``workers`` processes. ``progress(iterable, total)`` wraps the stream of finished machines.
    ``reduce_step_s``: first each run file reduced to window means (``fleet_reduce``, one task per file,
    ``reduce_progress`` wraps those), then discovery on the reduced files."""
    import logging

    from distributed import as_completed

    # distributed logs a worker's death and the retry at WARNING/ERROR on our stderr; the result says it
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    client, cluster, engine = _connect(scheduler, workers, timeout_s)
    reduced: dict[str, Any] | None = None
    try:
        if reduce_step_s is not None:
            machines, reduced = _reduce(client, list(machines), root, reduce_step_s, reduce_progress)
        keys = [f"nckemu-discover-{index:05d}-{machine.name}" for index, machine in enumerate(machines)]
        futures = client.map(discover_machine, list(machines), axis=axis, key=keys)
        finished = as_completed(futures, with_results=True)
        results = [result for _future, result in (progress(finished, len(futures)) if progress else finished)]
        losses = client.run_on_scheduler(_worker_losses, keys)
        by_name = {machine.name: key for machine, key in zip(machines, keys, strict=True)}
        for result in results:
            result["worker_losses"] = losses.get(by_name[result["machine"]], 0)
        del futures, finished
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    document = fleet_document(results, root, axis, engine)
    if reduced is not None:
        document["reduce"] = reduced
        document["failed"].update(reduced["machines_without_runs"])
    return document


def _reduce(client: Any, machines: list[MachineFolder], root: str, step_s: float,
            progress: Callable[[Any, int], Any] | None) -> tuple[list[MachineFolder], dict[str, Any]]:
    """Stage 1 on the cluster: the files not yet reduced, one task each; the machines over their reduced
    runs (a file that failed is left out and listed; a machine left without runs is not discovered)."""
    from distributed import as_completed

    from .reduce import plan, reduce_file

    tasks = plan(machines, root, step_s)
    todo = [task for task in tasks if not task.up_to_date()]
    keys = [f"nckemu-reduce-{index:06d}-{task.machine}-{Path(task.source).name}" for index, task in enumerate(todo)]
    futures = client.map(reduce_file, todo, step_s=step_s, key=keys)
    finished = as_completed(futures, with_results=True)
    results = [result for _future, result in (progress(finished, len(futures)) if progress else finished)]
    del futures, finished
    failed = {result["source"]: result["error"] for result in results if "error" in result}
    kept: list[MachineFolder] = []
    without: dict[str, str] = {}
    for machine in machines:
        runs = tuple(task.target for task in tasks if task.machine == machine.name and task.source not in failed)
        if runs:
            kept.append(MachineFolder(machine.name, runs, machine.model))
        else:
            without[machine.name] = "no run could be reduced"
    summary = {"step_s": step_s, "files": len(tasks), "reduced": len(todo) - len(failed),
               "up_to_date": len(tasks) - len(todo), "failed": failed, "machines_without_runs": without,
               "rows_in": sum(r.get("rows_in", 0) for r in results), "rows_out": sum(r.get("rows_out", 0) for r in results)}
    return kept, summary


# ---------------------------------------------------------------------------- HTML
def _number(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else html.escape(str(value))


def write_fleet_report(path: str | Path, document: dict[str, Any], title: str) -> None:
    """A self-contained HTML page: the fleet table, then one row per machine."""
    table_rows = []
    for row in document["table"]:
        spread = "<br>".join(f"{html.escape(key)}: {_number(s['median'])} (min {_number(s['min'])}, max "
                             f"{_number(s['max'])}, sd {_number(s['std'])})" for key, s in row["parameters"].items())
        table_rows.append(f"<tr><td>{html.escape(row['effect'])}</td><td>{row['machines']} of {row['of']}</td>"
                          f"<td>{spread}</td><td>{html.escape(', '.join(row['names']))}</td></tr>")
    machine_rows = []
    for machine in document["machines"]:
        name = html.escape(machine["machine"])
        runs = len(machine["runs"])
        note = f" (retried: {machine['worker_losses']} worker(s) lost)" if machine.get("worker_losses") else ""
        if "error" in machine:
            machine_rows.append(f"<tr><td>{name}</td><td>{runs}</td><td colspan=3 class=bad>"
                                f"{html.escape(machine['error'])}</td><td>{note}</td></tr>")
            continue
        findings = machine["findings"]
        missing = "; ".join(f"{e['effect']} {', '.join(f'{k}={_number(v)}' for k, v in e['parameters'].items())}"
                            for e in findings["missing_physics"]) or "nothing missing"
        machine_rows.append(
            f"<tr><td>{name}</td><td>{runs}</td><td>{findings['samples']}</td>"
            f"<td>{findings['heldout_rms_before_um']:.3f} &rarr; {findings['heldout_rms_after_um']:.3f}</td>"
            f"<td>{html.escape(missing)}</td><td>{html.escape(note)}</td></tr>")
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse;margin-bottom:2em}}
td,th{{border:1px solid #ccc;padding:4px 8px;vertical-align:top;text-align:left}}.bad{{color:#a00}}</style>
</head><body><h1>{html.escape(title)}</h1>
<p>{len(document['machines'])} machine(s), axis {html.escape(str(document['axis'] or 'per machine'))}, on
{html.escape(document['engine'])}; {len(document['failed'])} failed, {len(document['retried'])} retried after
a worker was lost.</p>
<h2>Missing physics across the fleet</h2>
<table><tr><th>effect</th><th>machines</th><th>parameters: median (spread)</th><th>which</th></tr>
{''.join(table_rows) or '<tr><td colspan=4>nothing missing on any machine</td></tr>'}</table>
<h2>Machines</h2>
<table><tr><th>machine</th><th>runs</th><th>samples</th><th>held-out RMS (um)</th><th>missing physics</th><th></th></tr>
{''.join(machine_rows)}</table></body></html>
"""
    try:
        write_atomically(path, lambda target: target.write_text(page, encoding="utf-8"))
    except OSError as exc:
        raise NckConfigError(f"cannot write: {exc.strerror}", path=str(path)) from None
