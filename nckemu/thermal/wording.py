"""What a discovery against a program's ``sim_`` column says, in the compensation engineer's words:
what the program compensated, the residual, where it falls short, what physics it leaves out."""

from __future__ import annotations

from typing import Any

import numpy as np

from . import stats
from .discover import Discovery
from .terms import EFFECTS


def _parameters(parameters: dict[str, Any]) -> str:
    return ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in parameters.items())


def program_findings(discovery: Discovery, law: str | None = None) -> list[tuple[str, str]]:
    """Four (heading, sentence) pairs for a discovery whose baseline is the program's compensation."""
    series = discovery.series
    measured, compensated = series["measured_um"], series["baseline_um"]
    error_rms = stats.rms(measured)
    residual_rms = stats.rms(measured - compensated)
    share = 100.0 * (1.0 - residual_rms / error_rms) if error_rms > 0 else 0.0
    what = (f"The program's compensation (sim_{discovery.axis}_um) ran from {float(np.min(compensated)):.2f} to "
            f"{float(np.max(compensated)):.2f} um over the {discovery.samples} measured samples; it takes the "
            f"recorded error's RMS from {error_rms:.3f} um to {residual_rms:.3f} um ({share:.0f} % removed).")
    if law:
        what += f" Read back from its output, its law is {law}."
    residual = (f"Left after compensation (err - sim): RMS {discovery.baseline_rms_um:.3f} um; with the best single "
                f"factor on the program's output {discovery.recalibrated_rms_um:.3f} um; with the missing physics "
                f"added, held-out {discovery.heldout_rms_after_um:.3f} um.")
    if discovery.mismatch:
        short = "It falls short " + "; ".join(
            f"from {w['t_start_s'] / 3600:.2f} h to {w['t_end_s'] / 3600:.2f} h ({w['why']})" for w in discovery.mismatch)
        short += "."
    else:
        short = "The residual has no structured window: it does not fall short anywhere the data can show."
    if discovery.missing_physics:
        physics = "It leaves out: " + "; ".join(
            f"{m['effect']} ({EFFECTS[m['effect']].description}: {_parameters(m['parameters'])})"
            for m in discovery.missing_physics) + "."
    else:
        physics = "It leaves out no physics the recording can show."
    return [("What the program compensated", what), ("The residual", residual),
            ("Where it falls short", short), ("What physics it leaves out", physics)]


