"""Issue 50: the twin heats through a machine file's fitted responses ([[sensor.response]]): checked
where the file is read, stepped by the emulator's cycle as the fit's math says, shown by machine show;
the older keys keep working."""

from __future__ import annotations

import numpy as np
import pytest

from nckemu.cli import main
from nckemu.emulator.machine.machine_file import parse_machine
from nckemu.errors import NckConfigError
from nckemu.heat_response import SPINDLE, simulate

AXES = """
name = "fitted mill"
[[axis]]
number = 1
name = "X1"
[[axis]]
number = 2
name = "SP1"
rotary = true
spindle = true
"""

SENSORS = """
[[sensor]]
name = "room"
temperature_C = 21.0
heat_spindle_K_per_krpm = 0.0
heat_axes_K_per_m_min = 0.0
[[sensor]]
name = "bearing"
temperature_C = 22.0
[[sensor.response]]
name = "spindle"
input = "spindle_rpm"
K = 0.25
power = 1.6
tau_s = 1200.0
[[sensor.response]]
name = "ambient"
input = "sensor"
sensor = "room"
from_C = 21.0
K = 0.8
tau_s = 3600.0
[[sensor]]
name = "frame"
temperature_C = 20.5
[[sensor.response]]
name = "neighbour"
input = "sensor"
sensor = "bearing"
from_C = 22.0
K = 0.4
tau_s = 2400.0
[[sensor]]
name = "old"
heat_spindle_K_per_krpm = 1.0
heat_time_constant_s = 600.0
"""


def test_a_program_heats_the_sensors_through_their_fitted_responses(tmp_path, capsys):
    """`program run --machine fitted.toml --out`: each fitted sensor as heat_response.simulate steps it
    over the run's own spindle speed (the emulator holds a cycle's inputs over the next cycle: 1 s of
    lag against time constants of minutes); the older keys still heat the sensor without a response."""
    program = tmp_path / "WARM.MPF"
    program.write_text("N10 S6000 M3\nN20 G4 F1800\nN30 M5\nN40 G4 F1800\nN50 M30\n")
    machine = tmp_path / "fitted.toml"
    machine.write_text(AXES + SENSORS)
    out = tmp_path / "sim.csv"
    assert main(["program", "run", str(program), "--machine", str(machine), "--out", str(out), "--sample", "10"]) == 0
    capsys.readouterr()
    table = np.genfromtxt(out, delimiter=",", names=True)
    t_s, rpm = table["t_s"], table["spindle_rpm"]
    twin = simulate(t_s, {SPINDLE: rpm}, {"room": 21.0, "bearing": 22.0, "frame": 20.5},
                    {s.name: s.response for s in parse_machine(AXES + SENSORS).sensors if s.response})
    assert float(np.max(table["temp_bearing_C"])) > 22.0 + 0.8 * 0.25 * 6.0 ** 1.6 * (1 - np.exp(-1.5))
    np.testing.assert_allclose(table["temp_bearing_C"], twin["bearing"], atol=0.05)
    np.testing.assert_allclose(table["temp_frame_C"], twin["frame"], atol=0.05)
    assert table["temp_room_C"][-1] == pytest.approx(21.0)
    assert table["temp_old_C"].max() > 20.0 + 5.0   # 1 K per krpm towards 6 K with tau 600 s


def test_parse_refuses_a_bad_response_naming_the_field():
    with pytest.raises(NckConfigError, match="unknown key 'gain'") as caught:
        parse_machine(AXES + SENSORS.replace("K = 0.25", "gain = 0.25"), "bad.toml")
    assert "sensor[1].response[0].gain" in str(caught.value)
    with pytest.raises(NckConfigError, match="no \\[\\[sensor\\]\\] named 'nowhere'"):
        parse_machine(AXES + SENSORS.replace('sensor = "bearing"', 'sensor = "nowhere"'), "bad.toml")
    with pytest.raises(NckConfigError, match="expected a power"):
        parse_machine(AXES + SENSORS.replace("power = 1.6", "power = -1.0"), "bad.toml")
    with pytest.raises(NckConfigError, match="expected a number"):
        parse_machine(AXES + SENSORS.replace("K = 0.25", 'K = "hot"'), "bad.toml")


def test_machine_show_lists_the_heat_of_every_sensor(tmp_path, capsys):
    path = tmp_path / "fitted.toml"
    path.write_text(AXES + SENSORS)
    assert main(["machine", "show", "--machine", str(path)]) == 0
    out = capsys.readouterr().out
    assert "heat: spindle +0.25 K per krpm^1.60, tau 20 min; ambient room 0.8 K/K, tau 1.00 h" in out
    assert "heat: neighbour bearing 0.4 K/K, tau 40 min" in out
    assert "heat: 1 K per 1000 rpm of the spindle + 0.2 K per m/min of path speed, tau 600 s" in out


def test_the_built_in_bed_warms_by_a_fraction_of_a_kelvin_and_md35100_is_said(tmp_path, capsys):
    """Issue 50's warm-up: 15 min each at 3000, 6000, 9000 and 12000 rpm on the built-in machine. The bed
    rose 9.7 K before (a spindle bearing's rise); 12000 rpm was held at 10000 without a word."""
    program = tmp_path / "WARM1H.MPF"
    program.write_text("N10 S3000 M3\nN20 G4 F900\nN30 S6000\nN40 G4 F900\nN50 S9000\nN60 G4 F900\n"
                       "N70 S12000\nN80 G4 F900\nN90 M5\nN100 M30\n")
    out = tmp_path / "sim.csv"
    assert main(["program", "run", str(program), "--out", str(out), "--sample", "60"]) == 0
    text = capsys.readouterr().out
    assert "note: S12000 in N70 held at 10000 rpm by MD35100 SPIND_VELO_LIMIT of spindle 1" in text
    bed = np.genfromtxt(out, delimiter=",", names=True)["temp_bed_C"]
    assert 0.02 < bed[-1] - 20.0 < 0.5
    assert main(["program", "run", str(program), "--json"]) == 0
    assert "MD35100" in capsys.readouterr().out.splitlines()[-1]
