"""The examples run as a user would run them, and do what they say."""

from __future__ import annotations

import pytest

from examples.fc70_port import compensation_mm, run


def test_fc70_port_follows_the_seed_example() -> None:
    rows = run(minutes=120, verbose=False)
    for minute, temperature_C, expected_mm in ((0, 30.0, 0.0), (60, 40.0, 0.3), (120, 50.0, 0.6)):
        assert rows[minute][0] == pytest.approx(temperature_C, abs=0.01)  # PIW 420 quantization
        assert rows[minute][2] == pytest.approx(expected_mm, abs=2e-3)
    for temperature, put_mm, applied_mm in rows:
        assert put_mm == pytest.approx(compensation_mm(temperature))
        assert applied_mm == pytest.approx(put_mm, abs=1e-6)  # reached within the minute
