"""Run the public SINUMERIK programs of bench/corpus/manifest.toml and say, per program, how far each got.

    python bench/corpus_fetch.py ~/nckemu-corpus          # once (needs GitHub)
    python bench/bench_corpus.py ~/nckemu-corpus [--machine M.toml] [--only NAME] [--json]

Each main program runs offline (a simulated clock, as ``nckemu program run``) on its repository's
machine file, with every subprogram and definition file its repository's globs name stored first
(subprograms in /_N_SPF_DIR, definition files in /_N_DEF_DIR under their own names, the other main
programs of its folder in /_N_MPF_DIR). One line per program:

    ran      simulated time to M30/M2 (or the end of the file)
    alarm    the NCK alarm that stopped it: number, text (the feature), program and line
    crashed  an exception of ours (a traceback in the log, or one escaping the run)
    timeout  still running after --max-time of simulated time or --wall seconds of real time

then the tally, and the alarms ranked by the programs they stop. Each program runs in its own process,
so a program that never ends costs --wall seconds and no more. A [[program]] of the manifest may give
itself more (max_time_s, wall_s, with why) and files of ours (values, under bench/corpus/: GUD and R
values, a machine's macros), stored after its definition files.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import logging
import multiprocessing
import re
import sys
import time
import traceback
from collections import Counter
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.corpus_fetch import load_manifest, repository_dir  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
MANIFEST_DIR = ROOT / "bench" / "corpus"
_ALARM = re.compile(r"alarm (\d+): (.*?)(?: \((\S+) line (\d+): (.*)\))?$")


def _stem(name: str) -> str:
    stem = name.split(".", 1)[0].upper()
    return re.sub(r"[^A-Z0-9_]", "_", stem)[:24] or "X"


def _matching(tree: Path, patterns: list[str]) -> list[Path]:
    found = []
    uppers = [pattern.upper() for pattern in patterns]
    for path in sorted(tree.rglob("*")):
        if path.is_file() and ".git" not in path.parts:
            relative = path.relative_to(tree).as_posix().upper()
            if any(fnmatch.fnmatchcase(relative, pattern) for pattern in uppers):
                found.append(path)
    return found


def _files(tree: Path, repository: dict, main: Path) -> list[tuple[str, bytes]]:
    """(NC path, text) of everything stored before ``main``: definitions first, as a control has them."""
    stored: list[tuple[str, bytes]] = []
    for path in _matching(tree, repository.get("definitions", [])):
        stored.append((f"/_N_DEF_DIR/_N_{_stem(path.name)}_DEF", path.read_bytes()))
    for path in _matching(tree, repository.get("subprograms", [])):
        stored.append((f"/_N_SPF_DIR/_N_{_stem(path.name)}_SPF", path.read_bytes()))
    for path in sorted(main.parent.iterdir()):
        if path != main and path.is_file() and path.suffix.upper() == ".MPF":
            stored.append((f"/_N_MPF_DIR/_N_{_stem(path.name)}_MPF", path.read_bytes()))
    return stored


def _values(entry: dict) -> list[tuple[str, bytes]]:
    """The program's GUD and R values and the machine's macros (``values`` in the manifest: a file of ours
    under bench/corpus/, or a list: NAME.GUD, NAME.RPA, MMAC.DEF), stored after its repository's
    definition files as a shop's archive of the HMI's values would be loaded."""
    names = entry.get("values") or []
    stored = []
    for name in [names] if isinstance(names, str) else names:
        path = MANIFEST_DIR / name
        kind = path.suffix.upper().lstrip(".")
        stored.append((f"/_N_DEF_DIR/_N_{_stem(path.name)}_{kind}", path.read_bytes()))
    return stored


class _Faults(logging.Handler):
    """Records logged with a traceback: a fault of ours, even when the channel turned it into an alarm."""

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.tracebacks: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        if record.exc_info:
            self.tracebacks.append("".join(traceback.format_exception(*record.exc_info)))


class _OutOfTime(Exception):
    """The program's real-time budget is spent (raised from the block listener, caught by run_one)."""


class _Blocks:
    """Counts the executed blocks by (program, line): where a program that does not end spends its time."""

    def __init__(self, wall_s: float) -> None:
        self.counts: Counter[tuple[str, int, str]] = Counter()
        self.deadline = time.monotonic() + wall_s

    def __call__(self, record: Any) -> None:
        self.counts[(record.program.rsplit("/", 1)[-1], record.line, record.text[:60])] += 1

    def check(self, _row: list[float]) -> None:
        """Once a machine cycle, between cycles (an exception from the block listener would reach the
        channel, which turns any exception into an internal-error alarm)."""
        if time.monotonic() > self.deadline:
            raise _OutOfTime

    def hottest(self) -> str:
        if not self.counts:
            return ""
        (program, line, text), count = self.counts.most_common(1)[0]
        return f"; busiest block {program} line {line}: {text} ({count} times)"


def run_one(machine: str, main: str, stored: list[tuple[str, bytes]], max_time_s: float,
            wall_s: float = 1.0e9) -> dict[str, Any]:
    """Run one program in this process; the outcome as a dict (never raises)."""
    from nckemu.emulator.machine.clock import SimulatedClock
    from nckemu.emulator.machine.core import Emulator
    from nckemu.emulator.machine.offline import run_offline
    from nckemu.errors import NckError

    faults = _Faults()
    logging.getLogger("nckemu").addHandler(faults)
    try:
        emulator = Emulator(str(ROOT / machine), clock=SimulatedClock())
        refused = []
        for path, text in stored:
            try:
                emulator.nck.programs.write(path, text)
            except NckError as exc:
                refused.append(f"{path}: {exc}")
        target = f"/_N_MPF_DIR/_N_{_stem(Path(main).name)}_MPF"
        emulator.nck.programs.write(target, Path(main).read_bytes())
        blocks = _Blocks(wall_s)
        result = run_offline(emulator, target, max_time_s=max_time_s, on_block=blocks, on_sample=blocks.check)
    except _OutOfTime:
        return {"outcome": "timeout", "detail": f"still running after {wall_s:.0f} s of real time"
                                                f"{blocks.hottest()}"}
    except Exception:  # the outcome "crashed": what the runner exists to find
        return {"outcome": "crashed", "detail": traceback.format_exc(limit=8)}
    finally:
        logging.getLogger("nckemu").removeHandler(faults)
    outcome: dict[str, Any] = {"blocks": result.blocks, "refused": refused}
    if faults.tracebacks:
        outcome.update(outcome="crashed", detail=faults.tracebacks[0])
    elif result.outcome == "ended":
        outcome.update(outcome="ran", time_s=round(result.t_s, 3))
    elif result.outcome == "alarm":
        text = result.alarms[0] if result.alarms else ""
        match = _ALARM.search(text)
        outcome.update(outcome="alarm", detail=text)
        if match:
            outcome.update(number=int(match.group(1)), feature=match.group(2),
                           alarm_program=match.group(3) or "", line=int(match.group(4) or 0),
                           block=(match.group(5) or "").strip())
    else:
        outcome.update(outcome="timeout", detail=f"still running after {result.t_s:.0f} s simulated"
                                                 f"{blocks.hottest()}")
    return outcome


def _worker(queue: Any, args: tuple) -> None:
    queue.put(run_one(*args))


def run_isolated(args: tuple, wall_s: float) -> dict[str, Any]:
    context = multiprocessing.get_context("fork" if sys.platform != "win32" else "spawn")
    queue = context.Queue()
    process = context.Process(target=_worker, args=(queue, args), daemon=True)
    process.start()
    try:
        return queue.get(timeout=wall_s)
    except Exception:
        return {"outcome": "timeout", "detail": f"still running after {wall_s:.0f} s of real time"}
    finally:
        process.join(timeout=1)
        if process.is_alive():
            process.kill()
            process.join()


def programs(corpus: Path, manifest: dict, only: str = "",
             machine: str = "") -> list[tuple[dict, Path, Path, dict]]:
    """(repository entry, repository tree, main program, program entry) of every program fetched into
    ``corpus``."""
    repositories = {entry["repo"]: entry for entry in manifest["repository"]}
    found = []
    for entry in manifest["program"]:
        repository = dict(repositories[entry["repo"]])
        if entry.get("machine"):  # a program of another machine than its repository's others
            repository["machine"] = entry["machine"]
        if machine:
            repository["machine"] = machine
        tree = repository_dir(corpus, entry["repo"])
        main = tree / entry["path"]
        if only and only.upper() not in f"{entry['repo']}/{entry['path']}".upper():
            continue
        if main.is_file():
            found.append((repository, tree, main, entry))
    return found


def describe(outcome: dict[str, Any]) -> str:
    kind = outcome["outcome"]
    if kind == "ran":
        return f"ran      {outcome['time_s']:.1f} s simulated, {outcome['blocks']} blocks"
    if kind == "alarm":
        if "number" in outcome:
            where = outcome["alarm_program"].rsplit("/", 1)[-1]
            return f"alarm    {outcome['number']} {outcome['feature']} ({where} line {outcome['line']}: {outcome['block'][:60]})"
        return f"alarm    {outcome['detail']}"
    if kind == "crashed":
        return "crashed  " + outcome["detail"].strip().splitlines()[-1]
    return f"timeout  {outcome['detail']}"


def feature_key(outcome: dict[str, Any]) -> str:
    """What blocks a program, grouped: the alarm number and the feature's words without numbers."""
    if outcome["outcome"] == "timeout":
        waits = any(name in outcome["detail"] for name in ("$A_IN", "$A_DB", "$A_OUT"))
        return "timeout: waits for its PLC ($A_IN/$A_DBB)" if waits else "timeout: still computing or moving"
    if outcome["outcome"] != "alarm" or "number" not in outcome:
        return outcome["outcome"]
    feature = re.sub(r"[-\d.]+", "#", outcome["feature"])[:70]
    return f"{outcome['number']} {feature}"


def run_corpus(corpus: Path, *, only: str = "", machine: str = "", max_time_s: float = 4 * 3600.0,
               wall_s: float = 60.0, on_result: Any = None) -> list[dict[str, Any]]:
    """Every fetched program of the manifest, run; one result dict each."""
    results = []
    for repository, tree, main_path, entry in programs(corpus, load_manifest(), only, machine):
        stored = _files(tree, repository, main_path)
        stored += _values(entry)
        # a program the manifest knows to be long has its own budget (max_time_s, wall_s and why)
        own_max_s = max(max_time_s, float(entry.get("max_time_s", 0.0)))
        own_wall_s = max(wall_s, float(entry.get("wall_s", 0.0)))
        outcome = run_isolated((repository["machine"], str(main_path), stored, own_max_s, own_wall_s),
                               own_wall_s + 30.0)
        result = {"repo": repository["repo"], "program": f"{repository['repo']}/{main_path.relative_to(tree).as_posix()}",
                  **outcome}
        results.append(result)
        if on_result is not None:
            on_result(result)
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("corpus", type=Path, help="the directory bench/corpus_fetch.py fetched into")
    parser.add_argument("--machine", default="", help="run every program on this machine file instead")
    parser.add_argument("--only", default="", help="only programs whose repo/path contains this")
    parser.add_argument("--max-time", type=float, default=4 * 3600.0, help="simulated seconds per program")
    parser.add_argument("--wall", type=float, default=60.0, help="real seconds per program")
    parser.add_argument("--json", action="store_true", help="one JSON document instead of the text")
    args = parser.parse_args(argv)
    if not programs(args.corpus, load_manifest(), args.only, args.machine):
        print(f"no program of the manifest under {args.corpus} (run bench/corpus_fetch.py first)", file=sys.stderr)
        return 1
    started = time.monotonic()

    def show(result: dict[str, Any]) -> None:
        if not args.json:
            print(f"{result['program']:70s} {describe(result)}", flush=True)

    results = run_corpus(args.corpus, only=args.only, machine=args.machine, max_time_s=args.max_time,
                         wall_s=args.wall, on_result=show)
    tally = Counter(result["outcome"] for result in results)
    blockers = Counter(feature_key(result) for result in results if result["outcome"] != "ran")
    if args.json:
        print(json.dumps({"programs": results, "tally": dict(tally), "blockers": dict(blockers.most_common())},
                         indent=1))
        return 0
    repositories = len({result["repo"] for result in results})
    print(f"\n{len(results)} programs from {repositories} repositories in {time.monotonic() - started:.0f} s: "
          + ", ".join(f"{tally[kind]} {kind}" for kind in ("ran", "alarm", "crashed", "timeout")))
    for key, count in blockers.most_common():
        print(f"  {count:3d}  {key}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
