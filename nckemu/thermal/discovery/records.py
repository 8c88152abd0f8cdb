"""The selector's records: a candidate as evaluated (``Evaluation``), a guard as it stands against
it (``Guard``), a move of two effects (``Move``), what every search path shares (``Baseline``) and one
line of explanation as it grows (``Path``). Data only: the search fills them, the words read them."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.model.terms import Term

from .findings import Finding, Withdrawn
from .library import Candidate


@dataclass
class Evaluation:
    candidate: Candidate
    cv: stats.CrossValidation
    t_value: float
    coefficient: float
    fold_wins: int
    # Held-out RMS without the sensors' noise carried by the fitted model's features: what candidates
    # are ranked on (held-out RMS itself still decides whether one is admitted at all).
    ranked_rms_um: float
    # RMS of the part of the feature the design does not already hold (for the detectable size).
    own_rms: float = math.nan
    # Why the candidate and a named term cancel each other in the joint fit (``fits.cancelling``):
    # empty when they do not.
    cancelling: str = ""


@dataclass(frozen=True)
class Guard:
    """One guard against false discovery as a candidate stands against it: its figure in words and
    whether it passes (``gain``: the held-out bar's relative drop)."""
    name: str
    passes: bool
    figure: str
    gain: float = math.nan


@dataclass
class Move:
    """Two effects judged as one move, tried when no single effect passes: physics that comes in pairs
    (a temperature and its lag, two sensors of one gradient) may show only together."""
    alone: tuple[Evaluation, Evaluation]    # each effect on its own, from the round's evaluations
    cv: stats.CrossValidation
    t_values: tuple[float, float]
    coefficients: tuple[float, float]
    fold_wins: int
    ranked_rms_um: float
    runs_with: np.ndarray | None            # runs that have the columns of both (None: all)
    # Each effect's share of what the move improves: how much the held-out figure rises without it.
    shares: tuple[float, float] = (math.nan, math.nan)
    cancelling: str = ""                    # as for an Evaluation, over both effects

    @property
    def terms(self) -> tuple[Term, Term]:
        return (self.alone[0].candidate.term.with_coefficient(self.coefficients[0]),
                self.alone[1].candidate.term.with_coefficient(self.coefficients[1]))

    @property
    def label(self) -> str:
        return " + ".join(e.candidate.label for e in self.alone)


@dataclass
class Baseline:
    """What every search path shares: the baseline's columns, the folds and the baseline's figures."""
    base_design: np.ndarray
    given: np.ndarray
    folds: list[np.ndarray]
    baseline_rms: float
    recalibrated: stats.Fit | None
    recalibrated_rms: float
    given_cv: stats.CrossValidation
    recal_cv: stats.CrossValidation
    calibrated_here: bool
    base_noise: np.ndarray          # sensor noise carried by base_design's columns
    given_noise: np.ndarray         # ... and by the model as given
    # Columns fitted besides the design that every fit carries (one offset per run): degrees of freedom.
    extra_parameters: int = 0
    # How held-out RMS is computed for the folds (several runs: through each fold's normal equations).
    cross_validate: Callable[[np.ndarray, np.ndarray, list[np.ndarray]], stats.CrossValidation] = \
        stats.cross_validate
    gain: tuple[float, float, stats.CrossValidation] = (math.nan, math.nan, stats.CrossValidation(math.nan, ()))

    @property
    def given_heldout_um(self) -> float:
        """The model as given is held-out data only when it was not calibrated on this record."""
        return math.inf if self.calibrated_here else self.baseline_rms

    @property
    def reference_cv(self) -> stats.CrossValidation:
        """The like-for-like baseline: refitted per fold, or as given when that predicts better."""
        return self.recal_cv if self.recal_cv.rms_um <= self.given_heldout_um else self.given_cv


@dataclass
class Path:
    """One line of explanation: the recalibrated model plus effects, or gain x model plus effects."""
    gain_mode: bool
    design: np.ndarray
    base_cv: stats.CrossValidation
    noise: np.ndarray               # sensor noise carried by each column of design
    discovered: list[Finding] = field(default_factory=list)
    added: list[Term] = field(default_factory=list)
    present: set[str] = field(default_factory=set)
    final: stats.Fit | None = None
    # The last round's candidates, none of which passed, and its critical t: what "nothing more"
    # rests on (the smallest detectable effects, a term that is likely but not proven).
    rejected: list[Evaluation] = field(default_factory=list)
    rejected_t_critical: float = math.nan
    rejected_paired_tests: int = 1     # ... and how many candidates the runs' paired test was corrected over
    # Terms named in a round and withdrawn at the end: the terms named after them explain what they did.
    withdrawn: list[Withdrawn] = field(default_factory=list)
    # What stopped the search: "data" (nothing more earned its place; below the limit, or judged at it)
    # or "limit". ``limit_terms``: the terms named when the limit was reached (0: never reached);
    # ``beyond_limit``: what the next round would name past it (labels, held-out before and after, figure).
    stopped_by: str = "data"
    limit_terms: int = 0
    beyond_limit: tuple[list[str], float, float, str] | None = None
    # Candidates that passed every guard but what a machine can have: (label, term, guards).
    cannot_have: list[tuple[str, Term, list[Guard]]] = field(default_factory=list)
    # The last round's candidates with every guard's figure, judged once (``Selector.judged``).
    judged: list[tuple[Evaluation, list[Guard]]] | None = None

    @property
    def at_limit(self) -> bool:
        """The search stopped at Settings.max_effects, and the next round, judged on a copy with the
        limit lifted, would have named more: its candidates are surveyed, not judged."""
        return self.stopped_by == "limit"
