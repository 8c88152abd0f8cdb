"""Discoveries that several thermal tests read, computed once per test run."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from nckemu.thermal.discovery.discover import Discovery, discover
from nckemu.thermal.model.terms import parse_model
from nckemu.thermal.recordings.recording import load_recording

# FL_THERMAL's ch3 against a hand model (offset, t5 at -2 um/K), every 4th reading
FL_THERMAL_CH3_MODEL = ('axis = "ch3"\n[[term]]\neffect = "offset"\nvalue_um = 0.0\n[[term]]\n'
                        'effect = "temperature"\nsensor = "t5"\nt_ref_C = 30.0\ncoeff_um_per_K = -2.0\n')


@pytest.fixture
def fl_thermal_ch3_discovery(shared_dir: Path, once_per_run: Callable[[str, Callable[[], Any]], Any]) -> Discovery:
    """The same discovery two tests judged apart (about 15 s each time): once per run, read only."""
    def produce() -> Discovery:
        recording = load_recording(shared_dir / "data" / "fl_thermal" / "recording.csv")
        recording = recording.slice(np.arange(len(recording.t_s)) % 4 == 0)
        return discover(recording, model=parse_model(FL_THERMAL_CH3_MODEL))

    result: Discovery = once_per_run("fl_thermal_ch3_discovery", produce)
    return result
