"""Words that follow the figures (issue 42): "below the bar" only of a figure below it, on every path."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from nckemu.thermal import stats
from nckemu.thermal.discovery.explain import bar_words, likely_record
from nckemu.thermal.discovery.library import Candidate
from nckemu.thermal.discovery.records import Evaluation
from nckemu.thermal.model.terms import Term


def _evaluation() -> Evaluation:
    term = Term("transient_gradient", {"sensor": "spindle", "tau_s": 2400.0, "coeff_um_per_K": 0.0})
    candidate = Candidate(term, np.zeros(4), np.zeros(4))
    return Evaluation(candidate, stats.CrossValidation(0.9, (0.9, 0.9)), 6.0, 1.5, 2, 0.9)


@given(gain=st.floats(-0.5, 0.9), bar=st.floats(0.01, 0.5))
def test_below_is_said_only_of_a_figure_below_the_bar(gain: float, bar: float) -> None:
    words = bar_words(gain, bar, "held-out RMS", "the runs' paired test refused it")
    assert ("below the" in words) == (gain < bar)
    assert ("above the" in words) == (gain >= bar)
    assert f"{gain:.1%}" in words


def test_a_figure_above_the_bar_names_what_held_the_term_back() -> None:
    words = bar_words(0.106, 0.10, "the median over runs of held-out RMS", "only 20 of 30 runs improve")
    assert words == ("lowers the median over runs of held-out RMS by 10.6%, above the 10% bar, but only 20 of "
                     "30 runs improve")
    assert "below" not in words
    assert "another guard held it back" in bar_words(0.2, 0.1, "held-out RMS")


def test_a_likely_record_s_words_follow_its_own_figures() -> None:
    below = likely_record(_evaluation(), 1.0, 0.95, 0.05, "held-out RMS", 4.2, 5, 0.10)
    assert below.evidence.heldout_improvement == 0.05 and "5.0%, below the 10%" in below.evidence.why
    assert "improves 2 of 5 folds" in below.evidence.why
    runs = likely_record(_evaluation(), 7.0, 6.258, 0.106, "the median over runs of held-out RMS", 4.2, 30, 0.10,
                         "runs", "only 20 of 30 runs improve")
    assert "above the 10% bar" in runs.evidence.why and "below" not in runs.evidence.why
    assert "of 30 runs" in runs.evidence.why
    # the figures are the ones the words speak of
    assert runs.evidence.heldout_rms_before_um == 7.0 and runs.evidence.heldout_rms_after_um == 6.258
    assert runs.to_json()["evidence"]["heldout_improvement"] == 0.106


def test_when_structure_remains_after_the_last_term_the_detectable_sizes_are_given() -> None:
    from pathlib import Path

    from nckemu.thermal.discovery.discover import discover_runs
    from nckemu.thermal.discovery.wording import finding_lines
    from nckemu.thermal.recordings.recording import load_runs

    runs = load_runs([str(Path(__file__).resolve().parents[3] / "fixtures/thermal/runs")])
    result = discover_runs(runs, "Z")
    assert result.missing_physics and result.residual_is_structure
    assert {"temperature", "thermal_lag", "transient_gradient"} <= set(result.smallest_detectable_um)
    left = next(line for line in finding_lines(result) if line.startswith("left:"))
    assert "still structure" in left and "thermal_lag 0.2" in left
