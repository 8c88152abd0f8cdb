"""``nckemu loop``: test a compensation program against a recorded machine, find what it misses,
generate the fixed program and judge it on held-out blocks of the recording.

1. The user's program runs in awlsim against the emulator, driven by the recording
   (``replay.run_on_recording``): ``sim_`` is what the NCK would have compensated.
2. ``discover`` takes that column as the baseline: what the program compensated, the residual, where
   it falls short, what physics it leaves out.
3. The improved model is generated as STL (``stlgen``) and run the same way.
Held-out judgement: the recording is cut into ``folds`` contiguous blocks of time; for each block the
program's coefficients are fitted on the other blocks (the effects and their time constants come
from step 2, fitted on all data, as ``discover`` does), the program is generated and run over the
whole recording, and its residual is kept on the block it did not see.
"""

from __future__ import annotations

import base64
import html
import io
import math
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from nckemu.cliutil import write_atomically
from nckemu.emulator.machine.machine_file import Axis, Machine, load_machine
from nckemu.thermal import stats
from nckemu.thermal.discovery.discover import Discovery, discover
from nckemu.thermal.discovery.plcmodel import PlcModel, plc_model, terms_of
from nckemu.thermal.discovery.report import findings_html
from nckemu.thermal.discovery.wording import program_findings
from nckemu.thermal.recordings.recording import Recording

from .bridge import check_program
from .replay import plc_inputs, recording_axis, run_on_recording, with_simulation
from .stlgen import GeneratedProgram, generate_program


@dataclass
class LoopResult:
    axis: Axis
    letter: str
    recording: Recording
    sim_old_um: np.ndarray
    sim_new_um: np.ndarray
    heldout_sim_um: np.ndarray            # each block from the program fitted without it
    discovery: Discovery
    plc: PlcModel
    program: GeneratedProgram
    findings: list[tuple[str, str]]
    fold_rms_um: list[tuple[float, float]] = field(default_factory=list)   # (before, after) per block
    warnings: list[str] = field(default_factory=list)

    def _rms(self, sim: np.ndarray) -> float:
        error = self.recording.errors_um[self.letter]
        rows = np.isfinite(error) & np.isfinite(sim)
        return stats.rms((error - sim)[rows])

    @property
    def rms_error_um(self) -> float:
        return self._rms(np.zeros_like(self.sim_old_um))

    @property
    def rms_before_um(self) -> float:
        return self._rms(self.sim_old_um)

    @property
    def rms_after_um(self) -> float:
        return self._rms(self.sim_new_um)

    @property
    def heldout_rms_after_um(self) -> float:
        return self._rms(self.heldout_sim_um)

    def to_json(self) -> dict[str, Any]:
        return {
            "axis": self.letter, "machine_axis": self.axis.number,
            "rms_error_um": round(self.rms_error_um, 4),
            "residual_rms_before_um": round(self.rms_before_um, 4),
            "residual_rms_after_in_sample_um": round(self.rms_after_um, 4),
            "heldout": {"residual_rms_before_um": round(self.rms_before_um, 4),
                        "residual_rms_after_um": round(self.heldout_rms_after_um, 4),
                        "blocks": [{"before_um": round(b, 4), "after_um": round(a, 4)} for b, a in self.fold_rms_um]},
            "program": dict(self.findings),
            "discovery": self.discovery.to_json(),
            "generated": {**self.program.to_json(), "model": self.plc.to_json()},
            "warnings": self.warnings,
        }


def _law_text(plc: PlcModel) -> str:
    parts = []
    for term in plc.program_law:
        p = term.parameters
        if term.effect == "offset":
            parts.append(f"{term.coefficient:+.3f} um")
        elif term.effect == "temperature":
            parts.append(f"{term.coefficient:+.4g} um/K x ({p['sensor']} - {float(p['t_ref_C']):g} degC)")
        else:
            parts.append(f"{term.coefficient:+.4g} um/m/K x position x ({p['sensor']} - {float(p['t_ref_C']):g} degC)")
    return " ".join(parts) + f" (within {plc.program_law_rms_um:.3f} um RMS of its output)"


def blocks(rows: int, folds: int) -> list[np.ndarray]:
    edges = np.linspace(0, rows, folds + 1).round().astype(int)
    return [np.arange(edges[i], edges[i + 1]) for i in range(folds)]


def _run_generated(program: GeneratedProgram, machine: Machine, recording: Recording, letter: str,
                   cycle_s: float, progress: bool | None) -> np.ndarray:
    with tempfile.TemporaryDirectory(prefix="nckemu-loop-") as directory:
        path = Path(directory) / "generated.awl"
        path.write_text(program.text, encoding="utf-8")
        return run_on_recording(path, machine, recording, letter, cycle_s, progress).sim_um


# PLC cycles per second of a run over a recording before one has been timed (bench_plc_replay.py: 86,520
# cycles in 20.2 s on the development machine); the first run's own rate replaces it.
NOMINAL_CYCLES_PER_S = 4300.0
NOMINAL_RUN_START_S = 1.5   # an emulator, awlsim and the program loaded, per run
WARMUP_S = 120.0  # as run_on_recording


def duration_text(seconds: float) -> str:
    """``45 s``, ``3.2 min``, ``1.5 h``: how long, as a person says it."""
    if seconds < 90:
        return f"{max(seconds, 1):.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def run_cycles(recording: Recording, cycle_s: float) -> int:
    """PLC cycles of one run over ``recording`` (its warm-up included), as ``RecordingDrive`` counts them."""
    first, last = float(recording.t_s[0]), float(recording.t_s[-1])
    t0 = first - math.ceil(WARMUP_S / cycle_s - 1e-9) * cycle_s
    return int(math.floor((last - t0) / cycle_s + 1e-9)) + 1


class _Phases:
    """One line per phase of the loop (``say``), with how long the rest will take: at first from the
    nominal rate, then from the runs timed so far; the generated programs' runs (the rest are all
    generated programs) from theirs once one is timed (their filters make them slower than yours:
    about 2.7x for bed_only_z.awl's on a 36 h recording at 1 s)."""

    def __init__(self, say: Callable[[str], None] | None, runs: int, cycles: int) -> None:
        self.say = say
        self.runs_left = runs
        self.cycles = cycles
        self.timed: list[float] = []            # wall seconds of each run timed so far, yours first
        self.started = time.monotonic()

    def line(self, text: str) -> None:
        if self.say is not None:
            self.say(f"nckemu loop: {text}")

    def per_run_s(self) -> float:
        """Seconds a run still to come will take: the generated programs' mean once one is timed."""
        runs = self.timed[1:] or self.timed
        return sum(runs) / len(runs) if runs else NOMINAL_RUN_START_S + self.cycles / NOMINAL_CYCLES_PER_S

    def ran(self, seconds: float) -> None:
        """One run took ``seconds``."""
        self.runs_left -= 1
        self.timed.append(seconds)

    def to_go(self) -> str:
        return duration_text(self.runs_left * self.per_run_s())


def run_loop(program: str | Path, machine: str | Path | Machine, recording: Recording, letter: str,
             cycle_s: float = 1.0, folds: int = 5, progress: bool | None = None,
             write_period_s: float = 10.0, on_phase: Callable[[str], None] | None = None) -> LoopResult:
    """``on_phase(line)`` gets one line as each phase begins and ends, with how long the rest will take
    (``nckemu loop`` prints them on stderr: seven PLC runs over a 36 h recording at 1 s take minutes)."""
    program = Path(program)
    check_program(program)
    machine = machine if isinstance(machine, Machine) else load_machine(machine)
    axis = recording_axis(machine, letter)
    letter = axis.recording
    if letter not in recording.errors_um:
        from nckemu.errors import NckConfigError

        raise NckConfigError(f"the recording has no err_{letter}_um column to judge axis {axis.name} by",
                             path=recording.source, line=1, field=f"err_{letter}_um")
    cycles = run_cycles(recording, cycle_s)
    phases = _Phases(on_phase, 2 + folds, cycles)
    hours = (float(recording.t_s[-1]) - float(recording.t_s[0])) / 3600.0
    phases.line(f"1/4 your program {program.name} over the recording: {cycles:,} PLC cycles of {cycle_s:g} s "
                f"({hours:.1f} h); {2 + folds} such runs in all (yours, the generated program, {folds} held-out "
                f"blocks): about {phases.to_go()} at {NOMINAL_CYCLES_PER_S:,.0f} cycles/s")
    started = time.monotonic()
    old = run_on_recording(program, machine, recording, letter, cycle_s, progress)
    phases.ran(time.monotonic() - started)
    phases.line(f"1/4 done in {duration_text(phases.per_run_s())} ({cycles / max(phases.per_run_s(), 1e-9):,.0f} "
                f"cycles/s); {phases.runs_left} runs to go, about {phases.to_go()}")
    with_old = with_simulation(recording, letter, old.sim_um)
    phases.line("2/4 discovering what your program leaves out")
    found_discovery = discover(with_old, axis=letter)
    found = terms_of(found_discovery.missing_physics)
    plc_sensors, spindle_input = plc_inputs(machine, recording)
    origin = f"nckemu loop on {Path(recording.source).name} (program {program.name})"
    model = plc_model(with_old, letter, found, plc_sensors, spindle_input=spindle_input)
    generated = generate_program(model.model, machine, axis, cycle_s, write_period_s, model.not_compensable, origin)
    phases.line(f"3/4 the generated program over the recording (about {duration_text(phases.per_run_s())} at "
                f"your program's pace; all the rest about {phases.to_go()})")
    started = time.monotonic()
    sim_new = _run_generated(generated, machine, recording, letter, cycle_s, progress)
    phases.ran(time.monotonic() - started)
    phases.line(f"3/4 done in {duration_text(phases.timed[-1])}; 4/4 held-out judgement: {folds} programs, each "
                f"fitted without one block of the recording and run over all of it (about {phases.to_go()})")
    heldout = np.full(len(recording.t_s), math.nan)
    error = recording.errors_um[letter]
    fold_rms = []
    for block in blocks(len(recording.t_s), folds):
        train = np.ones(len(recording.t_s), dtype=bool)
        train[block] = False
        fold_model = plc_model(with_old, letter, found, plc_sensors, train=train, spindle_input=spindle_input)
        fold_program = generate_program(fold_model.model, machine, axis, cycle_s, write_period_s,
                                        fold_model.not_compensable, origin)
        started = time.monotonic()
        sim = _run_generated(fold_program, machine, recording, letter, cycle_s, progress)
        phases.ran(time.monotonic() - started)
        done = folds - phases.runs_left
        phases.line(f"4/4 block {done} of {folds} judged" + (f", about {phases.to_go()} to go" if phases.runs_left else
                                                            f"; done in {duration_text(time.monotonic() - phases.started)}"))
        heldout[block] = sim[block]
        rows = block[np.isfinite(error[block])]
        if len(rows):
            fold_rms.append((stats.rms(error[rows] - old.sim_um[rows]), stats.rms(error[rows] - sim[rows])))
    findings = program_findings(found_discovery, _law_text(model))
    warnings = list(old.warnings) + [f"your program: {message}" for message in old.log.errors[:5]]
    if not np.any(old.sim_um):
        warnings.append(f"your program compensated nothing on axis {axis.name} (machine axis {axis.number}): check "
                        f"the unit in its address DB and MD32750")
    if generated.position_dependent:
        from .replay import position_dependent_warning

        warning = position_dependent_warning(generated.text, machine, axis)
        if warning:
            warnings.append(warning.replace("the program", "the generated program"))
    return LoopResult(axis, letter, recording, old.sim_um, sim_new, heldout, found_discovery, model, generated,
                      findings, fold_rms, warnings)


# ---------------------------------------------------------------------- the report
def _png(figure: Any) -> str:
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
    plt.close(figure)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def write_loop_report(path: str | Path, result: LoopResult, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    hours = (result.recording.t_s - result.recording.t_s[0]) / 3600.0
    error = result.recording.errors_um[result.letter]
    measured = np.isfinite(error)

    def shade(axes: Any) -> None:
        for index, window in enumerate(result.discovery.mismatch):
            axes.axvspan(window["t_start_s"] / 3600, window["t_end_s"] / 3600, color="orange", alpha=0.15,
                         label="where the program falls short" if index == 0 else None)

    figure, axes = plt.subplots(figsize=(10, 4))
    axes.plot(hours[measured], error[measured], ".", markersize=2, color="black", label="measured error")
    axes.plot(hours, result.sim_old_um, label="compensated by your program")
    axes.plot(hours, result.sim_new_um, label="compensated by the generated program")
    shade(axes)
    axes.set_xlabel("time [h]")
    axes.set_ylabel(f"axis {result.letter} [um]")
    axes.legend()
    overview = _png(figure)
    figure, axes = plt.subplots(figsize=(10, 3.5))
    axes.plot(hours[measured], (error - result.sim_old_um)[measured], label="residual, your program")
    axes.plot(hours[measured], (error - result.heldout_sim_um)[measured], label="residual, generated (held-out)")
    shade(axes)
    axes.axhline(0, color="grey", linewidth=0.5)
    axes.set_xlabel("time [h]")
    axes.set_ylabel("err - sim [um]")
    axes.legend()
    residuals = _png(figure)
    findings = findings_html(result.findings, "Your program against the recording")
    generated = "".join(f"<li>{html.escape(g['effect'])}: <code>{html.escape(_parameters_text(g['parameters']))}</code>"
                        f"{(' &mdash; ' + html.escape(g['plc'])) if g.get('plc') else ''}</li>"
                        for g in result.program.generated)
    set_aside = "".join(f"<li>{html.escape(n['effect'])}: {html.escape(n['why'])}</li>"
                        for n in result.program.not_compensable) or "<li>none</li>"
    folds = "".join(f"<tr><td>{i + 1}</td><td>{b:.3f}</td><td>{a:.3f}</td></tr>"
                    for i, (b, a) in enumerate(result.fold_rms_um))
    warnings = "".join(f"<p><b>Warning:</b> {html.escape(w)}</p>" for w in result.warnings)
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto}}td,th{{padding:4px 8px}}
table{{border-collapse:collapse}}tr{{border-bottom:1px solid #ddd}}dd{{margin-bottom:.6em}}</style></head><body>
<h1>{html.escape(title)}</h1>
<p>Axis {html.escape(result.letter)} (machine axis {result.axis.number}). Measured error RMS
{result.rms_error_um:.3f} um. Left after your program: {result.rms_before_um:.3f} um. Left after the generated
program: {result.heldout_rms_after_um:.3f} um on held-out blocks ({result.rms_after_um:.3f} um fitted on all).</p>
{warnings}
{findings}
<img alt="measured error and compensation" src="data:image/png;base64,{overview}">
<img alt="residual before and after" src="data:image/png;base64,{residuals}">
<h2>The generated program</h2><ul>{generated}</ul>
<h3>Not compensable in the PLC</h3><ul>{set_aside}</ul>
<h2>Held-out blocks</h2><p>Each block judged by a program fitted on the other blocks.</p>
<table><tr><th>block</th><th>your program [um RMS]</th><th>generated [um RMS]</th></tr>{folds}</table>
<details><summary>Generated STL</summary><pre>{html.escape(result.program.text)}</pre></details>
</body></html>"""
    write_atomically(path, lambda target: target.write_text(page, encoding="utf-8"))


def _parameters_text(parameters: dict[str, object]) -> str:
    """``sensor spindle, tau_s 2373, coeff_um_per_K 3.024``: four significant digits, as a person reads them."""
    return ", ".join(f"{key} {value:.4g}" if isinstance(value, float) else f"{key} {value}"
                     for key, value in parameters.items())
