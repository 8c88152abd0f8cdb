"""Splitters yield (train, test) index pairs: blocks of time in one run, runs as groups."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.thermal import stats
from nckemu.thermal.discovery.splitters import Blocks, LeaveOneRunOut, held_out_masks


@given(st.integers(2, 500), st.integers(1, 12))
def test_blocks_partition_the_samples_in_time_order(count: int, folds: int) -> None:
    pairs = list(Blocks(folds).split(count))
    tests = np.concatenate([test for _train, test in pairs])
    assert np.array_equal(tests, np.arange(count))  # every sample held out once, in order
    for train, test in pairs:
        assert len(np.intersect1d(train, test)) == 0 and len(train) + len(test) == count
        assert np.all(np.diff(test) == 1)  # contiguous


@given(st.integers(2, 300), st.integers(2, 9))
def test_blocks_are_the_blocked_folds_of_stats(count: int, folds: int) -> None:
    masks = held_out_masks(Blocks(folds), count)
    assert all(np.array_equal(a, b) for a, b in zip(masks, stats.blocked_folds(count, folds), strict=True))


@given(st.lists(st.integers(0, 4), min_size=2, max_size=200))
def test_leave_one_run_out_holds_out_each_run_once(groups_list: list[int]) -> None:
    groups = np.sort(np.asarray(groups_list))
    pairs = list(LeaveOneRunOut().split(len(groups), groups))
    assert len(pairs) == len(np.unique(groups))
    for (train, test), group in zip(pairs, np.unique(groups), strict=True):
        assert np.all(groups[test] == group) and np.all(groups[train] != group)


def test_leave_one_run_out_needs_the_groups() -> None:
    with pytest.raises(ValueError, match="run of every sample"):
        list(LeaveOneRunOut().split(5))
