"""What a discovery against a program's ``sim_`` column says, in the compensation engineer's words:
what the program compensated, the residual, where it falls short, what physics it leaves out."""

from __future__ import annotations

from typing import Any

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.model.families import family
from nckemu.thermal.model.terms import Term

from . import explain
from .discover import Discovery
from .findings import RegimeGroup


def _parameters(parameters: dict[str, Any]) -> str:
    return ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in parameters.items())


def program_findings(discovery: Discovery, law: str | None = None) -> list[tuple[str, str]]:
    """Four (heading, sentence) pairs for a discovery whose baseline is the program's compensation."""
    series = discovery.series
    measured, compensated = series["measured_um"], series["baseline_um"]
    error_rms = stats.rms(measured)
    residual_rms = stats.rms(measured - compensated)
    share = 100.0 * (1.0 - residual_rms / error_rms) if error_rms > 0 else 0.0
    what = (f"The program's compensation (sim_{discovery.axis}_um) ran from {float(np.min(compensated)):.2f} to "
            f"{float(np.max(compensated)):.2f} um over the {discovery.samples} measured samples; it takes the "
            f"recorded error's RMS from {error_rms:.3f} um to {residual_rms:.3f} um ({share:.0f} % removed).")
    if discovery.baseline_constant_um is not None:
        what += (f" Its output is one constant ({discovery.baseline_constant_um:g} um): it compensates nothing, "
                 f"so the candidates were tried against it plus an offset, as against a constant baseline.")
    if law:
        what += f" Read back from its output, its law is {law}."
    refit = ("with an offset fitted" if discovery.baseline_constant_um is not None
             else "with the best single factor on the program's output")
    residual = (f"Left after compensation (err - sim): RMS {discovery.baseline_rms_um:.3f} um; {refit} "
                f"{discovery.recalibrated_rms_um:.3f} um; with the missing physics "
                f"added, held-out {discovery.heldout_rms_after_um:.3f} um.")
    if discovery.mismatch:
        short = "It falls short " + "; ".join(
            f"from {w['t_start_s'] / 3600:.2f} h to {w['t_end_s'] / 3600:.2f} h ({w['why']})" for w in discovery.mismatch)
        short += "."
    else:
        short = "The residual has no structured window: it does not fall short anywhere the data can show."
    if discovery.missing_physics:
        physics = "It leaves out: " + "; ".join(
            f"{m.effect} ({family(m.effect).description}: {_parameters(m.parameters)})"
            for m in discovery.missing_physics) + "."
    elif discovery.residual_is_structure:
        physics = ("No candidate of the vocabulary passed the guards, but what it leaves is structure, not noise "
                   f"({structure_words(discovery)}): it leaves out physics this search does not name.")
    else:
        physics = "It leaves out no physics the recording can show."
    return [("What the program compensated", what), ("The residual", residual),
            ("Where it falls short", short), ("What physics it leaves out", physics)]




def structure_words(discovery: Discovery) -> str:
    """r(1) and the Ljung-Box Q of the final residual, in a few words."""
    s = discovery.residual_structure
    q = s.get("ljung_box_q")
    return f"r(1) = {s.get('r1', float('nan')):.2f}, Ljung-Box Q = {q:.0f}" if q is not None else \
        f"r(1) = {s.get('r1', float('nan')):.2f}"


def time_constant_lines(discovery: Discovery) -> list[str]:
    """One line per sensor named at two time constants (a fast skin and a slow core): each time
    constant with its um/K and its share of what the two improve together."""
    lines = []
    seen: set[tuple[str, str]] = set()
    for m in discovery.missing_physics:
        key = (m.effect, str(m.parameters.get("sensor")))
        twins = [t for t in discovery.missing_physics
                 if (t.effect, str(t.parameters.get("sensor"))) == key and "tau_s" in t.parameters]
        if len(twins) < 2 or key in seen:
            continue
        seen.add(key)
        parts = []
        for t in sorted(twins, key=lambda t: t.parameters["tau_s"]):
            move = getattr(t.evidence, "move", None)
            twin = getattr(t.evidence, "twin_share", None)
            share = f", {move.share:.0%} of the two" if move is not None else \
                f", {twin:.0%} of the two" if twin is not None else ""
            parts.append(f"tau {t.parameters['tau_s'] / 3600:.2f} h {t.parameters.get('coeff_um_per_K', 0.0):.3g} "
                         f"um/K{share}")
        lines.append(f"two time constants of {key[1]} ({key[0]}): " + "; ".join(parts))
    return lines


def attribution_lines(discovery: Discovery) -> list[str]:
    """One line per move of two effects that was weighed against other explanations: why these two,
    and the explanations set aside with their held-out figures."""
    lines = []
    seen: set[str] = set()
    for m in discovery.missing_physics:
        move = getattr(m.evidence, "move", None)
        if move is None or not move.equivalent or " + ".join(move.terms) in seen:
            continue
        seen.add(" + ".join(move.terms))
        weighed = ", ".join(f"{alt.effects} {alt.heldout_rms_um:.3f} um" for alt in move.equivalent)
        lines.append(f"why {' + '.join(move.terms)} (held-out {move.heldout_rms_after_um:.3f} um): {move.why}; "
                     f"weighed: {weighed}")
    return lines


def _size(parameters: dict[str, Any]) -> str:
    value = next((v for k, v in parameters.items() if k.startswith(("coeff", "slope", "um_per", "value", "gain"))), None)
    unit = next((k.split("_", 1)[1] for k in parameters if k.startswith(("coeff", "slope"))), "")
    return f" {value:+.3g} {unit.replace('_per_', '/').replace('um/K2', 'um/K^2')}" if isinstance(value, float) else ""


def worse_line(discovery: Discovery, shown: int = 4) -> str:
    """The runs the model leaves worse than before discovery beyond the harm tolerance, each with its
    figures (the first ``shown``), and what they share, or that no shared trait was found; empty
    when no run is made worse (issue 51: no run made worse in silence)."""
    worse = discovery.run_figures.get("made_worse", []) if discovery.run_figures else []
    if not worse:
        return ""
    runs = ", ".join(f"{w['run']} {w['before_um']:.3f} -> {w['after_um']:.3f} um" for w in worse[:shown])
    if len(worse) > shown:
        runs += f" and {len(worse) - shown} more (runs table)"
    shared = discovery.run_figures.get("made_worse_share") or \
        ["no trait found that explains it" if len(worse) == 1 else "no shared trait found"]
    return f"made worse: {runs}: {'; '.join(shared)}"


def group_figures(discovery: Discovery, regime: RegimeGroup) -> tuple[float, float, float]:
    """A group of runs' figures under the final model, from the runs' rows: the median over its runs of
    held-out RMS before and after, and its worst run after (the group's record holds them as they
    were when its term was named, before any later term)."""
    members = set(regime.runs)
    rows = [row for row in discovery.runs if row["name"] in members]
    if not rows:
        return regime.median_before_um, regime.median_after_um, regime.worst_after_um
    after = [row["heldout_rms_after_um"] for row in rows]
    return float(np.median([row["heldout_rms_before_um"] for row in rows])), float(np.median(after)), max(after)


def headline_lines(discovery: Discovery) -> list[str]:
    """At most four lines an engineer can act on (issue 51): each term named, its size and what it
    means physically (a group of runs fitted apart on one line with its own size), the runs made
    worse than before with what they share when there are any, then the figure per run group. The
    evidence follows them."""
    terms: list[str] = []
    done: set[int] = set()
    physics = discovery.missing_physics
    for index, m in enumerate(physics):
        if index in done:
            continue
        regime = getattr(m.evidence, "regime", None)
        label = explain.label_with_time_constants(Term(m.effect, m.parameters))
        line = f"{label}{_size(m.parameters)}"
        if regime is not None:
            others = [j for j, o in enumerate(physics) if j != index and getattr(o.evidence, "regime", None) is not None
                      and o.effect == m.effect and o.parameters.get("sensor") == m.parameters.get("sensor")
                      and o.parameters.get("sensors") == m.parameters.get("sensors")]
            done.update(others)
            for j in others:
                line += f", but{_size(physics[j].parameters)} on {physics[j].evidence.regime.runs_words}"
        line += f": {family(m.effect).description}"
        note = getattr(m.evidence, "note", None)
        if note and "one shape" in note:
            line += " (named as one shape with the sensor's temperature)"
        terms.append(line)
    if not terms:
        terms = ["nothing to add: " + ("what is left is structure no term of the vocabulary explains"
                                       if discovery.residual_is_structure else "the model explains what the data show")]
    worse = worse_line(discovery)
    room = 2 if worse else 3  # four lines in all: the terms shrink to make room for the runs made worse
    if len(terms) > room:
        terms = terms[:room - 1] + [f"and {len(terms) - room + 1} more terms (below)"]
    if worse:
        terms.append(worse)
    figures = discovery.run_figures
    if figures:
        line = (f"held-out, each run left out: median {figures['median_before_um']:.3f} -> "
                f"{figures['median_after_um']:.3f} um, worst run {figures['worst_after_um']:.3f} um")
        shown: set[str] = set()
        for m in physics:
            regime = getattr(m.evidence, "regime", None)
            if regime is None or not regime.apart or regime.runs_words in shown:
                continue  # several terms fitted apart on one group: the group once, with the final model's figures
            shown.add(regime.runs_words)
            before, after, worst = group_figures(discovery, regime)
            line += (f"; on {regime.runs_words}: median {before:.3f} -> {after:.3f} "
                     f"um (one coefficient for all runs: {regime.median_one_coefficient_um:.3f} um), worst "
                     f"{worst:.3f} um")
    else:
        line = f"held-out RMS {discovery.heldout_rms_before_um:.3f} -> {discovery.heldout_rms_after_um:.3f} um"
    return [*terms, line]


def finding_lines(discovery: Discovery) -> list[str]:
    """The text output's lines after the headline: found, likely, why nothing, coverage, data quality."""
    import json

    lines = [f"cannot use: {line}" for line in discovery.cannot_use]
    if discovery.cannot_use and discovery.why_nothing == discovery.cannot_use[0]:
        return lines  # a still error column: nothing was searched, nothing more to say
    lines += [f"missing: {m.effect} {json.dumps(m.parameters)}" for m in discovery.missing_physics]
    lines += time_constant_lines(discovery)
    lines += attribution_lines(discovery)
    for item in discovery.likely:
        e = item.evidence
        lines.append(f"likely, not proven: {item.label} {json.dumps(item.parameters)}: held-out "
                     f"{e.heldout_rms_before_um:.3f} -> {e.heldout_rms_after_um:.3f} um "
                     f"({e.heldout_improvement:.1%}, the bar is {e.heldout_bar:.0%}); {e.why}")
    for item in discovery.cannot_have:
        physical = next(g for g in item.guards if g.guard == "physical")
        held_out = item.guards[-1]
        coefficient = next((v for k, v in item.parameters.items() if k.startswith(("coeff", "slope"))), None)
        size = f" {coefficient:+.3g}" if isinstance(coefficient, float) else ""
        lines.append(f"{physical.figure.split(':')[0]}: {item.label}{size} ({physical.figure.split(': ', 1)[1]}); "
                     f"{held_out.figure}")
    if discovery.stopped:
        lines.append(f"stopped: {discovery.stopped}")
    for withdrawn in discovery.withdrawn:
        lines.append(f"withdrawn: {withdrawn.label}: {withdrawn.why}")
    for item in discovery.closest:
        held = ", ".join(item.held_back_by) or "nothing (another candidate was named)"
        figures = "; ".join(f"{g.figure} ({'passes' if g.passes else 'fails'})" for g in item.guards)
        lines.append(f"closest: {item.label}, held back by {held}: {figures}")
    if discovery.missing_physics and discovery.residual_is_structure:
        sizes = ", ".join(f"{family} {size:.2g}" for family, size in discovery.smallest_detectable_um.items())
        where = ""
        for item in discovery.left[:1]:
            hours = (f"{item['from_h']:.2f} h to {item['to_h']:.2f} h after its start" if "run" in item else
                     f"{item['t_start_s'] / 3600:.2f} h to {item['t_end_s'] / 3600:.2f} h")
            where = f"; largest {'in ' + item['run'] + ' ' if 'run' in item else ''}from {hours} ({item['why']})"
        lines.append(f"left: the residual is still structure ({structure_words(discovery)}){where}"
                     + (f"; the smallest effect each family could have shown next (RMS, um): {sizes}" if sizes else ""))
    if not discovery.missing_physics:
        # A residual that is structure (r(1) near 1, a huge Ljung-Box Q) is never "nothing missing".
        head = (f"nothing named, but the residual is structure ({structure_words(discovery)})"
                if discovery.residual_is_structure else "nothing missing")
        lines.append(f"{head}: {discovery.why_nothing}" if discovery.why_nothing else head)
    for item in discovery.coverage:
        lines.append(f"{item['column']} missing in {', '.join(item['missing_in'])}: {item['handled']}")
    return lines


def runs_table(discovery: Discovery) -> list[str]:
    """Per run: rows, hours, held-out before and after (each run left out), and where it still fails;
    a run the model leaves worse than before beyond the harm tolerance is flagged so."""
    if not discovery.runs:
        return []
    width = max(len(r["name"]) for r in discovery.runs)
    lines = [f"{'run':<{width}}  {'rows':>6}  {'hours':>6}  {'before_um':>9}  {'after_um':>8}"]
    for r in discovery.runs:
        flag = ("  worse than before" if r.get("made_worse") else
                f"  worse than before, in {r['worse_in_group']} (fitted apart)" if r.get("worse_in_group") else
                "  still fails" if r.get("fails") else "")
        lines.append(f"{r['name']:<{width}}  {r['rows']:>6}  {r['duration_h']:>6.1f}  "
                     f"{r['heldout_rms_before_um']:>9.3f}  {r['heldout_rms_after_um']:>8.3f}{flag}")
    if discovery.run_figures:
        lines.append(explain.runs_words(discovery.run_figures))
    for w in discovery.mismatch:
        if "run" in w:
            run = next(r for r in discovery.runs if r["name"] == w["run"])
            lines.append(f"{w['run']} still fails from {run['fails_from_h']:.2f} h to {run['fails_to_h']:.2f} h "
                         f"after its start ({w['why']})")
    return lines
