"""Validation splitters: which samples are held out, and which fitted on, for each fold.

Like scikit-learn's ``model_selection`` splitters (``TimeSeriesSplit``, ``LeaveOneGroupOut``), a
splitter yields (train, test) index pairs and knows nothing of what is fitted. Thermal residuals are
strongly autocorrelated, so samples are never split at random: within one run the folds are
contiguous blocks of time (``Blocks``); with several runs of a machine each run is a group
(``LeaveOneRunOut``), and a model is judged on a run it was not fitted on.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

import numpy as np


class Splitter(Protocol):
    def split(self, count: int, groups: np.ndarray | None = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """(train indices, test indices) per fold, over ``count`` time-ordered samples."""
        ...


@dataclass(frozen=True)
class Blocks:
    """``folds`` contiguous blocks of time (at least 2, at most one per sample)."""

    folds: int = 5

    def split(self, count: int, groups: np.ndarray | None = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        folds = max(2, min(self.folds, count))
        edges = np.linspace(0, count, folds + 1).round().astype(int)
        everything = np.arange(count)
        for start, end in zip(edges[:-1], edges[1:], strict=True):
            yield np.concatenate((everything[:start], everything[end:])), everything[start:end]


@dataclass(frozen=True)
class LeaveOneRunOut:
    """Each run (``groups``: the run's number per sample) is held out once, fitted on the others."""

    def split(self, count: int, groups: np.ndarray | None = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        if groups is None or len(groups) != count:
            raise ValueError("LeaveOneRunOut needs the run of every sample")
        for group in np.unique(groups):
            yield np.flatnonzero(groups != group), np.flatnonzero(groups == group)


def held_out_masks(splitter: Splitter, count: int, groups: np.ndarray | None = None) -> list[np.ndarray]:
    """The held-out samples of each fold as boolean masks (what ``stats.cross_validate`` takes)."""
    masks = []
    for _train, test in splitter.split(count, groups):
        mask = np.zeros(count, dtype=bool)
        mask[test] = True
        masks.append(mask)
    return masks
