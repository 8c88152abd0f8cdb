"""The knobs of discovery, in one frozen object every part of the pipeline reads (docs/thermal.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nckemu.thermal.model.structure import Structure


@dataclass(frozen=True)
class Settings:
    folds: int = 5
    min_improvement: float = 0.10       # relative drop of held-out RMS
    min_fold_share: float = 0.8         # share of folds (blocks of one run) that must improve
    # Several runs: instead of a share of runs that must improve, a paired test on each run's held-out
    # mean squared error before and after (Wilcoxon signed-rank, one-sided), at this level corrected
    # (Bonferroni) over the candidates of the round that reach it. With fewer than runs_test_min runs
    # (a few days of data: the test could hardly reach its level with one run not improving),
    # min_fold_share of the runs must improve, as before.
    runs_alpha: float = 0.05
    runs_test_min: int = 10
    # ... and then the held-out bar (the median over runs of each run's held-out RMS) is this drop, not
    # min_improvement: the paired test carries the evidence, the bar keeps out terms too small to matter.
    runs_min_improvement: float = 0.05
    runs_replace_t_test: bool = True
    # ... and a term's bar is weighed by its parameters (issue 51): each of them (the coefficient, each
    # time constant) must buy runs_min_improvement of what is left, 1 - (1 - bar)^parameters, in the
    # rounds and again at the end (withdraw_per_parameter). The paired test is corrected over the
    # candidates, not over the time constants tried as the t-test was, so without it a lag would earn
    # its time constant for free; the correction counts the candidates at the unweighed bar (see
    # Admission.count_paired_tests for what happened when it did not).
    runs_bar_per_parameter: bool = True
    withdraw_per_parameter: bool = True
    # No run made worse in silence: a term that leaves a run worse than this share more than before, and
    # by more than run_harm_floor_um, is first tried fitted apart over two groups of runs
    # (discovery/regimes.py: fit_apart), and named so when that harms none. When it cannot be,
    # run_harm_refuses refuses it; off (the default), it is admitted with the runs it harms named in its
    # guard, and the runs the final model leaves worse than before are named in the report's headline,
    # its runs table and run_figures.made_worse (with what they share).
    # On: on fl_thermal ch1 and ch5 cut into 14 runs every term harms a quiet run (0.63 -> 1.2 um),
    # none can be fitted apart, and nothing was named (median over runs 0.77 -> 2.54 um, 1.19 -> 3.17 um).
    run_harm_share: float = 0.10
    run_harm_floor_um: float = 0.3
    run_harm_refuses: bool = False
    # ... and after the search, a term of the last round may be fitted apart on two groups of runs
    # (discovery/regimes.py). False: never.
    run_groups: bool = True
    # ... nor two terms that cancel each other (fits.cancelling): together less than this share of the
    # larger alone, which moves the structure more than the whole error does. 0 turns it off.
    cancelling_share: float = 0.5
    # What a machine can have (issue 51): a term beyond it fits, but is never named (a model file's
    # [structure] table sets it for its machine).
    structure: Structure = Structure()
    alpha: float = 0.01                 # family-wise, Bonferroni over the candidates of a round
    equivalence: float = 0.03           # held-out RMS within 3 % of the best: equivalent
    max_effects: int = 6
    outlier_sigmas: float = 8.0
    min_gain_departure: float = 0.03
    # A gain error claims that a gauge or a scale reads gain x the truth: only physical values.
    gain_range: tuple[float, float] = (0.5, 2.0)
    # The model as given fits the record within this share of the least-squares optimum's RMS: it
    # was calibrated on the record, and its RMS as given is in-sample.
    calibrated_tolerance: float = 0.002
    glitch_sigmas: float = 8.0          # sensor bursts beyond this many robust sigma are glitches
    glitch_min_K: float = 0.3           # ... and beyond this many kelvin
    glitch_max_span_s: float = 600.0    # ... and over within this time (slower is heat a structure follows)
    # Temperature readings are averaged over this centred window before features are built: a
    # structure does not follow a sensor's white noise, and a difference of two sensors (a gradient)
    # carries the noise of both against a small signal (errors in variables).
    sensor_smoothing_s: float = 300.0
    # The fixed draw of sensor noise that measures how much of it each feature passes on (the
    # errors-in-variables share of a candidate's held-out RMS): fixed, so a run is repeatable.
    noise_draw_seed: int = 0
    lag_grid_s: tuple[float, ...] = tuple(float(v) for v in np.geomspace(300.0, 6 * 3600.0, 18))
    hysteresis_grid_s: tuple[float, ...] = tuple(float(v) for v in np.geomspace(600.0, 4 * 3600.0, 8))
    # Several runs sampled faster than this are resampled to it (the gauge averaged per step) once
    # the readings are averaged: nothing thermal is faster, and 30 runs of a day at 1 Hz fit in time.
    runs_resample_s: float = 30.0
    # "Likely, not proven": a term that passes every guard but the held-out bar, and still lowers
    # held-out RMS by at least this share, is reported with its figures, apart from the findings.
    likely_min_improvement: float = 0.02
    # When no single effect passes, moves of two effects are tried (issue 31: physics often comes in
    # pairs): every pair of the round's candidates is screened in-sample through one Gram matrix
    # (at most ``pair_pool`` candidates, the best alone first), the ``pair_beam`` best pairs are
    # cross-validated and judged as one move under every guard.
    pair_moves: bool = True
    pair_pool: int = 60
    pair_beam: int = 8
    # One sensor at two time constants (issue 42: a fast skin and a slow core). When a round names a
    # lag or a transient, the same sensor's pair of time constants at least this ratio apart is tried
    # as a move of two; it is named instead when it clears the held-out bar over the one time constant
    # (and over either of its own alone) under every guard. 0 turns it off.
    second_time_constant_ratio: float = 2.5
    # ... and beside it, the same sensor's lag (or transient) searched again with another sensor's plain
    # temperature, when they share drivers (issue 42: a spindle lag and a bed that follows the ambient
    # and part of the spindle's heat); named when it clears the same bars, before two time constants
    # within the margin of equivalence (a measured sensor before a constructed one).
    measured_partners: bool = True
