"""Issue 50, item 4: discovery says what a recording cannot give it, in the recording's words, and
never reports a still error column as "t = inf ... nothing missing"."""

from __future__ import annotations

import numpy as np

from nckemu.cli import main
from nckemu.thermal.discovery.discover import discover
from nckemu.thermal.discovery.unusable import short_time_constants
from nckemu.thermal.model.terms import Term, ThermalModel
from nckemu.thermal.recordings.recording import Recording, write_recording

OFFSET = ThermalModel("Z", [Term("offset", {"value_um": 0.0})], "<constant offset>")


def _recording(error_um: np.ndarray, hours: float = 6.0) -> Recording:
    t_s = np.arange(0.0, hours * 3600, 60.0)
    rpm = np.where((t_s // 3600) % 2 == 1, 6000.0, 0.0)
    spindle_C = 20.0 + 5.0 * np.convolve(rpm / 6000.0, np.ones(30) / 30, mode="full")[:len(t_s)]
    return Recording("<still>", t_s, {"temp_spindle_C": spindle_C, "temp_cabinet_C": np.full(len(t_s), 21.5)},
                     spindle_rpm=rpm, errors_um={"Z": error_um(spindle_C) if callable(error_um) else error_um})


def test_a_still_error_column_is_said_and_nothing_is_searched(tmp_path, capsys):
    recording = _recording(np.zeros(360))
    result = discover(recording, axis="Z", model=OFFSET)
    assert result.missing_physics == [] and result.closest == []
    assert result.cannot_use[0].startswith("err_Z_um reads 0 um on all 360 of its samples")
    assert any("temp_cabinet_C reads 21.5 C on every sample" in line for line in result.cannot_use)
    path = tmp_path / "sim.csv"
    write_recording(path, recording)
    assert main(["discover", str(path), "--axis", "Z"]) == 0
    out = capsys.readouterr().out
    assert "t = inf" not in out and "nothing missing" not in out
    assert "cannot use: err_Z_um reads 0 um" in out


def test_a_still_sensor_is_said_beside_what_is_found():
    result = discover(_recording(lambda spindle_C: 3.0 * (spindle_C - 20.0)), axis="Z", model=OFFSET)
    assert result.missing_physics, "the spindle sensor explains the error"
    assert [line for line in result.cannot_use if "temp_cabinet_C" in line]
    assert not [line for line in result.cannot_use if "temp_spindle_C reads" in line]


def test_a_time_constant_at_the_edge_of_the_recording_is_said():
    lines = short_time_constants([("thermal_lag(spindle)", {"tau_s": 7000.0, "sensor": "spindle"})], 6 * 3600.0)
    assert lines == ["thermal_lag(spindle): tau_s 1.94 h is near the longest the recording's 6.00 h can tell "
                     "(2.00 h, a third of it): the true time constant may be longer; a longer recording would tell"]
    assert short_time_constants([("thermal_lag(spindle)", {"tau_s": 1800.0})], 6 * 3600.0) == []
