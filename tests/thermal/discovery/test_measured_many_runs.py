"""The public measured recordings cut into ten runs or more (issue 42, second part): discovery under
the runs' paired test (no t-test, a 5 % bar, up to 6 terms, withdrawal) is never worse on held-out
runs, median or worst, than the admission before it, on every channel tried. Skips without
``../shared``. Slow: 12 discoveries of 14-26 runs."""

from __future__ import annotations

import pytest

from nckemu.thermal.discovery.discover import discover_runs
from nckemu.thermal.discovery.settings import Settings

from .measured_runs import measured_runs

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]
BEFORE = Settings(runs_replace_t_test=False, runs_min_improvement=0.10, max_effects=4)


@pytest.mark.parametrize(("path", "axis", "hours"), [
    ("fl_thermal/recording.csv", "ch1", 3.5), ("fl_thermal/recording.csv", "ch3", 3.5),
    ("fl_thermal/recording.csv", "ch5", 3.5), ("sjtu_spindle/recording.csv", "dL", 6.0),
    ("sjtu_spindle/recording.csv", "dL", 4.0), ("sjtu_spindle/recording.csv", "dL", 3.0)])
def test_never_worse_than_the_admission_before(path: str, axis: str, hours: float) -> None:
    runs = measured_runs(path, hours)
    assert len(runs) >= 10
    now = discover_runs(runs, axis, None)
    before = discover_runs(runs, axis, None, BEFORE)
    print(f"{path} {axis} {len(runs)} runs: median {now.heldout_rms_before_um:.3f} -> {now.heldout_rms_after_um:.3f} "
          f"(before: {before.heldout_rms_after_um:.3f}), worst {now.run_figures['worst_after_um']:.3f} "
          f"(before: {before.run_figures['worst_after_um']:.3f}), {len(now.missing_physics)} terms")
    assert 1 <= len(now.missing_physics) <= 6
    assert now.heldout_rms_after_um <= before.heldout_rms_after_um + 1e-9
    assert now.run_figures["worst_after_um"] <= before.run_figures["worst_after_um"] + 1e-9
