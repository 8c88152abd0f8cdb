"""The selector's words read as the figures they carry: a bar weighed by parameters says so, the runs a
term harms are named (four at most), and "candidate" takes its plural only for more than one."""

from __future__ import annotations

from nckemu.thermal.discovery import selection_words as words
from nckemu.thermal.model.terms import Term

LAG = Term("thermal_lag", {"sensor": "spindle", "tau_s": 1800.0, "coeff_um_per_K": 1.0})


def test_the_held_out_figure_says_when_the_bar_is_weighed_by_parameters() -> None:
    plain = words.heldout_words(words.HELD_OUT, 2.0, 1.8, 0.1, 0.05, 0.05, (LAG,))
    assert plain == "held-out RMS 2.000 -> 1.800 um (10.0%; the bar is 5%)"
    weighed = words.heldout_words(words.MEDIAN_OVER_RUNS, 2.0, 1.8, 0.1, 0.0975, 0.05, (LAG,))
    assert weighed.endswith("(10.0%; the bar is 9.8%) (5% for each of its 2 parameters)")


def test_the_runs_a_term_harms_are_named_four_at_most() -> None:
    assert words.harm_words([], 0.1, 0.2) == ""
    one = words.harm_words(["day1"], 0.1, 0.2)
    assert one == "; 1 run worse by more than 10% and 0.2 um: day1"
    many = words.harm_words([f"day{n}" for n in range(1, 7)], 0.1, 0.2)
    assert many == "; 6 runs worse by more than 10% and 0.2 um: day1, day2, day3, day4, ..."
    # The guard's figure says whether such a term is refused or only named (it passes then)
    assert words.harm_guard_words(["day1"], 0.1, 0.2) == "1 run worse by more than 10% and 0.2 um: day1"
    assert words.harm_guard_words(["day1"], 0.1, 0.2, refuses=False).endswith(
        "day1 (named, not refused: Settings.run_harm_refuses is off)")
    assert words.harm_guard_words([], 0.1, 0.2, refuses=False) == "no run worse by more than 10% and 0.2 um"


def test_the_paired_test_counts_its_candidates() -> None:
    assert words.paired_test_words(0.012, 0.05, 0.05, 1).endswith("0.05 over 1 candidate)")
    assert words.paired_test_words(0.012, 0.025, 0.05, 2).endswith("0.05 over 2 candidates)")
    assert words.paired_test_words(0.012, 0.05, 0.05, 0).endswith("0.05 over 1 candidate)")


def test_what_a_machine_cannot_have_is_the_start_of_its_figure() -> None:
    """The search recognises a candidate held back only by its physics by this start (note_cannot_have)."""
    assert words.physical_words(True, "a negative time constant").startswith(words.CANNOT_HAVE)
    assert words.physical_words(False, "") == "parameters outside what a machine can have"
    assert words.physical_words(True, "") == "parameters a machine can have"
