"""Runs that follow another relation (issue 51): no run made worse in silence.

When the search has named what it can, a candidate of its last round may still act on every run, with
one sign on some and the other sign on the rest (a fixture mounted the other way round for ten days,
another cycle type). Fitted on all runs at once its coefficient is the difference of the two and helps
no one; fitted per group of runs (each run held out, its group's coefficient from the other runs of
its group), it may. The groups are the user's (``--group-by``: a part of the run names, a date or a
cycle name) or found from the residual's relation: the sign of the candidate's slope on each run,
when the runs of one sign are one stretch of dates (``consecutive``).

A split is named only when it clears what a term must (the runs' paired test, the held-out bar for its
parameters, the sizes a machine can have); one that leaves no run worse than the harm tolerance comes
first, and one that still does is named only as a term of one coefficient would be
(``Settings.run_harm_refuses`` off), its runs named with the model's. The report then names the group,
its runs, and both models' figures (one coefficient for all runs, one per group). Once a group is
named, the later terms are tried on it too (``carry_groups``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from nckemu.errors import NckConfigError
from nckemu.thermal import stats
from nckemu.thermal.recordings.recording import Recording, column_kind

from . import explain, shapes
from .admission import runs_improve
from .findings import Evidence, RegimeGroup, finding
from .library import present_key
from .records import Evaluation, Path
from .run_figures import consecutive
from .selector import Selector

MIN_GROUP_RUNS = 3
# Candidates tried fitted apart over groups already named, best in sample first (carry_groups).
CARRIED_TRIES = 8


@dataclass
class Split:
    evaluation: Evaluation
    groups: np.ndarray                  # per run: 0 the larger group, 1 the other
    cv: stats.CrossValidation
    coefficients: tuple[float, float]


def groups_by_names(names: list[str], pattern: str) -> np.ndarray | None:
    """Run groups from a part of each run's name (``pattern``: a regular expression, its first group
    if it has one): two labels only (the most common and the rest). None when all runs agree."""
    try:
        compiled = re.compile(pattern)
    except re.error as exc:
        raise NckConfigError(f"--group-by {pattern!r} is not a regular expression: {exc}", field="--group-by") from None
    labels = []
    for name in names:
        found = compiled.search(name)
        labels.append("" if found is None else (found.group(1) if compiled.groups else found.group(0)))
    values, counts = np.unique(labels, return_counts=True)
    if len(values) < 2:
        return None
    common = values[int(np.argmax(counts))]
    return np.array([0 if label == common else 1 for label in labels])


COLUMN_PREFIX = "column:"


def run_column(recording: Recording, column: str) -> np.ndarray | None:
    """A run's column by its recording name (``spindle_rpm``, ``temp_bed_C``, ``pos_X_mm``) or short name
    (a sensor, ``bed``; an axis's position, ``X``); None when the run has no such column."""
    if column in ("spindle_rpm", "spindle"):
        return recording.spindle_rpm
    kind = column_kind(column)
    if kind is not None:
        table = {"temp": recording.temperatures_C, "pos": recording.positions_mm}.get(kind[0], {})
        return table.get(column if kind[0] == "temp" else kind[1])
    return recording.temperatures_C.get(f"temp_{column}_C", recording.positions_mm.get(column))


def natural_break(values: np.ndarray) -> np.ndarray | None:
    """Two groups of runs from one value each: equal values together (a cycle code: the most common value
    against the rest); values that all differ (a mean speed) cut where the two groups are tightest (the
    cut of least within-group sum of squares, two-class natural breaks). None: fewer than
    ``MIN_GROUP_RUNS`` on a side, or one value everywhere."""
    distinct, counts = np.unique(values, return_counts=True)
    if len(distinct) < 2:
        return None
    if len(distinct) <= 3:
        common = distinct[int(np.argmax(counts))]
        groups = (values != common).astype(int)
    else:
        ordered = np.sort(values)
        costs = [float(np.var(ordered[:k]) * k + np.var(ordered[k:]) * (len(ordered) - k))
                 for k in range(MIN_GROUP_RUNS, len(ordered) - MIN_GROUP_RUNS + 1)]
        if not costs:
            return None
        cut = ordered[MIN_GROUP_RUNS + int(np.argmin(costs))]
        high = values >= cut
        groups = (high if high.sum() <= (~high).sum() else ~high).astype(int)  # the smaller group apart
    return groups if min(groups.sum(), len(groups) - groups.sum()) >= MIN_GROUP_RUNS else None


def groups_by_column(recordings: list[Recording], column: str) -> np.ndarray | None:
    """Run groups from a column of the recordings: each run's mean of it (``natural_break``)."""
    values = []
    for recording in recordings:
        found = run_column(recording, column)
        if found is None or not np.isfinite(found).any():
            raise NckConfigError(f"--group-by column:{column}: the run {recording.name or recording.source!r} has "
                                 f"no column {column!r} (a sensor, spindle_rpm or pos_<axis>_mm)",
                                 path=recording.source, field="--group-by")
        values.append(float(np.nanmean(found)))
    return natural_break(np.round(np.asarray(values), 9))


def check_group_by(recordings: list[Recording], group_by: str) -> None:
    """Refuse a grouping that cannot be read (a bad regular expression, a column some run lacks)."""
    if group_by.startswith(COLUMN_PREFIX):
        groups_by_column(recordings, group_by[len(COLUMN_PREFIX):])
    else:
        groups_by_names([recording.name or recording.source for recording in recordings], group_by)


def given_groups(selector: Selector, group_by: str) -> np.ndarray | None:
    """The user's grouping: ``column:NAME`` (a column of the recordings) or a regular expression on the
    run names."""
    runs = selector.library.problem.runs
    if group_by.startswith(COLUMN_PREFIX):
        return groups_by_column([run.readings.raw for run in runs], group_by[len(COLUMN_PREFIX):])
    return groups_by_names([run.name for run in runs], group_by)


def slopes(selector: Selector, feature: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Each run's least-squares slope of the residual on the feature (both centred per run)."""
    groups = selector.library.problem.groups
    runs = len(selector.library.problem.runs)
    moment = np.bincount(groups, weights=feature * residual, minlength=runs)
    gram = np.bincount(groups, weights=feature * feature, minlength=runs)
    return np.where(gram > 0, moment / np.maximum(gram, 1e-300), 0.0)


def by_sign(run_slopes: np.ndarray) -> np.ndarray | None:
    """Runs grouped by the sign of their slope: the larger group 0. None when a group is too small."""
    negative = run_slopes < 0
    if min(negative.sum(), (~negative).sum()) < MIN_GROUP_RUNS:
        return None
    minority = negative if negative.sum() < (~negative).sum() else ~negative
    return minority.astype(int)


def best_stretches(selector: Selector, feature: np.ndarray, residual: np.ndarray, names: list[str],
                   count: int = 3) -> list[np.ndarray]:
    """The ``count`` stretches of consecutive runs in name order (date ranges) whose own coefficient
    beside the rest's lowers the in-sample residual most, best first (each group's coefficient from
    its runs' moments of the residual on the feature, both centred per run); at least
    ``MIN_GROUP_RUNS`` runs on each side. A run at a stretch's end whose feature barely moves may tip
    the in-sample best by a hair: the next ones are offered too."""
    groups = selector.library.problem.groups
    runs = len(names)
    moment = np.bincount(groups, weights=feature * residual, minlength=runs)
    gram = np.bincount(groups, weights=feature * feature, minlength=runs)
    order = np.argsort(names, kind="stable")
    moment, gram = moment[order], gram[order]
    total_moment, total_gram = float(moment.sum()), float(gram.sum())
    found: list[tuple[float, int, int]] = []
    for start in range(runs):
        inside_moment = inside_gram = 0.0
        for stop in range(start, runs):
            inside_moment += float(moment[stop])
            inside_gram += float(gram[stop])
            size = stop - start + 1
            outside_gram = total_gram - inside_gram
            if size < MIN_GROUP_RUNS or runs - size < MIN_GROUP_RUNS or inside_gram <= 0 or outside_gram <= 0:
                continue
            explained = inside_moment ** 2 / inside_gram + (total_moment - inside_moment) ** 2 / outside_gram
            found.append((explained, start, stop))
    out = []
    for _explained, start, stop in sorted(found, reverse=True)[:count]:
        labels = np.zeros(runs, dtype=int)
        labels[order[start:stop + 1]] = 1
        out.append(labels if 2 * labels.sum() <= runs else 1 - labels)  # the smaller group apart
    return out


def grouped_columns(selector: Selector, feature: np.ndarray, groups: np.ndarray) -> np.ndarray:
    sample_groups = groups[selector.library.problem.groups]
    return np.column_stack([feature * (sample_groups == 0), feature * (sample_groups == 1)])


def path_residual(selector: Selector, path: Path) -> np.ndarray:
    """What the path's design leaves of the gauge samples, fitted in sample (all of them without a design)."""
    design = path.design
    return selector.y - design @ stats.least_squares(design, selector.y) if design.shape[1] else selector.y


def best_split(selector: Selector, path: Path, given: np.ndarray | None) -> Split | None:
    """The last round's candidate whose split over the groups lowers the in-sample residual most,
    cross-validated (each run held out, its group's coefficient from the others of its group)."""
    y, design = selector.y, path.design
    names = [run.name for run in selector.library.problem.runs]
    residual = path_residual(selector, path)
    best: tuple[float, Evaluation, np.ndarray] | None = None
    for evaluation in path.rejected:
        if evaluation.candidate.runs_with is not None:
            continue
        feature = evaluation.candidate.feature
        groups = given if given is not None else by_sign(slopes(selector, feature, residual))
        if groups is None or (given is None and not consecutive(names, groups)):
            continue
        columns = grouped_columns(selector, feature, groups)
        full = np.column_stack([design, columns])
        left = stats.rms(y - full @ stats.least_squares(full, y))
        if best is None or left < best[0]:
            best = (left, evaluation, groups)
    if best is None:
        return None
    _left, evaluation, groups = best
    split = fitted_split(selector, path, evaluation, groups)
    named = named_term_split(selector, path, groups)
    if named is not None:
        bar = shapes.parameter_bar(selector.bar, shapes.parameters_of(evaluation.candidate.term))
        if selector.heldout_gain(split.cv, named) < bar:
            return None
    return split


def fitted_split(selector: Selector, path: Path, evaluation: Evaluation, groups: np.ndarray) -> Split:
    """The candidate fitted apart over the groups beside the path's design: cross-validated (each run
    held out, its group's coefficient from the others of its group) and the two groups' coefficients."""
    y = selector.y
    full = np.column_stack([path.design, grouped_columns(selector, evaluation.candidate.feature, groups)])
    cv = selector.baseline.cross_validate(full, y, selector.baseline.folds)
    fitted = stats.least_squares(full, y)
    return Split(evaluation, groups, cv, (float(fitted[-2]), float(fitted[-1])))


def named_term_split(selector: Selector, path: Path, groups: np.ndarray) -> stats.CrossValidation | None:
    """The path with the named term whose split over the groups lowers the in-sample residual most
    fitted apart (its column replaced by one a group), cross-validated; None without named terms.

    A group whose runs a named term acts on with another size (light days on which a sensor's reading
    is mostly a coolant pump's cycling) is told by that term at another size there. A new candidate
    split over the same groups must beat it (by the bar for its parameters): else it stands in for the
    named term's other size, with a sign that says nothing about the machine."""
    y, design = selector.y, path.design
    first = design.shape[1] - len(path.added)
    best: tuple[float, np.ndarray] | None = None
    for index in range(len(path.added)):
        column = first + index
        rest = np.delete(design, column, axis=1)
        full = np.column_stack([rest, grouped_columns(selector, design[:, column], groups)])
        left = stats.rms(y - full @ stats.least_squares(full, y))
        if best is None or left < best[0]:
            best = (left, full)
    return None if best is None else selector.baseline.cross_validate(best[1], y, selector.baseline.folds)


def judged(selector: Selector, path: Path, split: Split, reversed_only: bool = True, harm_refuses: bool = True) -> bool:
    """A split clears what a term with its parameters must: the runs' paired test, the held-out bar
    for its parameters (two coefficients and the term's time constants), each group's coefficient a
    size a machine can have, and (``harm_refuses``) no run harmed; and (``reversed_only``) the two
    groups' coefficients are of opposite signs."""
    s = selector.settings
    term = split.evaluation.candidate.term
    bar = shapes.parameter_bar(selector.bar, shapes.parameters_of(term) + 1)
    gain = selector.heldout_gain(split.cv, path.base_cv)
    before = np.square(np.asarray(path.base_cv.fold_rms_um))
    after = np.square(np.asarray(split.cv.fold_rms_um))
    improves = runs_improve(before, after, s.runs_alpha, s.min_fold_share, s.runs_test_min)
    one_sign_each = split.coefficients[0] * split.coefficients[1] < 0 or not reversed_only
    can_have = not any(term.spec.cannot_have(term.parameters, coefficient, s.structure)
                       for coefficient in split.coefficients)
    return gain >= bar and improves and one_sign_each and can_have \
        and not (harm_refuses and selector.harms_runs(path.base_cv.fold_rms_um, split.cv.fold_rms_um))


def describe(names: list[str], members: list[int]) -> str:
    """A group of runs in words: a stretch of consecutive runs (in name order: dates) or a list."""
    order = sorted(range(len(names)), key=lambda i: names[i])
    positions = sorted(order.index(i) for i in members)
    if positions == list(range(positions[0], positions[-1] + 1)):
        return f"the {len(members)} consecutive runs {names[order[positions[0]]]} .. {names[order[positions[-1]]]}"
    shown = ", ".join(names[i] for i in sorted(members, key=lambda i: names[i])[:6])
    return f"{len(members)} runs ({shown}{', ...' if len(members) > 6 else ''})"


def split_runs(selector: Selector, path: Path, pattern: str | None = None) -> bool:
    """Name a group of runs that follows another relation, when one clears the guards (module doc),
    and the later terms on it (``carry_groups``); a group named in a round already (``fit_apart``):
    its later terms. True when a term was named: the path then carries its term twice, one per group."""
    if not selector.settings.run_groups or not selector.paired_runs or path.gain_mode or not path.rejected:
        return False
    given = given_groups(selector, pattern) if pattern else None
    if pattern and given is None:
        return False
    named = named_groups(selector, path)
    if named is not None:  # a group named in a round (fit_apart): its later terms
        return carry_groups(selector, path, *named)
    split = best_split(selector, path, given)
    if split is None or not judged(selector, path, split, harm_refuses=selector.settings.run_harm_refuses):
        return False
    label = explain.label_with_time_constants(split.evaluation.candidate.term)
    name_split(selector, path, split, found_words(pattern, f"the sign of {label}'s slope on each run"),
               path.rejected_t_critical)
    carry_groups(selector, path, split.groups, label)  # ... and fits the final path
    return True


def ranked_splits(selector: Selector, path: Path, groups: np.ndarray) -> list[Evaluation]:
    """The last round's candidates, each fitted apart over ``groups`` beside the path's design, by the
    in-sample residual they leave, least first."""
    y, design = selector.y, path.design
    scored = []
    for order, evaluation in enumerate(path.rejected):
        if evaluation.candidate.runs_with is not None:
            continue
        full = np.column_stack([design, grouped_columns(selector, evaluation.candidate.feature, groups)])
        scored.append((stats.rms(y - full @ stats.least_squares(full, y)), order, evaluation))
    return [evaluation for _left, _order, evaluation in sorted(scored, key=lambda item: item[:2])]


def named_groups(selector: Selector, path: Path) -> tuple[np.ndarray, str] | None:
    """The groups a term of the path was fitted apart on (the group apart 1) and that term's label;
    None when no term was."""
    names = [run.name for run in selector.library.problem.runs]
    for found, term in zip(path.discovered, path.added, strict=True):  # no gain error: split_runs's paths
        record = found.evidence
        if isinstance(record, Evidence) and record.regime is not None and record.regime.apart:
            apart = set(record.regime.runs)
            return np.array([1 if name in apart else 0 for name in names]), explain.label_with_time_constants(term)
    return None


def carry_groups(selector: Selector, path: Path, groups: np.ndarray, first_label: str) -> bool:
    """Runs that follow another relation follow it in more than one term: a fixture mounted the other
    way round turns every effect of the heat it carries (a sensor's temperature and its transient
    alike). Once a group is named, the last round's candidates are fitted apart over the same groups
    (the best ``CARRIED_TRIES`` by the in-sample residual, in turn) and the first that clears what a
    split must is named; then the rounds of one coefficient for all runs resume, as the search's do.
    Runs it still leaves worse are named with the model's, not refused, as for a term of one
    coefficient (``Settings.run_harm_refuses``). Up to ``Settings.max_effects`` columns in all; the
    terms that the later ones made redundant are then withdrawn (``Search.withdraw_redundant``).
    True when a term was named; the path's final fit is made in any case."""
    s = selector.settings
    named = False
    while path.rejected and len(path.added) + 2 <= s.max_effects:
        split = next((trial for trial in (fitted_split(selector, path, evaluation, groups)
                                          for evaluation in ranked_splits(selector, path, groups)[:CARRIED_TRIES])
                      if judged(selector, path, trial, reversed_only=False, harm_refuses=s.run_harm_refuses)), None)
        if split is None:
            break
        name_split(selector, path, split, f"the groups {first_label} was named on", path.rejected_t_critical)
        path.present.add(present_key(split.evaluation.candidate.term))
        named = True
        path.rejected = []
        while len(path.added) < s.max_effects and selector.searcher.round(path):
            pass
    if named:  # the later terms may explain what an earlier one did (a split included)
        selector.searcher.withdraw_redundant(path)
    path.final = stats.fit(path.design, selector.y)
    return named


def found_words(pattern: str | None, otherwise: str) -> str:
    if not pattern:
        return otherwise
    if pattern.startswith(COLUMN_PREFIX):
        return f"the runs' {pattern[len(COLUMN_PREFIX):]} column"
    return f"the runs' names ({pattern})"


def fit_apart(selector: Selector, path: Path, evaluation: Evaluation, t_crit: float,
              pattern: str | None = None) -> bool:
    """A candidate that passes every guard but leaves runs worse than the harm tolerance (issue 51: no
    run made worse in silence) is named only fitted apart over two groups of runs, one coefficient a
    group (each run held out, its group's coefficient from the other runs of its group). The groups are
    the user's (``pattern``) or found: the stretches of runs in name order (date ranges) whose own
    coefficient lowers the in-sample residual most (``best_stretches``), tried in turn, the smaller
    group the one apart. The split must clear the runs' paired test, the bar for its
    parameters and harm no run; the groups' coefficients may share a sign (a sensor that tells the
    structure's heat on heavy days and a coolant pump's cycling on light ones). With
    ``Settings.run_harm_refuses`` off, a split that still harms runs is named when it harms fewer than
    the one coefficient would and beats it by the bar for its extra parameter. True when named."""
    problem = selector.library.problem
    if not selector.settings.run_groups or not selector.paired_runs or path.gain_mode \
            or evaluation.candidate.runs_with is not None:
        return False
    names = [run.name for run in problem.runs]
    feature = evaluation.candidate.feature
    if pattern:
        given = given_groups(selector, pattern)
        groupings = [] if given is None else [given]
    else:
        groupings = best_stretches(selector, feature, path_residual(selector, path), names)
    tried: list[Split] = []
    for groups in groupings:
        split = fitted_split(selector, path, evaluation, groups)
        if judged(selector, path, split, reversed_only=False):
            break
        tried.append(split)
    else:
        if selector.settings.run_harm_refuses:
            return False
        # Named as a pooled term is: the runs it still leaves worse are named with the model's; the split
        # leaves fewer of them than one coefficient for all runs would, and beats it by a parameter's bar.
        pooled_harms = len(selector.harms_runs(path.base_cv.fold_rms_um, evaluation.cv.fold_rms_um))
        harming = [split for split in tried if judged(selector, path, split, reversed_only=False, harm_refuses=False)
                   and selector.heldout_gain(split.cv, evaluation.cv) >= selector.bar
                   and len(selector.harms_runs(path.base_cv.fold_rms_um, split.cv.fold_rms_um)) < pooled_harms]
        if not harming:
            return False
        split = min(harming, key=lambda candidate: float(np.median(candidate.cv.fold_rms_um)))
    label = explain.label_with_time_constants(evaluation.candidate.term)
    name_split(selector, path, split, found_words(pattern, f"the stretch of dates on which {label} acts otherwise"), t_crit,
               because=f"one coefficient for all runs leaves runs worse than before by more than "
                       f"{selector.settings.run_harm_share:.0%} and {selector.settings.run_harm_floor_um:g} um")
    path.present.add(present_key(evaluation.candidate.term))
    return True


def name_split(selector: Selector, path: Path, split: Split, found_by: str, t_crit: float,
               because: str = "") -> None:
    """The split's term named once a group, with the group, its runs and both models' figures."""
    names = [run.name for run in selector.library.problem.runs]
    evaluation = split.evaluation
    term = evaluation.candidate.term
    members = [list(np.flatnonzero(split.groups == g)) for g in (0, 1)]
    before, pooled, after = (np.asarray(cv.fold_rms_um) for cv in (path.base_cv, evaluation.cv, split.cv))
    label = explain.label_with_time_constants(term)
    records = []
    for group, runs in enumerate(members):
        coefficient = split.coefficients[group]
        records.append(RegimeGroup(
            describe(names, runs), [names[i] for i in runs], round(coefficient, 6),
            round(float(np.median(before[runs])), 4), round(float(np.median(pooled[runs])), 4),
            round(float(np.median(after[runs])), 4), round(float(np.max(after[runs])), 4), group == 1))
    other = records[1]
    why = (f"{other.runs_words} follow another relation: {label} {split.coefficients[1]:+.3g} um/K there against "
           f"{split.coefficients[0]:+.3g} um/K in the other {len(members[0])} runs (grouped by {found_by}); "
           f"fitted apart (each run held out, its group's coefficient from the other runs of its group)"
           + (f"; {because}" if because else ""))
    design = np.column_stack([path.design, grouped_columns(selector, evaluation.candidate.feature, split.groups)])
    noise_columns = grouped_columns(selector, evaluation.candidate.noise, split.groups)
    gain = selector.heldout_gain(split.cv, path.base_cv)
    for group, record in enumerate(records):
        named = term.with_coefficient(split.coefficients[group])
        evidence = Evidence(
            heldout_rms_before_um=round(path.base_cv.rms_um, 4), heldout_rms_after_um=round(split.cv.rms_um, 4),
            heldout_rms_without_sensor_noise_um=round(split.cv.rms_um, 4), t_value_ar1_corrected=None,
            t_critical=round(t_crit, 3) if math.isfinite(t_crit) else 0.0,
            folds_improved=f"{int(np.sum(after < before))}/{len(before)}", window=None,
            equivalent=[], why=why, preferred=(f"{label} per group of runs: the median over runs of held-out RMS "
                                               f"{float(np.median(before)):.3f} -> {float(np.median(after)):.3f} um "
                                               f"({gain:.1%}; one coefficient for all runs "
                                               f"{float(np.median(pooled)):.3f} um)"))
        evidence.regime = record
        path.discovered.append(finding(named.effect, named.parameters, evidence))
        path.added.append(named)
    path.design = design
    path.noise = np.column_stack([path.noise, noise_columns])
    path.base_cv = split.cv


__all__ = ["Split", "fit_apart", "groups_by_column", "groups_by_names", "natural_break", "split_runs"]
