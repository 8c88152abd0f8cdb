"""The problem: gauge samples over one run or several, each run centred on its own offset."""

from __future__ import annotations

import numpy as np
import pytest

from nckemu.errors import NckConfigError
from nckemu.thermal.discovery.problem import Problem
from nckemu.thermal.discovery.readings import prepare
from nckemu.thermal.discovery.settings import Settings
from nckemu.thermal.model.terms import Term, ThermalModel
from nckemu.thermal.recordings.recording import Recording


def _run(offset_um: float, seed: int, rows: int = 60) -> Recording:
    rng = np.random.default_rng(seed)
    t = np.arange(rows) * 60.0
    temperature = 20 + np.linspace(0, 3, rows)
    error = offset_um + 2 * (temperature - 20) + rng.normal(0, 0.1, rows)
    error[::10] = np.nan
    return Recording(f"<run{seed}>", t, {"temp_a_C": temperature}, None, {}, {"Z": error})


def _problem(per_run_offset: bool, runs: int = 3) -> Problem:
    model = ThermalModel("Z", [Term("offset", {"value_um": 0.0}),
                               Term("temperature", {"sensor": "a", "t_ref_C": 20.0, "coeff_um_per_K": 2.0})])
    prepared = [(f"run{i}", prepare(_run(10.0 * i, i), Settings())) for i in range(runs)]
    return Problem(prepared, "Z", model, per_run_offset=per_run_offset)


def test_each_run_is_centred_on_its_own_offset() -> None:
    problem = _problem(per_run_offset=True)
    assert [t.effect for t in problem.base_terms] == ["temperature"]  # the offset is the runs' own
    for group in range(3):
        assert abs(np.mean(problem.y[problem.groups == group])) < 1e-9
    column = problem.feature(problem.base_terms[0])
    assert abs(np.mean(column[problem.groups == 1])) < 1e-9
    # centred data give the slope an offset per run would
    slope = float(np.dot(column, problem.y) / np.dot(column, column))
    assert slope == pytest.approx(2.0, abs=0.05)
    assert len(problem.y) == 3 * 54 and problem.run_means(problem.raw_y)[2] > 15


def test_one_run_is_not_centred_and_set_aside_drops_samples() -> None:
    problem = _problem(per_run_offset=False, runs=1)
    assert np.array_equal(problem.y, problem.raw_y)
    version = problem.version
    drop = np.zeros(len(problem.y), dtype=bool)
    drop[[0, 5]] = True
    problem.set_aside(drop)
    assert len(problem.y) == 52 and problem.version == version + 1


def test_a_run_without_the_axis_is_refused() -> None:
    recording = _run(0.0, 1)
    recording.errors_um = {"X": recording.errors_um["Z"]}
    with pytest.raises(NckConfigError, match="err_Z_um"):
        Problem([("r", prepare(recording, Settings()))], "Z", None)
