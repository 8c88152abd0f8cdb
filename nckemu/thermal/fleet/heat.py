"""A fleet's heat: each machine folder's `machine fit` as one Dask task (as `discover --fleet` runs each
machine's discovery), and the heat terms tabulated across the fleet: which term on which sensor, on how
many machines, with the spread of its gain and time constant."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from nckemu.errors import NckError

from .discover import MachineFolder, _connect, _spread, _worker_name


def fit_machine(machine: MachineFolder, inputs: Sequence[str]) -> dict[str, Any]:
    """The Dask task: read this machine's runs, fit each sensor's heat, return the fit as JSON."""
    from nckemu.thermal.heat.fit import fit_heat
    from nckemu.thermal.heat.table import load_heat_runs

    try:
        runs = load_heat_runs(list(machine.runs), list(inputs))
        return {"machine": machine.name, "worker": _worker_name(), **fit_heat(runs).to_json()}
    except NckError as exc:
        return {"machine": machine.name, "worker": _worker_name(), "error": str(exc)}


def heat_table(machines: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (sensor, term): on how many machines it was named, and the spread of K and tau_s."""
    found: dict[tuple[str, str], list[tuple[str, dict[str, Any]]]] = {}
    fitted = [m for m in machines if "sensors" in m]
    for machine in fitted:
        for sensor in machine["sensors"]:
            for term in sensor["terms"]:
                label = term["name"] + (f" {term['sensor']}" if term.get("sensor") else "")
                found.setdefault((sensor["sensor"], label), []).append((machine["machine"], term))
    rows = []
    for (sensor, label), hits in sorted(found.items(), key=lambda item: (-len(item[1]), item[0])):
        rows.append({"sensor": sensor, "term": label, "machines": len({name for name, _ in hits}), "of": len(fitted),
                     "K": _spread([float(term["K"]) for _, term in hits]),
                     "tau_s": _spread([float(term["tau_s"]) for _, term in hits])})
    return rows


def fit_fleet(machines: Sequence[MachineFolder], inputs: Sequence[str], *, scheduler: str | None = None,
              workers: int | None = None, progress: Callable[[Any, int], Any] | None = None) -> dict[str, Any]:
    import logging

    from distributed import as_completed

    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    client, cluster, engine = _connect(scheduler, workers, 10.0)
    try:
        keys = [f"nckemu-heat-{index:05d}-{machine.name}" for index, machine in enumerate(machines)]
        futures = client.map(fit_machine, list(machines), inputs=list(inputs), key=keys)
        finished = as_completed(futures, with_results=True)
        results = [result for _future, result in (progress(finished, len(futures)) if progress else finished)]
        del futures, finished
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    ordered = sorted(results, key=lambda m: m["machine"])
    return {"engine": engine, "machines": ordered, "table": heat_table(ordered),
            "failed": {m["machine"]: m["error"] for m in ordered if "error" in m}}
