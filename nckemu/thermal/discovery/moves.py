"""Moves of two effects: physics that comes in pairs (a temperature and its lag, two sensors of one
gradient, a fast skin and a slow core of one sensor) tried together and admitted as two effects."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.model import families
from nckemu.thermal.model.families import Family
from nckemu.thermal.model.terms import Term

from . import explain
from . import selection_words as words
from .admission import Admission, t_critical
from .findings import MoveAlternative, MoveEvidence, finding
from .fits import Fits
from .library import Library, present_key, time_constants
from .records import Baseline, Evaluation, Move, Path
from .settings import Settings


class Moves:
    def __init__(self, y: np.ndarray, library: Library, settings: Settings, baseline: Baseline,
                 admission: Admission, fits: Fits) -> None:
        self.y = y
        self.library = library
        self.settings = settings
        self.baseline = baseline
        self.admission = admission
        self.fits = fits

    def pair_round(self, path: Path, evaluations: list[Evaluation], single_tests: int) -> bool:
        """No single effect passed: screen the pairs of the round's candidates, cross-validate the best
        few, and admit the simplest passing move as two effects. Every guard applies to the move as a
        whole (both coefficients past the t-test, Bonferroni-corrected over every pair of hypotheses),
        and each effect must earn its place in it: the move must clear the held-out bar over either
        effect alone."""
        s = self.settings
        pool = sorted(evaluations, key=lambda e: e.ranked_rms_um)[: s.pair_pool]
        if len(pool) < 2:
            return False
        pairs = self.screen_pairs(path.design, pool)
        grid = np.array([e.candidate.grid_points for e in pool], dtype=float)
        tests = single_tests + int((grid.sum() ** 2 - float(np.sum(grid ** 2))) / 2)
        t_crit = self._move_t_critical(path.design, tests)
        moves = [self.fits.evaluate_pair(path, pool[first], pool[second]) for first, second in pairs]
        if self.admission.per_run:
            self.admission.paired_tests = max(1, sum(self.admission.move_passes(path, move, t_crit, paired=False)
                                                     for move in moves))
        passing = [move for move in moves if self.admission.move_passes(path, move, t_crit)]
        if not passing:
            return False
        best = min(passing, key=lambda m: m.ranked_rms_um)
        margin = s.equivalence * (1 + sum(time_constants(term) for term in best.terms))
        equivalent = [m for m in passing if m.ranked_rms_um <= best.ranked_rms_um * (1 + margin)]
        chosen = min(equivalent, key=lambda m: (sum(t.spec.complexity for t in m.terms), m.ranked_rms_um))
        self.admit_move(path, chosen, [m for m in equivalent if m is not chosen], t_crit)
        return True

    def screen_pairs(self, design: np.ndarray, pool: list[Evaluation]) -> list[tuple[int, int]]:
        """The ``pair_beam`` pairs of ``pool`` that lower the in-sample residual most beside ``design``:
        the features and the gauge projected off the design once, then every pair's fit is a 2 x 2
        solve on one Gram matrix (no fit of n samples per pair)."""
        features = np.column_stack([e.candidate.feature for e in pool])
        target = self.y
        if design.shape[1]:
            stacked = np.column_stack([features, target])
            stacked = stacked - design @ stats.least_squares(design, stacked)
            features, target = stacked[:, :-1], stacked[:, -1]
        gram = features.T @ features
        moment = features.T @ target
        diagonal = np.diag(gram)
        first, second = np.triu_indices(len(pool), 1)
        cross = gram[first, second]
        determinant = diagonal[first] * diagonal[second] - cross ** 2
        # Near-collinear pairs (a lag and a slightly longer lag) are one effect fitted twice: skipped.
        usable = determinant > 1e-6 * diagonal[first] * diagonal[second]
        with np.errstate(divide="ignore", invalid="ignore"):
            reduction = (diagonal[second] * moment[first] ** 2 - 2 * cross * moment[first] * moment[second]
                         + diagonal[first] * moment[second] ** 2) / determinant
        reduction = np.where(usable & np.isfinite(reduction), reduction, -np.inf)
        # Pairs that span the same columns with the design (temperature(a) + temperature(b), or the
        # gradient a - b and either; a sensor of the design and a gradient with it) fit alike: the
        # simplest stands for them, and the beam holds moves that differ.
        complexity = np.array([e.candidate.term.spec.complexity for e in pool])
        scale = float(np.max(reduction)) if np.isfinite(np.max(reduction)) and np.max(reduction) > 0 else 1.0
        order = np.lexsort((complexity[first] + complexity[second], -np.round(reduction / scale, 7)))
        chosen: list[int] = []
        for k in order:
            if len(chosen) == self.settings.pair_beam or not reduction[k] > 0:
                break
            if not any(abs(reduction[k] - reduction[c]) <= 1e-6 * reduction[c] for c in chosen):
                chosen.append(int(k))
        return [(int(first[k]), int(second[k])) for k in chosen]

    def admit_move(self, path: Path, move: Move, equivalent: list[Move], t_crit: float, *,
                   why: str = words.PAIR_WHY,
                   alternatives: list[MoveAlternative] | None = None,
                   preferred: Callable[[int], str] | None = None) -> None:
        folds = len(self.baseline.folds)
        figures = self.admission.runs.run_figures(move.cv, path.base_cv, move.runs_with) if self.admission.per_run else None
        for index, (alone, term) in enumerate(zip(move.alone, move.terms, strict=True)):
            member = Evaluation(alone.candidate, move.cv, move.t_values[index], move.coefficients[index],
                                move.fold_wins, move.ranked_rms_um)
            record = explain.evidence(member, member, [member], 0.0, path.base_cv.rms_um, t_crit, folds, None,
                                      term.spec.description)
            record.move = MoveEvidence(
                [e.candidate.label for e in move.alone], round(move.cv.rms_um, 4),
                [round(e.cv.rms_um, 4) for e in move.alone], [round(share, 3) for share in move.shares],
                [MoveAlternative(m.label, round(m.cv.rms_um, 4)) for m in equivalent] + (alternatives or []),
                why, round(move.shares[index], 3))
            record.preferred = preferred(index) if preferred is not None else \
                words.move_preferred(move.label, move.shares[index])
            record.runs = figures
            path.discovered.append(finding(term.effect, term.parameters, record))
            path.added.append(term)
            path.present.add(present_key(term))
        path.design = np.column_stack([path.design] + [e.candidate.feature for e in move.alone])
        path.noise = np.column_stack([path.noise] + [e.candidate.noise for e in move.alone])
        path.base_cv = move.cv

    def time_constant_moves(self, path: Path, chosen: Evaluation, design: np.ndarray, tests: int) -> bool:
        """The round names an effect with a time constant of one sensor. Two questions before it is
        admitted as one effect (issue 42), each a move of two judged under every guard, which must
        clear the held-out bar over the effect the round chose and over either of its own alone:

        - a measured partner: the sensor's lag (or transient) with its time constant searched again
          beside another sensor's plain temperature (a lag found alone absorbs what a correlated
          sensor explains: a bed that follows the ambient and part of the spindle's heat);
        - two time constants of the sensor (a fast skin and a slow core), both of one sign.

        A measured sensor comes before a constructed one: the partner is named when it is within the
        margin of equivalence of the two time constants. Every value tried counts among the round's
        hypotheses. True when a move was admitted."""
        s = self.settings
        term = chosen.candidate.term
        sensor = term.parameters.get("sensor")
        if sensor is None or not time_constants(term) or len(path.added) + 2 > s.max_effects:
            return False
        tried_moves: list[tuple[str, Move, float]] = []
        # A partner search starts from the one time constant family the chosen term is or extends (the
        # registry's searched_column); two time constants only of such a family itself.
        partner_family = families.one_time_constant_family(term.effect)
        if partner_family is not None and s.measured_partners:
            partnered = self.partner_move(path, chosen, design, tests, partner_family, str(sensor))
            if partnered is not None:
                move, t_crit, other_partners = partnered
                tried_moves += [("partner", m, t_crit) for m in (move, *other_partners)]
        kind = term.spec.searched_column
        if kind is not None and s.second_time_constant_ratio:
            found = self.split_move(path, chosen, design, tests, kind, str(sensor))
            if found is not None:
                tried_moves.append(("split", *found))
        passing = [(what, move, t_crit) for what, move, t_crit in tried_moves
                   if self.admission.move_passes(path, move, t_crit, over=chosen)]
        if not passing:
            return False
        best = min(passing, key=lambda item: item[1].ranked_rms_um)
        margin = s.equivalence * (1 + sum(time_constants(t) for t in best[1].terms))
        measured = [item for item in passing if item[0] == "partner"
                    and item[1].ranked_rms_um <= best[1].ranked_rms_um * (1 + margin)]
        what, move, t_crit = measured[0] if measured else best
        others = [item for item in passing if item[1] is not move]

        def named(what: str, move: Move) -> str:
            if what != "split":
                return move.label
            return words.two_time_constants_label(move.alone[0].candidate.label,
                                                  [t.parameters["tau_s"] for t in move.terms])

        alternatives = [MoveAlternative(words.alone_label(chosen.candidate.label), round(chosen.cv.rms_um, 4))] \
            + [MoveAlternative(named(w, m), round(m.cv.rms_um, 4)) for w, m, _t in others]
        hours = [words.hours(t.parameters["tau_s"]) for t in move.terms if "tau_s" in t.parameters]
        if what == "split":
            why = words.split_why(hours[0], hours[1], chosen.candidate.label, chosen.cv.rms_um, move.cv.rms_um)

            def preferred(index: int) -> str:
                return words.split_preferred(chosen.candidate.label, hours[0], hours[1], move.shares[index])
        else:
            equivalent = [named(w, m) for w, m, _t in others if m.ranked_rms_um <= move.ranked_rms_um * (1 + margin)]
            plain = not time_constants(move.alone[0].candidate.term)
            why = words.partner_why(plain, move.label, chosen.candidate.label, chosen.cv.rms_um, move.cv.rms_um)
            if equivalent:
                constructed = any(w == "split" for w, m, _t in others
                                  if m.ranked_rms_um <= move.ranked_rms_um * (1 + margin))
                measured_too = any(w == "partner" for w, m, _t in others
                                   if m.ranked_rms_um <= move.ranked_rms_um * (1 + margin))
                why += words.equivalent_partners_words(
                    margin, equivalent, move.alone[1].candidate.label if measured_too else None, constructed)

            def preferred(index: int) -> str:
                return words.partner_preferred(move.label, plain, move.shares[index])
        self.admit_move(path, move, [], t_crit, why=why, alternatives=alternatives, preferred=preferred)
        return True

    def _alone(self, path: Path, design: np.ndarray, terms: list[Term], grid_points: int) -> list[Evaluation] | None:
        alone = []
        for term in terms:
            candidate = self.library.candidate(term, grid_points)
            if candidate is None:
                return None
            alone.append(self.fits.evaluate(design, path.noise, candidate, path.base_cv))
        return alone

    def _move_t_critical(self, design: np.ndarray, tests: int) -> float:
        return t_critical(self.settings.alpha, tests,
                          len(self.y) - design.shape[1] - 2 - self.baseline.extra_parameters)

    def partner_move(self, path: Path, chosen: Evaluation, design: np.ndarray, tests: int, searched: Family,
                     sensor: str) -> tuple[Move, float, list[Move]] | None:
        """The sensor's ``effect`` beside the best other sensor's plain temperature, its time constant
        searched again with the partner in; and the same beside each other partner (sensors that share
        drivers may each stand in for the other: the words list those the data cannot tell apart)."""
        library = self.library
        partners: dict[str, Term] = {}
        for other in library.sensors():
            if other == sensor or f"temperature:{other}" in path.present or library.modelled("temperature", other):
                continue
            partners[other] = Term("temperature", {"sensor": other, "t_ref_C": library.t_ref(other),
                                                   "coeff_um_per_K": 0.0})
        columns = {}
        for name, partner in partners.items():
            candidate = library.candidate(partner)
            if candidate is not None:
                columns[name] = candidate.feature
        assert searched.searched_column is not None
        found = library.best_with_partner(searched.searched_column, sensor, design, columns)
        if found is None:
            return None
        tau_s, partner_name, tried = found
        base = {"sensor": sensor, "tau_s": tau_s, "coeff_um_per_K": 0.0}
        if "t_ref_C" in searched.optional:
            base = {"sensor": sensor, "t_ref_C": library.t_ref(sensor), **base}
        alone = self._alone(path, design, [Term(searched.effect, base), partners[partner_name]], tried)
        if alone is None:
            return None
        move = self.fits.evaluate_pair(path, alone[0], alone[1])
        plain = Term("temperature", {"sensor": sensor, "t_ref_C": library.t_ref(sensor), "coeff_um_per_K": 0.0})
        if f"temperature:{sensor}" not in path.present and not library.modelled("temperature", sensor):
            # A time constant that earns nothing over the sensor itself (re-searched to the grid's
            # end beside the partner: a lag of 4 min of a sensor averaged over 5) is the sensor.
            simple = self._alone(path, design, [plain, partners[partner_name]], 1)
            if simple is not None:
                simpler = self.fits.evaluate_pair(path, simple[0], simple[1])
                if move.ranked_rms_um > (1 - self.admission.bar) * simpler.ranked_rms_um:
                    move = simpler
        others = []
        for name, partner in partners.items():
            if name == partner_name or name not in columns:
                continue
            other = self._alone(path, design, [move.alone[0].candidate.term, partner], tried)
            if other is not None:
                others.append(self.fits.evaluate_pair(path, other[0], other[1]))
        return move, self._move_t_critical(design, tests + tried), others

    def split_move(self, path: Path, chosen: Evaluation, design: np.ndarray, tests: int, kind: str,
                   sensor: str) -> tuple[Move, float] | None:
        """The sensor at its best pair of time constants (``Library.best_time_constant_pair``), both
        coefficients of one sign."""
        found = self.library.best_time_constant_pair(kind, sensor, design, self.settings.second_time_constant_ratio)
        if found is None:
            return None
        _rms, fast_s, slow_s, tried = found
        term = chosen.candidate.term
        alone = self._alone(path, design, [Term(term.effect, {**term.parameters, "tau_s": tau_s,
                                                              term.spec.coefficient: 0.0})
                                           for tau_s in (fast_s, slow_s)], tried)
        if alone is None:
            return None
        move = self.fits.evaluate_pair(path, alone[0], alone[1])
        if move.coefficients[0] * move.coefficients[1] <= 0:
            # A skin and a core of one structure heated from one side move it the same way; two lags of
            # one sensor pulling apart are a transient (a family of its own), two transients pulling
            # apart one band of time constants, not two paths of heat.
            return None
        return move, self._move_t_critical(design, tests + tried)
