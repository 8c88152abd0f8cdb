"""Admission over several runs (issue 42): the runs' held-out errors as paired samples, not a head count."""

from __future__ import annotations

import numpy as np

from nckemu.thermal import stats
from nckemu.thermal.discovery.admission import runs_improve

LEVEL = 0.05 / 4  # runs_alpha over four candidates reaching the test
SHARE = 0.8       # min_fold_share: the head count, where the runs are too few for the test


def test_most_runs_a_little_and_a_few_a_lot_pass_though_a_head_count_refuses() -> None:
    # 30 runs: 10 light runs a little worse (+2 %), 20 heavy runs much better (-40 % mean square)
    before = np.concatenate([np.full(10, 4.0), np.full(20, 36.0)]) * np.linspace(1.0, 1.1, 30)
    after = before * np.concatenate([np.full(10, 1.02), np.full(20, 0.6)])
    assert int(np.sum(after < before)) == 20  # 67 %: the old rule (80 % of runs) refused it
    assert stats.paired_improvement_p(before, after) < 1e-3
    assert runs_improve(before, after, LEVEL, SHARE)


def test_one_run_a_lot_and_many_worse_does_not_pass() -> None:
    before = np.full(30, 9.0) * np.linspace(1.0, 1.2, 30)
    after = before * 1.03
    after[0] = before[0] * 0.05  # one run almost perfect
    assert stats.paired_improvement_p(before, after) > 0.5
    assert not runs_improve(before, after, LEVEL, SHARE)


def test_half_better_half_worse_by_the_same_amounts_is_no_evidence() -> None:
    before = np.full(20, 10.0)
    after = before + np.tile([-1.0, 1.0], 10) * np.repeat(np.arange(1, 11), 2)
    assert not runs_improve(before, after, LEVEL, SHARE)


def test_a_few_days_the_share_of_runs_decides() -> None:
    before = np.array([4.0, 5.0, 6.0])
    assert runs_improve(before, before * 0.9, LEVEL, SHARE)  # 0.5^3 > level: all three improve
    worse_one = before * np.array([0.5, 0.5, 1.01])
    assert not runs_improve(before, worse_one, LEVEL, SHARE)  # 2 of 3 is below 80 %
    six = np.arange(1.0, 7.0)
    assert runs_improve(six, six * np.array([0.5, 0.5, 0.5, 0.5, 0.5, 1.01]), LEVEL, SHARE)  # 5 of 6


def test_from_ten_runs_the_test_decides() -> None:
    before = np.arange(1.0, 11.0)
    eight_of_ten = before * np.array([0.5] * 8 + [2.0, 2.0])
    assert runs_improve(before, eight_of_ten, LEVEL, SHARE, min_runs=11)  # the head count: 80 %
    assert not runs_improve(before, eight_of_ten, LEVEL, SHARE)  # the two worse runs lose the most


def test_unchanged_runs_are_no_evidence() -> None:
    before = np.full(12, 3.0)
    assert stats.paired_improvement_p(before, before) == 1.0
    assert not runs_improve(before, before, LEVEL, SHARE)


def test_the_duty_mix_days_are_light_then_heavy_and_the_null_shares_their_inputs() -> None:
    from nckemu.thermal.synthetic.scenarios import make_duty_mix_family

    family = make_duty_mix_family("duty_mix_days", 3, runs=12)
    null = make_duty_mix_family("null_duty_mix_days", 3, runs=12)
    assert family.truth.kinds == ("light",) * 10 + ("heavy",) * 2 and family.truth.effect == "temperature"
    assert null.truth.effect is None
    light, heavy = family.runs[0], family.runs[-1]
    assert np.ptp(heavy.sensor("rear")) > 2 * np.ptp(light.sensor("rear"))
    np.testing.assert_array_equal(family.runs[5].sensor("rear"), null.runs[5].sensor("rear"))
    # the concealed term is the only difference between the families
    assert float(np.ptp(heavy.errors_um["Z"] - null.runs[-1].errors_um["Z"])) > 10.0
