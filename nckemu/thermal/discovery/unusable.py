"""What a recording cannot give discovery, said once in the recording's own words: an error column
that never moves (nothing to explain), a sensor that never changes (it can explain nothing), a time
constant as long as the recording lets one be (the recording is too short to tell a longer one).

A constant error column would otherwise be "explained" by every candidate at once: a zero residual
gives an infinite t-value and "nothing missing", which says nothing about the machine.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from nckemu.thermal.recordings.recording import Recording

# Below this spread a column is one value (µm for an error column, K for a sensor): a logger's
# resolution is coarser.
STILL_UM = 1e-9
STILL_K = 1e-6
# The lag grids stop at a third of the recording (library.best_time_constant): a time constant this
# close to that edge may be longer still.
EDGE_SHARE = 0.8


def _hours(seconds: float) -> str:
    return f"{seconds / 3600:.2f} h" if seconds >= 3600 else f"{seconds / 60:.0f} min"


def still_error(recording: Recording, axis: str, values: np.ndarray) -> str | None:
    """One line when the gauge's samples of ``axis`` are one value (a machine without thermal error
    keys writes all zeros), else None."""
    finite = values[np.isfinite(values)]
    if len(finite) == 0 or float(np.ptp(finite)) > STILL_UM:
        return None
    return (f"err_{axis}_um reads {float(finite[0]):g} um on all {len(finite)} of its samples: there is no error "
            f"to explain, so no term was searched (a program run on a machine without thermal_um_per_K writes 0)")


def still_sensors(recordings: Iterable[Recording]) -> list[str]:
    """One line per temperature that never changes within a recording: it can explain nothing."""
    lines = []
    for recording in recordings:
        for name, values in recording.temperatures_C.items():
            finite = values[np.isfinite(values)]
            if len(finite) > 1 and float(np.ptp(finite)) <= STILL_K:
                where = f"{recording.name}: " if recording.name else ""
                lines.append(f"{where}{name} reads {float(finite[0]):g} C on every sample: a sensor "
                             f"that never changes explains nothing here")
    return lines


def short_time_constants(parameters: list[tuple[str, dict[str, object]]], duration_s: float) -> list[str]:
    """One line per named time constant at the edge of what a recording of ``duration_s`` can tell."""
    lines = []
    if duration_s <= 0:
        return lines
    longest_s = duration_s / 3
    for label, values in parameters:
        for key, value in values.items():
            if not (key.startswith("tau") and key.endswith("_s")) or not isinstance(value, float | int):
                continue
            if float(value) >= EDGE_SHARE * longest_s:
                lines.append(f"{label}: {key} {_hours(float(value))} is near the longest the recording's "
                             f"{_hours(duration_s)} can tell ({_hours(longest_s)}, a third of it): the true "
                             f"time constant may be longer; a longer recording would tell")
    return lines
