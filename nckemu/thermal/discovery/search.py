"""The search: one path of explanation grown a round at a time (the recalibrated model, or gain x the
model as given, plus effects), each round's candidates judged by the admission tests, and at the end
the shapes named, the terms the later ones made redundant withdrawn, and twins' shares given."""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable

import numpy as np

from nckemu.thermal import stats

from . import explain, shapes
from . import selection_words as words
from .admission import Admission, t_critical
from .findings import Evidence, Finding, GainEvidence, Withdrawn, finding
from .fits import Fits
from .library import Library, present_key, time_constants
from .moves import Moves
from .records import Baseline, Evaluation, Path
from .settings import Settings


class Search:
    def __init__(self, y: np.ndarray, t_s: np.ndarray, library: Library, settings: Settings,
                 baseline: Baseline, admission: Admission) -> None:
        self.y = y
        self.t_s = t_s
        self.library = library
        self.settings = settings
        self.baseline = baseline
        self.admission = admission
        self.fits = Fits(y, baseline, admission)
        self.moves = Moves(y, library, settings, baseline, admission, self.fits)
        # A candidate that harms runs, tried fitted apart over two groups of runs (discovery/regimes.py,
        # wired by discover.py): True when it was named so.
        self.fit_apart: Callable[[Path, Evaluation, float], bool] | None = None

    def search(self, gain_mode: bool) -> Path:
        """Add effects one round at a time to the recalibrated model (or to gain x the model as given)."""
        setup = self.baseline
        if gain_mode:
            gain, gain_se, gain_cv = setup.gain
            path = Path(True, setup.given[:, None], gain_cv, setup.given_noise[:, None])
            path.present.add("gain_error")
            path.discovered.append(Finding("gain_error", {"gain": round(gain, 5)}, GainEvidence(
                round(setup.baseline_rms, 4), round(gain_cv.rms_um, 4), round(setup.baseline_rms, 4),
                round(gain_se, 5), [], words.GAIN_WHY)))
        else:
            path = Path(False, setup.base_design, setup.recal_cv, setup.base_noise)
        if self.library.problem.per_run_offset:
            path.present.add("offset")  # each run's own offset is in the baseline
        for _round in range(self.settings.max_effects):
            if len(path.added) >= self.settings.max_effects or not self.round(path):
                break
        if self.limit_may_have_stopped(path):
            self.judge_next_round(path)
        self.name_shapes(path)
        if self.admission.paired_runs:
            self.withdraw_redundant(path)
        # A term withdrawn for its final size changes the others' worth: judged again until it holds.
        while self.withdraw_beyond_structure(path) and self.admission.paired_runs:
            self.withdraw_redundant(path)
        if path.at_limit:
            self.survey(path)
        path.final = stats.fit(path.design, self.y) if path.design.shape[1] else None
        self.twin_shares(path)
        return path

    def evaluate_round(self, path: Path) -> tuple[list[Evaluation], float, int] | None:
        """The round's candidates evaluated beside the path's design: (evaluations, critical t, the
        hypotheses it is corrected over); the runs' paired test counted over them. None: no candidate."""
        s, setup = self.settings, self.baseline
        design = path.design
        candidates = self.library.candidates(design if design.shape[1] else setup.given[:, None], path.present,
                                             tuple(path.added))
        if not candidates:
            return None
        # Bonferroni over every hypothesis of the round, each time constant tried included.
        tests = sum(c.grid_points for c in candidates)
        t_crit = t_critical(s.alpha, tests, len(self.y) - design.shape[1] - 1 - setup.extra_parameters)
        evaluations = [e for e in (self.fits.evaluate(design, path.noise, c, path.base_cv, tuple(path.added))
                                   for c in candidates)
                       if self.twin_of_one_sign(path, e)]
        self.admission.count_paired_tests(evaluations, path.base_cv, t_crit)
        return evaluations, t_crit, tests

    def round(self, path: Path) -> bool:
        s, setup = self.settings, self.baseline
        folds = setup.folds
        design = path.design
        evaluated = self.evaluate_round(path)
        if evaluated is None:
            return False
        evaluations, t_crit, tests = evaluated
        single_paired_tests = self.admission.paired_tests  # pair_round counts its moves' own
        passing = [e for e in evaluations if self.admission.passes(e, path.base_cv, t_crit)]
        fitting = self.note_cannot_have(path, [e for e in evaluations if e not in passing], t_crit)
        passing = [e for e in passing if self.admission.earned(e, evaluations, passing)]
        if self.fit_apart is not None and self.fitted_apart(path, evaluations, passing, t_crit):
            return True
        if not passing and s.pair_moves and len(path.added) + 2 <= s.max_effects \
                and self.moves.pair_round(path, evaluations, tests):
            return True
        if not passing:
            path.rejected, path.rejected_t_critical = evaluations, t_crit
            path.rejected_paired_tests = single_paired_tests
            return False
        best, margin, equivalent = self.admission.equivalent(passing, fitting)
        chosen = min(equivalent, key=lambda e: (e.candidate.term.spec.complexity, e.ranked_rms_um))
        chosen = self.admission.parsimonious(chosen, passing)
        if self.moves.time_constant_moves(path, chosen, design, tests):
            return True
        term = chosen.candidate.term.with_coefficient(chosen.coefficient)
        # Several runs share one clock from their own starts: a window in time names no run.
        window = [] if self.library.problem.per_run_offset else explain.locate(
            self.t_s, chosen.coefficient * (chosen.candidate.feature - np.median(chosen.candidate.feature)))
        record = explain.evidence(chosen, best, equivalent, margin, path.base_cv.rms_um, t_crit, len(folds),
                                  window[0][:2] if window else None, term.spec.description)
        if self.admission.per_run:
            record.runs = self.admission.runs.run_figures(chosen.cv, path.base_cv, chosen.candidate.runs_with)
        path.discovered.append(finding(term.effect, term.parameters, record))
        path.added.append(term)
        path.present.add(present_key(term))
        path.design = np.column_stack([design, chosen.candidate.feature])
        path.noise = np.column_stack([path.noise, chosen.candidate.noise])
        path.base_cv = chosen.cv
        return True

    def fitted_apart(self, path: Path, evaluations: list[Evaluation], passing: list[Evaluation],
                     t_crit: float) -> bool:
        """Candidates that pass every guard but leave runs worse than the harm tolerance (refused by it
        or not: ``Settings.run_harm_refuses``), better than every candidate that harms none: the one a
        round would pick among them tried fitted apart over two groups of runs (``fit_apart``); the
        others are its alternatives, not other relations. True when it was named so."""
        admission = self.admission
        reference = admission.runs.reference_folds(path.base_cv)

        def harms(e: Evaluation) -> bool:
            return bool(admission.runs.harms_runs(reference, e.cv.fold_rms_um))

        best_harmless = min((e.ranked_rms_um for e in passing if not harms(e)), default=math.inf)
        harming = []
        for evaluation in evaluations:
            if evaluation.ranked_rms_um >= best_harmless or not harms(evaluation):
                continue
            if evaluation not in passing:
                failing = [g for g in admission.guards_of(evaluation, path.base_cv, t_crit) if not g.passes]
                if not (len(failing) == 1 and failing[0].name == words.HARM
                        and admission.earned(evaluation, evaluations, passing)):
                    continue
            harming.append(evaluation)
        if not harming:
            return False
        # The simplest of those as good as the best first, as a round picks (a sensor before a gradient
        # with a sensor the baseline holds).
        _best, _margin, equivalent = admission.equivalent(harming)
        order = sorted(equivalent, key=lambda e: (e.candidate.term.spec.complexity, e.ranked_rms_um)) \
            + sorted((e for e in harming if e not in equivalent), key=lambda e: e.ranked_rms_um)
        assert self.fit_apart is not None
        return self.fit_apart(path, order[0], t_crit)

    def note_cannot_have(self, path: Path, refused: list[Evaluation], t_crit: float) -> list[Evaluation]:
        """Candidates that pass every guard but what a machine can have: never named, listed with
        their figures ("fits, but a machine cannot have it"). Returns those, and those held back only
        by the bar for their extra parameters: candidates that fit."""
        fitting = []
        for evaluation in refused:
            label = explain.label_with_time_constants(evaluation.candidate.term)
            guards = self.admission.guards_of(evaluation, path.base_cv, t_crit)
            failing = [g for g in guards if not g.passes]
            cannot = len(failing) == 1 and failing[0].figure.startswith(words.CANNOT_HAVE)
            if cannot or (len(failing) == 1 and failing[0] is guards[-1] and guards[-1].gain >= self.admission.bar):
                fitting.append(evaluation)
            if cannot and not any(item[0] == label for item in path.cannot_have):
                term = evaluation.candidate.term.with_coefficient(evaluation.coefficient)
                path.cannot_have.append((label, term, guards))
        return fitting

    def limit_may_have_stopped(self, path: Path) -> bool:
        """The search reached ``Settings.max_effects``, or came within a move of two of it (a round that
        admitted nothing may have been denied its pair round by the limit)."""
        s = self.settings
        return len(path.added) >= s.max_effects or (s.pair_moves and len(path.added) + 2 > s.max_effects)

    def judge_next_round(self, path: Path) -> None:
        """Whether the limit or the data stopped the search: the next round judged in full (single
        effects, moves of two, time constants, a fit apart over groups of runs) on a copy of the path,
        with room for a move of two beyond the terms named; the copy is thrown away, and the admission's
        count of paired tests is restored. Nothing admitted: the data stopped the search, and that
        round's candidates are the last round's (what ``closest`` and the detectable sizes rest on).
        Something admitted: the limit stopped it, and ``path.beyond_limit`` says what the round would
        name, with its held-out figure."""
        trial = copy.deepcopy(dataclasses.replace(path, rejected=[], judged=None))
        lifted = Search(self.y, self.t_s, self.library,
                        dataclasses.replace(self.settings, max_effects=len(path.added) + 2), self.baseline,
                        self.admission)
        lifted.fit_apart = self.fit_apart
        paired_tests = self.admission.paired_tests
        try:
            admitted = lifted.round(trial)
        finally:
            self.admission.paired_tests = paired_tests
        path.limit_terms = len(path.added)
        if not admitted:
            path.stopped_by = "data"
            if trial.rejected:
                path.rejected, path.rejected_t_critical = trial.rejected, trial.rejected_t_critical
                path.rejected_paired_tests = trial.rejected_paired_tests
            path.cannot_have = trial.cannot_have
            return
        path.stopped_by = "limit"
        labels = list(dict.fromkeys(explain.label_with_time_constants(term)
                                    for term in trial.added[len(path.added):]))
        before_um, after_um, _gain, figure = self.admission.heldout_figures(trial.base_cv, path.base_cv)
        path.beyond_limit = (labels, before_um, after_um, figure)

    def survey(self, path: Path) -> None:
        """The search stopped at the limit: the next round's candidates, evaluated and not admitted, so
        the words can say what came closest and the detectable sizes can be given."""
        surveyed = self.evaluate_round(path)
        if surveyed is not None:
            path.rejected, path.rejected_t_critical, _tests = surveyed
            path.rejected_paired_tests = self.admission.paired_tests

    def twin_of_one_sign(self, path: Path, evaluation: Evaluation) -> bool:
        """A sensor's second time constant, offered in a later round, moves the structure the same way
        as its first in the joint fit (a skin and a core of one structure heated from one side; two
        pulling apart are one band of time constants, not two paths of heat: ``split_move``)."""
        term = evaluation.candidate.term
        sensor = term.parameters.get("sensor")
        twins = [index for index, added in enumerate(path.added)
                 if added.effect == term.effect and added.parameters.get("sensor") == sensor
                 and time_constants(added) and sensor is not None]
        if not twins:
            return True
        full = np.column_stack([path.design, evaluation.candidate.feature])
        coefficients = stats.least_squares(full, self.y)
        first = path.design.shape[1] - len(path.added) + twins[0]
        return bool(coefficients[first] * coefficients[-1] > 0)

    def name_shapes(self, path: Path) -> None:
        """A sensor named with its temperature and its own lag is named as the shape the two make: the
        lag's column becomes the sensor's transient at the lag's time constant (the same span, the
        same held-out figures), and the temperature is the static part (``shapes``). Whether the
        static part earns its parameter is then the withdrawal's to judge."""
        offset = 1 if path.gain_mode else 0
        pairs = shapes.temperature_with_lag(path.added)
        if not pairs:
            return
        coefficients = stats.least_squares(path.design, self.y)
        first = path.design.shape[1] - len(path.added)
        design, noise = path.design.copy(), path.noise.copy()
        for temperature_index, lag_index in pairs:
            lag = path.added[lag_index]
            if not self.settings.second_time_constant_ratio and any(
                    t.effect == "transient_gradient" and t.parameters.get("sensor") == lag.parameters["sensor"]
                    for t in path.added):
                continue  # a sensor at one time constant only: its transient is named already
            candidate = self.library.candidate(shapes.as_transient(lag))
            record = path.discovered[lag_index + offset]
            if candidate is None or not isinstance(record.evidence, Evidence) \
                    or record.evidence.regime is not None \
                    or path.discovered[temperature_index + offset].evidence.regime is not None:
                # a lag (or a temperature) fitted apart over groups of runs is two columns, not one shape
                continue
            column = first + lag_index
            design[:, column], noise[:, column] = candidate.feature, candidate.noise
            path.added[lag_index] = candidate.term
            path.present.add(present_key(candidate.term))
            record.evidence.note = shapes.shape_words(str(lag.parameters["sensor"]), float(lag.parameters["tau_s"]),
                                                      float(coefficients[column]),
                                                      float(coefficients[first + temperature_index]))
            path.discovered[lag_index + offset] = finding(candidate.term.effect, candidate.term.parameters,
                                                          record.evidence)
        path.design, path.noise = design, noise
        path.base_cv = self.baseline.cross_validate(path.design, self.y, self.baseline.folds)

    def withdraw_redundant(self, path: Path) -> None:
        """With the runs' paired test and its lower bar, a term may pass in an early round and be
        explained by the terms named after it (a gradient of the rear and the ambient, then the rear's
        and the front's own temperatures; a second time constant that stood in for a temperature named
        later; a term fitted apart on a group of runs before the group's later terms). Each term must
        still clear its bar (``withdrawal_bar``; a term fitted apart, one parameter more) over the
        others: without it, the median over runs of held-out RMS must rise by the bar, the worst run by
        the margin of equivalence, or some run by more than the harm tolerance. The one that matters
        least is withdrawn (a term fitted apart, both its groups' columns), and the rest are judged
        again; a term of a move whose partner goes stays, alone."""
        s = self.settings
        offset = 1 if path.gain_mode else 0
        while True:
            weakest: tuple[float, tuple[int, ...], stats.CrossValidation, list[int], float] | None = None
            for unit in self.withdrawal_units(path):
                record = path.discovered[unit[0] + offset].evidence
                assert isinstance(record, Evidence)
                without, keep = self.without_added(path, *unit)
                median_with, median_without = (float(np.median(cv.fold_rms_um)) for cv in (path.base_cv, without))
                loss = 1.0 - median_with / median_without if median_without > 0 else 0.0
                worst_with, worst_without = max(path.base_cv.fold_rms_um), max(without.fold_rms_um)
                # a term fitted apart (two columns): one coefficient more than its own
                bar = self.admission.withdrawal_bar(path.added[unit[0]], len(unit) - 1) \
                    if record.move is None or s.withdraw_per_parameter else -math.inf
                if loss < bar and worst_without <= (1 + s.equivalence) * worst_with \
                        and not self.admission.runs.harms_runs(path.base_cv.fold_rms_um, without.fold_rms_um) \
                        and (weakest is None or loss < weakest[0]):
                    weakest = (loss, unit, without, keep, bar)
            if weakest is None:
                return
            loss, unit, without, keep, bar = weakest
            why = words.withdrawn_words(
                float(np.median(without.fold_rms_um)), float(np.median(path.base_cv.fold_rms_um)), loss, bar,
                self.admission.bar, path.added[unit[0]], max(without.fold_rms_um), max(path.base_cv.fold_rms_um),
                extra_parameters=len(unit) - 1)
            self.take_out(path, unit, without, keep, why)

    def withdrawal_units(self, path: Path) -> list[tuple[int, ...]]:
        """What the withdrawal weighs as one: each term, and a term fitted apart over groups of runs as
        its two groups' columns together (named one after the other, the larger group first)."""
        offset = 1 if path.gain_mode else 0
        units: list[tuple[int, ...]] = []
        index = 0
        while index < len(path.added):
            record = path.discovered[index + offset].evidence
            if not isinstance(record, Evidence):
                index += 1
                continue
            if record.regime is None:
                units.append((index,))
                index += 1
                continue
            partner = path.discovered[index + offset + 1].evidence if index + 1 < len(path.added) else None
            if not record.regime.apart and isinstance(partner, Evidence) and partner.regime is not None \
                    and partner.regime.apart and path.added[index + 1].effect == path.added[index].effect:
                units.append((index, index + 1))
                index += 2
            else:
                index += 1
        return units

    def withdraw_beyond_structure(self, path: Path) -> bool:
        """A term is admitted at the size a machine can have (the physical guard), but the terms named
        after it move its coefficient in the joint fit (a sensor named alone absorbs part of a
        correlated sensor of the other sign, and grows once that one is in). Named terms whose final
        coefficient a machine cannot have are withdrawn, the largest first, until none is left; the
        words give the final size, why, and the held-out figure without it. A term fitted apart over
        groups of runs is two columns, judged when it was split. True when one was withdrawn."""
        offset = 1 if path.gain_mode else 0
        withdrawn = False
        while path.added:
            coefficients = stats.least_squares(path.design, self.y)
            first = path.design.shape[1] - len(path.added)
            beyond = []
            for index, term in enumerate(path.added):
                record = path.discovered[index + offset].evidence
                if isinstance(record, Evidence) and record.regime is not None:
                    continue
                coefficient = float(coefficients[first + index])
                why = term.spec.cannot_have(term.parameters, coefficient, self.settings.structure)
                if why:
                    beyond.append((abs(coefficient), index, coefficient, why))
            if not beyond:
                return withdrawn
            withdrawn = True
            _size, index, coefficient, why = max(beyond)
            without, keep = self.without_added(path, index)
            without_um, with_um, _gain, figure = self.admission.heldout_figures(path.base_cv, without)
            self.take_out(path, index, without, keep, words.beyond_structure_words(why, figure, without_um, with_um),
                          coefficient)
        return withdrawn

    def take_out(self, path: Path, indices: int | tuple[int, ...], without: stats.CrossValidation, keep: list[int],
                 why: str, coefficient: float | None = None) -> None:
        """Withdraws ``path.added[index]`` (its column, its record; ``without``: the path's design
        without it, cross-validated, and the columns kept) with ``why``, at ``coefficient`` when given;
        the partner of a move it was named in stays as a term of its own. Several indices: a term
        fitted apart over groups of runs, its groups' columns."""
        offset = 1 if path.gain_mode else 0
        taken = (indices,) if isinstance(indices, int) else indices
        term = path.added[taken[0]] if coefficient is None else path.added[taken[0]].with_coefficient(coefficient)
        gone = [path.discovered[index + offset].evidence for index in taken]
        for index in sorted(taken, reverse=True):
            path.added.pop(index)
            path.discovered.pop(index + offset)
        path.design, path.noise = path.design[:, keep], path.noise[:, keep]
        label = explain.label_with_time_constants(term) + (" fitted apart over groups of runs" if len(taken) > 1 else "")
        path.withdrawn.append(Withdrawn(term.effect, label, dict(term.parameters), why))
        path.base_cv = without
        for record in gone:
            if isinstance(record, Evidence) and record.move is not None:
                self.leave_move(path, record.move.terms, label)

    def leave_move(self, path: Path, members: list[str], withdrawn: str) -> None:
        """A term of a move was withdrawn: its partner stays as a term of its own, and says so."""
        for found in path.discovered:
            record = found.evidence
            if isinstance(record, Evidence) and record.move is not None and record.move.terms == members:
                record.move = None
                record.preferred = words.partner_withdrawn_words(withdrawn)

    def without_added(self, path: Path, *indices: int) -> tuple[stats.CrossValidation, list[int]]:
        """The path's design without the columns of ``path.added[index]`` for each of ``indices``,
        cross-validated, and the columns kept."""
        first = path.design.shape[1] - len(path.added)
        gone = {first + index for index in indices}
        keep = [c for c in range(path.design.shape[1]) if c not in gone]
        return self.baseline.cross_validate(path.design[:, keep], self.y, self.baseline.folds), keep

    def twin_shares(self, path: Path) -> None:
        """A sensor named at two time constants in two rounds (the second found once another term was
        in): each one's share, as for a move of two, of what the two improve together: how much the
        held-out figure rises without it."""
        groups: dict[tuple[str, object], list[int]] = {}
        for index, term in enumerate(path.added):
            if time_constants(term) and term.parameters.get("sensor") is not None:
                groups.setdefault((term.effect, term.parameters["sensor"]), []).append(index)
        for indices in groups.values():
            records = [path.discovered[i + (1 if path.gain_mode else 0)].evidence for i in indices]
            if len(indices) != 2 or any(not isinstance(r, Evidence) or r.move is not None for r in records):
                continue
            lost = [max(self.admission.heldout_gain(path.base_cv, self.without_added(path, index)[0]), 0.0)
                    for index in indices]
            total = sum(lost)
            for record, part in zip(records, lost, strict=True):
                assert isinstance(record, Evidence)
                record.twin_share = round(part / total if total > 0 else 0.5, 4)
