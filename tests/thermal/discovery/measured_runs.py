"""The public measured recordings of ../shared cut into runs of equal length, as the tests of
discovery over many runs use them (named part01, part02, ... in time order)."""

from __future__ import annotations

import numpy as np
import pytest

from nckemu.thermal.recordings.recording import Recording, load_recording

from ...conftest import SHARED


def measured_runs(path: str, hours: float) -> list[Recording]:
    """``../shared/data/<path>`` cut into runs of ``hours`` (a last run of 20 samples or fewer is
    left out); skips the test when ../shared is not beside the repository."""
    source = SHARED / "data" / path
    if not source.exists():
        pytest.skip("../shared is not beside the repository")
    recording = load_recording(source)
    t = recording.t_s - recording.t_s[0]
    parts = []
    for index, start in enumerate(np.arange(0.0, t[-1], hours * 3600.0)):
        inside = (t >= start) & (t < start + hours * 3600.0)
        if inside.sum() > 20:
            parts.append(recording.slice(inside, name=f"part{index + 1:02d}"))
    return parts
