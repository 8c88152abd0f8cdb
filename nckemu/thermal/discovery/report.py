"""A self-contained HTML report: the recording, baseline and improved model over time, the residual
before and after, and the located windows, as matplotlib figures embedded as PNG."""

from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from nckemu.cliutil import write_atomically

from .discover import Discovery  # noqa: E402
from .findings import Evidence, Finding  # noqa: E402


def _png(figure: plt.Figure) -> str:
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    plt.close(figure)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _shade(axes: plt.Axes, discovery: Discovery) -> None:
    if discovery.runs:  # the runs are laid end to end: each run's windows are in the per-run table
        return
    for index, window in enumerate(discovery.mismatch):
        axes.axvspan(window["t_start_s"] / 3600, window["t_end_s"] / 3600, color="orange", alpha=0.15,
                     label="located mismatch" if index == 0 else None)


def findings_html(findings: list[tuple[str, str]], heading: str = "The program against the recording") -> str:
    """The program's findings (``wording.program_findings``) as a definition list under ``heading``."""
    items = "".join(f"<dt><b>{html.escape(h)}</b></dt><dd>{html.escape(s)}</dd>" for h, s in findings)
    return f"<h2>{html.escape(heading)}</h2><dl>{items}</dl>"


def _um(value: object) -> str:
    return f"{value:.3f} um" if isinstance(value, int | float) else "n/a"


def _row(finding: Finding) -> str:
    """One discovered effect: why, held-out RMS before and after, the equivalent explanations and
    which one was preferred."""
    evidence = finding.evidence
    parts = [html.escape(evidence.why),
             f"held-out {_um(evidence.heldout_rms_before_um)} &rarr; {_um(evidence.heldout_rms_after_um)}"]
    if isinstance(evidence, Evidence):
        parts.append(f"t = {evidence.t_value_ar1_corrected} (critical {evidence.t_critical}), "
                     f"folds improved {evidence.folds_improved}")
    else:
        parts.append(f"gain standard error {evidence.gain_se}")
    if evidence.equivalent:
        listed = ", ".join(html.escape(f"{e.effect} ({_um(e.heldout_rms_um)})") for e in evidence.equivalent)
        parts.append(f"equivalent explanations considered: {listed}")
    for text in (evidence.preferred, evidence.note if isinstance(evidence, Evidence) else None):
        if text:
            parts.append(html.escape(text))
    move = evidence.move if isinstance(evidence, Evidence) else None
    if move is not None:  # a move of two: why these two, and what was weighed against them
        parts.append(html.escape(move.why))
        if move.equivalent:
            weighed = ", ".join(f"{m.effects} ({_um(m.heldout_rms_um)})" for m in move.equivalent)
            parts.append(f"weighed: {html.escape(weighed)}")
    return (f"<tr><td>{html.escape(finding.effect)}</td>"
            f"<td><code>{html.escape(json.dumps(finding.parameters))}</code></td>"
            f"<td>{'<br>'.join(parts)}</td></tr>")


def _runs_section(discovery: Discovery) -> str:
    """Several runs: each run's held-out RMS before and after (a table and a bar plot), and where
    the model still fails."""
    if not discovery.runs:
        return ""
    import numpy as np

    names = [r["name"] for r in discovery.runs]
    before = [r["heldout_rms_before_um"] for r in discovery.runs]
    after = [r["heldout_rms_after_um"] for r in discovery.runs]
    figure, axes = plt.subplots(figsize=(10, 3.5))
    x = np.arange(len(names))
    axes.bar(x - 0.2, before, 0.4, label="before (baseline)")
    axes.bar(x + 0.2, after, 0.4, label="after (improved model)")
    crowded = len(names) > 8 or max(len(n) for n in names) * len(names) > 90
    axes.set_xticks(x, names, rotation=60 if crowded else 0, ha="right" if crowded else "center", fontsize=8)
    axes.set_ylabel("held-out RMS [um]")
    axes.set_title("each run held out: fitted on the other runs, its own offset on itself")
    axes.legend()
    plot = _png(figure)
    red = ' style="background:#fee"'
    rows = "".join(
        f"<tr{red if r.get('fails') else ''}><td>{html.escape(r['name'])}</td>"
        f"<td>{r['rows']}</td><td>{r['duration_h']:.1f}</td><td>{r['heldout_rms_before_um']:.3f}</td>"
        f"<td>{r['heldout_rms_after_um']:.3f}</td><td>"
        + (html.escape(f"{'worse than before, ' if r.get('made_worse') else ''}still fails, {r['fails_from_h']:.2f} h to {r['fails_to_h']:.2f} h after its start"
                       + (f"; {r['follows']}" if r.get("follows") else "")) if r.get("fails") else "")
        + "</td></tr>" for r in discovery.runs)
    coverage = "".join(f"<li>{html.escape(c['column'])} missing in {html.escape(', '.join(c['missing_in']))}: "
                       f"{html.escape(c['handled'])}</li>" for c in discovery.coverage)
    return (f"<h2>Runs</h2><table><tr><th>run</th><th>rows</th><th>hours</th><th>held-out before [um]</th>"
            f"<th>held-out after [um]</th><th></th></tr>{rows}</table>"
            + (f"<p>Columns some runs lack:</p><ul>{coverage}</ul>" if coverage else "")
            + f'<img alt="held-out RMS per run, before and after" src="data:image/png;base64,{plot}">'
            + _figures_line(discovery) + _per_run_plots(discovery))


def _figures_line(discovery: Discovery) -> str:
    if not discovery.run_figures:
        return ""
    from .explain import runs_words

    return f"<p><b>Per run.</b> {html.escape(runs_words(discovery.run_figures))}.</p>"


def _per_run_plots(discovery: Discovery) -> str:
    """One small plot per run: recorded, baseline and improved model, each as predicted with the run
    held out (fitted on the other runs, the run's own offset on itself). Runs the model still fails
    have a red frame and title, and their window shaded."""
    series = discovery.series
    if not discovery.runs or "heldout_improved_um" not in series:
        return ""
    import math

    count = len(discovery.runs)
    columns = min(4, count)
    rows = math.ceil(count / columns)
    figure, grid = plt.subplots(rows, columns, figsize=(10.5, 2.3 * rows + 0.4), squeeze=False)
    for index, run in enumerate(discovery.runs):
        axes = grid[index // columns][index % columns]
        mine = series["run_index"] == index
        hours = series["run_hours"][mine]
        axes.plot(hours, series["measured_um"][mine], ".", markersize=2, color="black", label="recorded")
        axes.plot(hours, series["heldout_baseline_um"][mine], color="tab:blue", linewidth=1, label="baseline")
        axes.plot(hours, series["heldout_improved_um"][mine], color="tab:orange", linewidth=1.2,
                  label="improved model")
        fails = bool(run.get("fails"))
        title = (f"{run['name']}\n{run['heldout_rms_before_um']:.2f} -> {run['heldout_rms_after_um']:.2f} um"
                 + (" STILL FAILS" if fails else ""))
        axes.set_title(title, fontsize=7.5, color="red" if fails else "black")
        if fails:
            axes.axvspan(run["fails_from_h"], run["fails_to_h"], color="red", alpha=0.12)
            for spine in axes.spines.values():
                spine.set_color("red")
                spine.set_linewidth(2)
        axes.tick_params(labelsize=7)
        if index % columns == 0:
            axes.set_ylabel("um", fontsize=7)
    for index in range(count, rows * columns):
        grid[index // columns][index % columns].axis("off")
    handles, labels = grid[0][0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="upper center", ncol=3, fontsize=8, frameon=False)
    figure.supxlabel("hours after the run's start", fontsize=8)
    figure.tight_layout(rect=(0, 0, 1, 1 - 0.35 / (2.3 * rows + 0.4)))
    return ('<h3>Each run held out</h3><p>Recorded error, the baseline and the improved model, each fitted on '
            'the other runs (the run\'s own offset on itself); red: a run the model still fails, its window '
            'shaded.</p>'
            f'<img alt="each run: recorded, baseline, improved model" src="data:image/png;base64,{_png(figure)}">')


def _honest_section(discovery: Discovery) -> str:
    parts = []
    if discovery.why_nothing:
        heading = "Why nothing is named" if discovery.residual_is_structure else "Why nothing is missing"
        parts.append(f"<p><b>{heading}.</b> {html.escape(discovery.why_nothing)}</p>")
    for item in discovery.likely:
        e = item.evidence
        parts.append(f"<p><b>Likely, not proven:</b> {html.escape(item.label)} "
                     f"<code>{html.escape(json.dumps(item.parameters))}</code>: held-out "
                     f"{_um(e.heldout_rms_before_um)} &rarr; {_um(e.heldout_rms_after_um)}; "
                     f"{html.escape(e.why)}.</p>")
    for withdrawn in discovery.withdrawn:
        parts.append(f"<p><b>Withdrawn:</b> {html.escape(withdrawn.label)}: {html.escape(withdrawn.why)}.</p>")
    for item in discovery.left[:1]:
        where = f"in {item['run']} from {item['from_h']:.2f} h to {item['to_h']:.2f} h after its start" \
            if "run" in item else f"from {item['t_start_s'] / 3600:.2f} h to {item['t_end_s'] / 3600:.2f} h"
        parts.append(f"<p><b>What is left</b> is largest {html.escape(where)}: {html.escape(item['why'])}.</p>")
    if discovery.closest:
        rows = "".join(
            f"<tr><td>{html.escape(item.label)}</td><td>{html.escape(', '.join(item.held_back_by))}</td><td>"
            + "<br>".join(f"{'&#10003;' if g.passes else '&#10007;'} {html.escape(g.guard)}: {html.escape(g.figure)}"
                          for g in item.guards) + "</td></tr>"
            for item in discovery.closest)
        parts.append("<p><b>The candidates that came closest</b> in the last round, with every guard's figure:</p>"
                     f"<table><tr><th>candidate</th><th>held back by</th><th>guards</th></tr>{rows}</table>")
    return "".join(parts)


def _headline(discovery: Discovery) -> str:
    """Several runs: the at most four lines an engineer can act on, before the evidence (issue 51)."""
    if not discovery.runs:
        return ""
    from .wording import headline_lines

    return "<ul>" + "".join(f"<li><b>{html.escape(line)}</b></li>" for line in headline_lines(discovery)) + "</ul>\n"


def write_report(path: str | Path, discovery: Discovery, title: str,
                 findings: list[tuple[str, str]] | None = None) -> None:
    series = discovery.series
    hours = series["t_s"] / 3600
    figure, axes = plt.subplots(figsize=(10, 4))
    axes.plot(hours, series["measured_um"], ".", markersize=3, label="recorded", color="black")
    axes.plot(hours, series["baseline_um"], label="baseline (as given)")
    axes.plot(hours, series["improved_um"], label="improved model")
    _shade(axes, discovery)
    axes.set_xlabel("time [h]" + (" (runs end to end, each about its own offset)" if discovery.runs else ""))
    axes.set_ylabel(f"error of axis {discovery.axis} [um]")
    axes.legend()
    overview = _png(figure)
    figure, axes = plt.subplots(figsize=(10, 3.5))
    axes.plot(hours, series["residual_before_um"], label="residual before (baseline as given)")
    axes.plot(hours, series["residual_after_um"], label="residual after (improved model)")
    _shade(axes, discovery)
    axes.axhline(0, color="grey", linewidth=0.5)
    axes.set_xlabel("time [h]")
    axes.set_ylabel("residual [um]")
    axes.legend()
    residuals = _png(figure)
    nothing = ("nothing named, but the residual is structure, not noise: physics this search does not name is left"
               if discovery.residual_is_structure else "nothing missing")
    rows = "".join(_row(m) for m in discovery.missing_physics) or f"<tr><td colspan=3>{nothing}</td></tr>"
    windows = "".join(f"<li>{html.escape(w['run']) + ': ' if 'run' in w else ''}{w['t_start_s'] / 3600:.2f} h to {w['t_end_s'] / 3600:.2f} h: {html.escape(w['why'])}</li>"
                      for w in discovery.mismatch) or ("<li>no run the model still fails</li>" if discovery.runs
                                         else "<li>no structured residual</li>")
    quality = ("<h2>Data quality</h2><ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in discovery.data_quality)
               + "</ul>") if discovery.data_quality else ""
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto}}td{{padding:4px 8px;vertical-align:top}}
table{{border-collapse:collapse}}tr{{border-bottom:1px solid #ddd}}</style></head><body>
<h1>{html.escape(title)}</h1>
{_headline(discovery)}<p>Axis {html.escape(discovery.axis)}, {discovery.samples} measured samples. RMS as given
{discovery.baseline_rms_um:.3f} um; recalibrated {discovery.recalibrated_rms_um:.3f} um; held-out
{discovery.heldout_rms_before_um:.3f} &rarr; {discovery.heldout_rms_after_um:.3f} um
(before: {html.escape(discovery.before_is or "the baseline")}).</p>
{findings_html(findings) if findings else ""}
{_runs_section(discovery)}
<h2>Missing physics</h2><table><tr><th>effect</th><th>parameters</th><th>evidence</th></tr>{rows}</table>
<p><b>Preferred explanation.</b> {html.escape(discovery.preferred or "-")}</p>
{_honest_section(discovery)}
{quality}
<h2>Where the model disagrees</h2><ul>{windows}</ul>
<img alt="recording, baseline and improved model" src="data:image/png;base64,{overview}">
<img alt="residual before and after" src="data:image/png;base64,{residuals}">
</body></html>"""
    write_atomically(path, lambda target: target.write_text(page, encoding="utf-8"))
