"""Discovery over many runs: 30 runs x 24 h at 1 Hz with 6 sensors (issue 23: under 60 s here; issue 31:
still under 60 s with pair moves on, the same discovery without pair moves printed as the anchor; issue
42: and with a second time constant and measured partners, the same without them printed too; issue 42's
second part: and with the runs' paired test in place of the t-test, the admission before it printed too).

The anchor, measured in the same run: single-run discovery on the same data, the runs laid end to end
as one recording and averaged to the steps discover_runs works on (Settings.runs_resample_s, 30 s).
On the raw 1 Hz rows (2.56 million) single-run discovery is no anchor: it held 16 GB and had not
finished after 18 min when stopped (``--raw-anchor`` runs it anyway). Also the time to write the runs
and read them back with load_runs, CSV against Parquet.

Usage: .venv/bin/python bench/bench_discover_runs.py [--runs 30] [--hours 24] [--dt 1] [--no-anchor]
       [--family job_mix_gradient | null_job_mix | ...]
A null family is the costly case for pair moves: no single effect passes, so every round ends in a
screen of pairs and the beam's cross-validations.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from nckemu.thermal.discovery.discover import discover, discover_runs  # noqa: E402
from nckemu.thermal.discovery.readings import resample  # noqa: E402
from nckemu.thermal.discovery.settings import Settings  # noqa: E402
from nckemu.thermal.recordings.recording import Recording, load_runs, write_recording  # noqa: E402
from nckemu.thermal.synthetic.scenarios import AXIS, make_run_family  # noqa: E402


def end_to_end(runs: list[Recording]) -> Recording:
    """The runs as one recording, each starting one median interval after the previous one ends."""
    pieces, shift = [], 0.0
    for run in runs:
        pieces.append(run.t_s - run.t_s[0] + shift)
        shift = pieces[-1][-1] + float(np.median(np.diff(run.t_s)))
    sensors = sorted(set.intersection(*(set(run.temperatures_C) for run in runs)))
    rpm = None if any(run.spindle_rpm is None for run in runs) else np.concatenate([run.spindle_rpm for run in runs])
    return Recording("<runs end to end>", np.concatenate(pieces),
                     {k: np.concatenate([run.temperatures_C[k] for run in runs]) for k in sensors}, rpm, {},
                     {AXIS: np.concatenate([run.errors_um[AXIS] for run in runs])})


def timed(label: str, work):  # noqa: ANN001, ANN201 - a bench helper
    started = time.perf_counter()
    result = work()
    elapsed = time.perf_counter() - started
    print(f"{label:<46} {elapsed:8.2f} s", flush=True)
    return result, elapsed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--dt", type=float, default=1.0, help="mean sampling interval, s")
    parser.add_argument("--family", default="job_mix_gradient")
    parser.add_argument("--no-anchor", action="store_true", help="skip single-run discover on the same data")
    parser.add_argument("--raw-anchor", action="store_true",
                        help="the anchor on the raw rows, not averaged (needs > 16 GB at the default size)")
    parser.add_argument("--no-files", action="store_true", help="skip writing and reading CSV/Parquet")
    args = parser.parse_args()

    family, _ = timed("generate", lambda: make_run_family(args.family, 1, args.runs, args.hours, args.dt,
                                                          missing_share=0.0))
    runs = family.runs
    rows = sum(len(run.t_s) for run in runs)
    readings = sum(int(np.count_nonzero(~np.isnan(run.errors_um[AXIS]))) for run in runs)
    print(f"{len(runs)} runs x {args.hours:g} h, mean dt {args.dt:g} s: {rows} rows, {readings} gauge readings, "
          f"{len(runs[0].temperatures_C)} sensors")
    if not args.no_files:
        with tempfile.TemporaryDirectory() as directory:
            for suffix in (".parquet", ".csv"):
                folder = Path(directory) / suffix[1:]
                folder.mkdir()
                timed(f"write {suffix[1:]}", lambda f=folder, s=suffix: [write_recording(f / f"{r.name}{s}", r)
                                                                          for r in runs])
                size_mb = sum(p.stat().st_size for p in folder.iterdir()) / 1e6
                timed(f"load_runs {suffix[1:]} ({size_mb:.0f} MB)", lambda f=folder: load_runs([f], axis=AXIS))

    result, elapsed_runs = timed("discover_runs (pair moves on)", lambda: discover_runs(runs, AXIS, family.model))
    named = [m.effect for m in result.missing_physics]
    print(f"  named: {', '.join(named) or '-'} (truth: {family.truth.effect})")
    without = Settings(pair_moves=False)
    result, elapsed_single = timed("anchor: discover_runs, pair moves off",
                                   lambda: discover_runs(runs, AXIS, family.model, without))
    named = [m.effect for m in result.missing_physics]
    print(f"  named: {', '.join(named) or '-'}; pair moves cost {elapsed_runs - elapsed_single:+.2f} s")
    narrow = Settings(second_time_constant_ratio=0.0, measured_partners=False)
    result, elapsed_narrow = timed("anchor: discover_runs, issue 42's searches off",
                                   lambda: discover_runs(runs, AXIS, family.model, narrow))
    named = [m.effect for m in result.missing_physics]
    print(f"  named: {', '.join(named) or '-'}; a second time constant and measured partners cost "
          f"{elapsed_runs - elapsed_narrow:+.2f} s")
    before = Settings(runs_replace_t_test=False, runs_min_improvement=Settings().min_improvement, max_effects=4)
    result, elapsed_before = timed("anchor: discover_runs, admission as before issue 42's second part",
                                   lambda: discover_runs(runs, AXIS, family.model, before))
    named = [m.effect for m in result.missing_physics]
    print(f"  named: {', '.join(named) or '-'}; the paired test's admission, a second time constant in later "
          f"rounds, withdrawal and the closest candidates cost {elapsed_runs - elapsed_before:+.2f} s")
    if not args.no_anchor:
        whole = end_to_end(runs)
        if not args.raw_anchor:
            whole = resample(whole, Settings().runs_resample_s)
        result, elapsed_one = timed(f"anchor: discover, the runs end to end, {len(whole.t_s)} rows",
                                    lambda: discover(whole, AXIS, family.model))
        print(f"ratio discover_runs / anchor: {elapsed_runs / elapsed_one:.2f}")
    print(f"target: discover_runs under 60 s: {'met' if elapsed_runs < 60 else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
