"""The machine file's drives ([drives], [[drive]]) and the 828D edge parameters: defaults, and bad input
named by file, line and field."""

from __future__ import annotations

import pytest

from nckemu.emulator.machine.machine_file import FEED_DRIVE, SPINDLE_DRIVE, parse_machine
from nckemu.errors import NckConfigError

AXES = """
[[axis]]
number = 1
name = "X1"

[[axis]]
number = 5
name = "SP1"
spindle = true
rotary = true

[[sensor]]
name = "motor"
"""


def test_without_drive_rows_each_axis_has_its_drive() -> None:
    machine = parse_machine(AXES, "m.toml")
    assert [(d.number, d.axis) for d in machine.drives] == [(1, 1), (5, 5)]
    assert machine.drives[0].rated_power_kW == FEED_DRIVE["rated_power_kW"]
    assert machine.drives[1].magnetizing_current_A == SPINDLE_DRIVE["magnetizing_current_A"]
    assert machine.drive_settings.dc_link_V == 600.0


def test_drive_rows_and_settings() -> None:
    machine = parse_machine(AXES + """
[drives]
dc_link_V = 560.0
unmeasured_C = -200.0

[[drive]]
number = 1
axis = "SP1"
motor_sensor = "motor"
rated_power_kW = 9
""", "m.toml")
    (drive,) = machine.drives
    assert (drive.number, drive.axis, drive.motor_sensor, drive.rated_power_kW) == (1, 5, "motor", 9.0)
    assert drive.speed_load_pct == SPINDLE_DRIVE["speed_load_pct"]   # a spindle's defaults
    assert machine.drive_settings.dc_link_V == 560.0


@pytest.mark.parametrize(("extra", "field"), [
    ("[[drive]]\nnumber = 1\naxis = \"Y9\"\n", "drive[0].axis"),
    ("[[drive]]\nnumber = 1\nmotor_sensor = \"bed\"\n", "drive[0].motor_sensor"),
    ("[[drive]]\nnumber = 32\n", "drive[0].number"),
    ("[[drive]]\nnumber = 1\n\n[[drive]]\nnumber = 1\n", "drive[1].number"),
    ("[[drive]]\nnumber = 1\nrated_power = 3.0\n", "drive[0].rated_power"),
    ("[[drive]]\nnumber = 1\nrated_current_A = 0\n", "drive[0].rated_current_A"),
    ("[drives]\nefficiency = 1.2\n", "drives.efficiency"),
    ("[drives]\ndc_link = 600\n", "drives.dc_link"),
    ("[tools]\ncutting_edge_params = 25\n\n[[tool]]\nnumber = 1\nedges = [{ teeth = 4 }]\n", "tool[0].edges[0].teeth"),
    ("[tools]\nori_length_components = [1, 1, 2]\n", "tools.ori_length_components"),
])
def test_bad_input_names_the_field(extra: str, field: str) -> None:
    with pytest.raises(NckConfigError) as caught:
        parse_machine(AXES + extra, "m.toml")
    assert caught.value.field == field and "m.toml" in str(caught.value)
