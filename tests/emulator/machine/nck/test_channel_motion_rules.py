"""What F means on the channel (issue 49), times checked by hand: F on the geometry axes with the rotary
axes within their own limits, FGROUP, rotary axes alone in degrees/min; G96 constant cutting speed with
LIMS on a lathe in diameter programming; a G33 thread and G331/G332 tapping at the spindle's speed. Each
block's time is read from the offline block table (``program run --blocks``)."""

from __future__ import annotations

import math

import pytest

from nckemu.catalogue.program_names import program_path
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import parse_machine
from nckemu.emulator.machine.nck.program_run import BlockRecord
from nckemu.emulator.machine.offline import run_offline

# A five-axis mill: X, Y, Z at 30 m/min and 2 m/s², B and C at 36 000 °/min and 10 (taken as 10 000 °/s²).
MILL = """
name = "five-axis test mill"
channels = 1
[[axis]]
number = 1
name = "X1"
travel_mm = [-2000.0, 2000.0]
[[axis]]
number = 2
name = "Y1"
travel_mm = [-2000.0, 2000.0]
[[axis]]
number = 3
name = "Z1"
travel_mm = [-2000.0, 2000.0]
[[axis]]
number = 4
name = "B1"
rotary = true
[[axis]]
number = 5
name = "C1"
rotary = true
[[axis]]
number = 6
name = "SP1"
rotary = true
spindle = true
[initial]
MD32000 = { 1 = 30000.0, 2 = 30000.0, 3 = 30000.0, 4 = 36000.0, 5 = 36000.0 }
MD32300 = { 1 = 2.0, 2 = 2.0, 3 = 2.0, 4 = 10.0, 5 = 10.0 }
"""

# A lathe: X (radius, the machine's own unit) and Z at 10 m/min and 1 m/s², a spindle up to 4000 rpm.
LATHE = """
name = "test lathe"
channels = 1
[[axis]]
number = 1
name = "X1"
travel_mm = [-10.0, 250.0]
[[axis]]
number = 2
name = "Z1"
travel_mm = [-600.0, 50.0]
[[axis]]
number = 3
name = "SP1"
rotary = true
spindle = true
[initial]
MD32000 = { 1 = 10000.0, 2 = 10000.0 }
MD32300 = { 1 = 1.0, 2 = 1.0 }
MD35100 = { 3 = 4000.0 }
[program]
spindle_accel_rev_s2 = 20.0
"""


def blocks_of(machine: str, text: str, feed_override_pct: float = 100.0) -> dict[str, BlockRecord]:
    """Run ``text`` offline; the block table by block number (the blocks that have one)."""
    emulator = Emulator(parse_machine(machine, "test.toml"), clock=SimulatedClock())
    emulator.cycle_s = 0.1
    emulator.nck.channels[1].state.feed_override_pct = feed_override_pct
    path = program_path("RULES.MPF")
    emulator.nck.programs.write(path, text.encode())
    records: list[BlockRecord] = []
    result = run_offline(emulator, path, on_block=records.append)
    assert result.outcome == "ended", result.alarms
    return {record.number: record for record in records if record.number}


def took_s(record: BlockRecord) -> float:
    return record.end_s - record.start_s


# ------------------------------------------------------------------ F on the geometry axes
def test_rotary_axes_keep_their_own_limits_under_f() -> None:
    # Z-300 X420 is 516.14 mm of path: 4.3 s at F7200 (120 mm/s). C and B turn 3600° each in the same
    # time, at most 600 °/s: that takes 6 s, so the path slows to 516.14/6 mm/s. The ramps: C carries
    # 3600/516.14 of the path, so the path may accelerate at 10 000 °/s² over that share: both half
    # ramps add v/a = 600/10000 s. By hand 6.06 s (the block took 42.7 s when the degrees counted as path).
    table = blocks_of(MILL, "R3=-300 R6=420\nN10 G01 G91 Z=R3 C-3600 B-3600 X=R6 F7200\nM30\n")
    assert took_s(table["N10"]) == pytest.approx(3600.0 / 600.0 + 600.0 / 10000.0, rel=1e-9)
    assert table["N10"].positions_mm["C"] == pytest.approx(-3600.0)


def test_geometry_axes_alone_are_not_slowed_and_fgroup_changes_the_path() -> None:
    # Without the rotary axes the same 516.14 mm take 4.3 s plus the ramps (X's share sets them):
    # 120 mm/s, accelerating at 2000 / (420/516.14) mm/s².
    length = math.hypot(300.0, 420.0)
    table = blocks_of(MILL, "N10 G01 G91 Z-300 X420 F7200\n"
                            "N20 FGROUP(X, Z, C, B)\n"
                            "N30 Z-300 C-3600 B-3600 X420\n"
                            "N40 FGROUP()\n"
                            "N50 G0 X0 Z0\n"
                            "N60 G1 G91 Z-300 C3600 B3600 X420\n"
                            "M30\n")
    accel = 2000.0 / (420.0 / length)
    assert took_s(table["N10"]) == pytest.approx(length / 120.0 + 120.0 / accel, rel=1e-9)
    # FGROUP with the rotary axes: F along X, Z, C and B together (the degrees count as path, as the
    # control does then): 5117 mm at 120 mm/s, the ramps set by C's share (10 000 over 3600/5117)
    full = math.sqrt(length ** 2 + 2 * 3600.0 ** 2)
    assert took_s(table["N30"]) == pytest.approx(full / 120.0 + 120.0 / (10000.0 / (3600.0 / full)), rel=1e-9)
    # FGROUP() is the geometry axes again: the rotary axes' own limits set the time
    assert took_s(table["N60"]) == pytest.approx(6.06, rel=1e-9)


def test_rotary_axes_alone_take_f_in_degrees_per_minute() -> None:
    # C90 at F3600 °/min: 60 °/s, 1.5 s, plus 60/10000 s of ramps
    table = blocks_of(MILL, "N10 G1 G91 C90 F3600\nN20 B45 C-45\nM30\n")
    assert took_s(table["N10"]) == pytest.approx(1.5 + 60.0 / 10000.0, rel=1e-9)
    # two rotary axes: F along their combined path, 63.64° at 60 °/s
    assert took_s(table["N20"]) == pytest.approx(math.hypot(45.0, 45.0) / 60.0 + 60.0 / (10000.0 * math.sqrt(2)),
                                                 rel=1e-9)


# ------------------------------------------------------------------ turning
FACING = """G18 G90 DIAMON
N10 G0 X100 Z0
N20 G96 S200 LIMS=3000 M3
N30 G4 F2
N40 G1 X0 F0.1
N50 G97
N60 G1 Z-10
M30
"""


def facing_by_hand_s(start_radius_mm: float, speed_m_min: float, limit_rpm: float, feed_mm_rev: float) -> float:
    """A facing cut to the centre at constant cutting speed: n = v/(2 pi r) until LIMS, then LIMS.

    Above the radius where n reaches LIMS, dr/dt = f n / 60 = f v 1000 / (60 2 pi r), so the time from R to
    r_lim is 60 2 pi (R² - r_lim²) / (2 f v 1000); from r_lim to 0 at LIMS it is r_lim / (f LIMS / 60)."""
    limit_radius = speed_m_min * 1000.0 / (2 * math.pi * limit_rpm)
    outer = 60.0 * 2 * math.pi * (start_radius_mm ** 2 - limit_radius ** 2) / (2 * feed_mm_rev * speed_m_min * 1000.0)
    return outer + limit_radius / (feed_mm_rev * limit_rpm / 60.0)


def test_g96_facing_from_x100_to_x0_with_lims() -> None:
    table = blocks_of(LATHE, FACING)
    # DIAMON: X100 is a radius of 50 mm; the machine's X goes to 50
    assert table["N10"].positions_mm["X"] == pytest.approx(50.0)
    # 22.50 s while the spindle speeds up from 637 rpm, 2.12 s at LIMS 3000 rpm: 24.62 s (it took 6003.8 s
    # when S200 was read as rpm and F0.1 as mm/min)
    expected = facing_by_hand_s(50.0, 200.0, 3000.0, 0.1)
    assert expected == pytest.approx(24.62, abs=0.01)
    assert took_s(table["N40"]) == pytest.approx(expected, rel=1e-4)
    assert table["N40"].spindle_rpm == pytest.approx(3000.0)          # at the centre: LIMS
    assert table["N40"].positions_mm["X"] == pytest.approx(0.0)
    # G97 keeps the speed the spindle has, feed per revolution: 10 mm at 0.1 mm x 3000 rpm = 5 mm/s
    assert took_s(table["N60"]) == pytest.approx(2.0 + 5.0 / 1000.0, rel=1e-9)


def test_g96_starts_where_the_tool_is_and_the_spindle_follows_x() -> None:
    table = blocks_of(LATHE, "G18 G90 DIAMON\nN10 G0 X100 Z0\nN20 G96 S200 LIMS=3000 M3\nN30 G4 F2\n"
                             "N40 G1 X10 F0.1\nM30\n")
    # at X100 (r 50) the spindle turns 200 000 / (2 pi 50) = 636.6 rpm (ramped up during the dwell)
    assert table["N30"].spindle_rpm == pytest.approx(200000.0 / (2 * math.pi * 50.0), rel=1e-6)
    # to X10 (r 5): LIMS from r 10.61 on, so the facing time less the last 5 mm at LIMS (1 s)
    assert took_s(table["N40"]) == pytest.approx(facing_by_hand_s(50.0, 200.0, 3000.0, 0.1) - 1.0, rel=1e-4)


def test_a_thread_runs_at_the_spindle_speed_and_ignores_the_feed_override() -> None:
    # S1000, pitch 1.5 mm: 1500 mm/min = 25 mm/s over 30 mm, 1.2 s plus 25/1000 s of ramps; the feed
    # override of 50 % does not act on a thread (it halves the G1 after it: 10 mm at 5 mm/s)
    text = "G18 G90 G95\nN10 G0 X20 Z5\nN20 S1000 M3\nN30 G4 F3\nN40 G33 Z-25 K1.5\nN50 G1 Z0 F0.2\nM30\n"
    table = blocks_of(LATHE, text, feed_override_pct=50.0)
    assert took_s(table["N40"]) == pytest.approx(30.0 / 25.0 + 25.0 / 1000.0, rel=1e-9)
    assert took_s(table["N50"]) == pytest.approx(25.0 / (0.2 * 1000 / 60 / 2) + (0.2 * 1000 / 60 / 2) / 1000.0,
                                                 rel=1e-9)


def test_tapping_g331_g332_at_the_programmed_speed() -> None:
    # G331 Z-20 K1 S600: 600 mm/min = 10 mm/s, 20 mm in 2 s plus 10/1000 s of ramps; G332 back the same
    text = "G18 G90\nN10 G0 X0 Z0\nN20 SPOS=0\nN30 G331 Z-20 K1 S600\nN40 G332 Z0 K1\nM30\n"
    table = blocks_of(LATHE, text)
    assert took_s(table["N30"]) == pytest.approx(2.0 + 0.01, rel=1e-9)
    assert took_s(table["N40"]) == pytest.approx(2.0 + 0.01, rel=1e-9)
    assert table["N40"].positions_mm["Z"] == pytest.approx(0.0)


# ------------------------------------------------------------------ helices and polar coordinates
def test_a_helix_with_turn_takes_its_turns_and_is_on_them_halfway() -> None:
    # From X20 Y0 about X0 Y0 back to X20 Y0 with two more turns (TURN=2): three turns of radius 20 while Z
    # goes down 10 mm: hypot(3 x 2 pi 20, 10) = 377.12 mm at F1200 (20 mm/s), plus the ramps (the plane
    # axes carry 376.99/377.12 of the path each: 2000 mm/s² over that share)
    text = "G17 G90 G0 X20 Y0 Z0\nN10 G3 X20 Y0 Z-10 I-20 J0 TURN=2 F1200\nM30\n"
    length = math.hypot(3 * 2 * math.pi * 20.0, 10.0)
    expected = length / 20.0 + 20.0 / (2000.0 / (3 * 2 * math.pi * 20.0 / length))
    table = blocks_of(MILL, text)
    assert took_s(table["N10"]) == pytest.approx(expected, rel=1e-9)
    # halfway in time (the ramps are symmetric): one and a half turns, on the far side, Z half way down
    emulator = Emulator(parse_machine(MILL, "test.toml"), clock=SimulatedClock())
    emulator.cycle_s = 0.1
    path = program_path("HELIX.MPF")
    emulator.nck.programs.write(path, text.encode())
    emulator.nck.axes.set_position(1, 20.0)         # where the G0 goes: it takes no time
    channel = emulator.nck.channels[1]
    channel.select(path)
    channel.start()
    emulator.step_machine(0.0)
    assert channel.state.block_number == "N10"
    start_s = channel.run.block_start_s
    emulator.clock.set(start_s + expected / 2)
    emulator.step_machine(start_s + expected / 2)
    positions = emulator.nck.axes.positions_mm
    assert (positions[1], positions[2], positions[3]) == pytest.approx((-20.0, 0.0, -5.0), abs=1e-6)


def test_polar_coordinates_pole_and_circle_about_it() -> None:
    # G111 puts the pole at X50 Y50; AP=0 RP=20 is X70 Y50; G3 AP=180 turns about the pole to X30 Y50:
    # a half circle of radius 20, 62.83 mm at 20 mm/s plus 20/2000 s of ramps
    table = blocks_of(MILL, "G17 G90 G0 X0 Y0 Z0\nN10 G111 X50 Y50\nN20 G0 AP=0 RP=20\n"
                            "N30 G3 AP=180 F1200\nN40 G110 X0 Y-10\nN50 G1 AP=270 RP=5\nM30\n")
    assert (table["N20"].positions_mm["X"], table["N20"].positions_mm["Y"]) == pytest.approx((70.0, 50.0))
    assert took_s(table["N10"]) == 0.0
    assert took_s(table["N30"]) == pytest.approx(math.pi * 20.0 / 20.0 + 20.0 / 2000.0, rel=1e-9)
    assert (table["N30"].positions_mm["X"], table["N30"].positions_mm["Y"]) == pytest.approx((30.0, 50.0))
    # G110: the pole relative to the last programmed point (X30 Y50): X30 Y40; AP=270 RP=5 is X30 Y35
    assert (table["N50"].positions_mm["X"], table["N50"].positions_mm["Y"]) == pytest.approx((30.0, 35.0))


# ------------------------------------------------------------------ tool radius compensation
MILL_WITH_TOOL = MILL + """
[tools]
cutting_edge_params = 25
[[tool]]
number = 1
ident = "END_MILL_10"
edges = [{ type = 120, length1_mm = 0.0, radius_mm = 5.0 }]
"""
SQUARE = """T1 D1 M6
G17 G90 G0 X0 Y0 Z0
N10 {side} G1 X10 Y10 F600
N20 G1 X50
N30 Y50
N40 X10
N50 Y10
N60 G40 G1 X0 Y0
M30
"""


def line_s(length_mm: float) -> float:
    """A line at F600 (10 mm/s) between two stops, X and Y at 2000 mm/s² (the diagonal's shares allow more)."""
    return length_mm / 10.0 + 10.0 / 2000.0


def test_g42_goes_round_the_outside_of_a_square_with_the_edge_radius() -> None:
    # The 40 mm square from X10 Y10, counter-clockwise, the tool (radius 5) right of it: outside. The
    # approach ends 5 mm below the first corner (X10 Y5), each side runs 5 mm outside, each outside corner is
    # a quarter circle of radius 5 about the corner (7.854 mm at 10 mm/s, its own ramps), the last side ends
    # at X5 Y10 and G40 retracts to X0 Y0.
    table = blocks_of(MILL_WITH_TOOL, SQUARE.format(side="G42"))
    corner_s = math.pi / 2 * 5.0 / 10.0 + 10.0 / 2000.0
    assert (table["N10"].positions_mm["X"], table["N10"].positions_mm["Y"]) == pytest.approx((10.0, 5.0))
    assert took_s(table["N10"]) == pytest.approx(math.hypot(10.0, 5.0) / 10.0 + 10.0 / (2000.0 / (10 / math.hypot(10, 5))),
                                                 rel=1e-9)
    for number, corner in (("N20", (55.0, 10.0)), ("N30", (50.0, 55.0)), ("N40", (5.0, 50.0))):
        assert took_s(table[number]) == pytest.approx(line_s(40.0) + corner_s, rel=1e-9), number
        assert (table[number].positions_mm["X"], table[number].positions_mm["Y"]) == pytest.approx(corner)
    assert took_s(table["N50"]) == pytest.approx(line_s(40.0), rel=1e-9)
    assert (table["N50"].positions_mm["X"], table["N50"].positions_mm["Y"]) == pytest.approx((5.0, 10.0))
    assert (table["N60"].positions_mm["X"], table["N60"].positions_mm["Y"]) == pytest.approx((0.0, 0.0))


def test_g41_cuts_the_inside_corners_of_the_square() -> None:
    # The tool left of the same contour: inside. Each side is 5 mm shorter at each inside corner.
    table = blocks_of(MILL_WITH_TOOL, SQUARE.format(side="G41"))
    ends = {"N10": (10.0, 15.0), "N20": (45.0, 15.0), "N30": (45.0, 45.0), "N40": (15.0, 45.0), "N50": (15.0, 10.0)}
    for number, end in ends.items():
        assert (table[number].positions_mm["X"], table[number].positions_mm["Y"]) == pytest.approx(end), number
    assert took_s(table["N20"]) == pytest.approx(line_s(35.0), rel=1e-9)
    assert took_s(table["N30"]) == pytest.approx(line_s(30.0), rel=1e-9)
    assert took_s(table["N50"]) == pytest.approx(line_s(35.0), rel=1e-9)


def test_g41_on_circles_offsets_their_radius() -> None:
    # A full circle of radius 20 about X30 Y30, counter-clockwise, the tool left: inside, radius 15
    text = ("T1 D1 M6\nG17 G90 G0 X0 Y0 Z0\nN10 G41 G1 X50 Y30 F600\nN20 G3 X50 Y30 I-20 J0\n"
            "N30 G40 G1 X60 Y30\nM30\n")
    table = blocks_of(MILL_WITH_TOOL, text)
    assert (table["N10"].positions_mm["X"], table["N10"].positions_mm["Y"]) == pytest.approx((45.0, 30.0))
    assert took_s(table["N20"]) == pytest.approx(2 * math.pi * 15.0 / 10.0 + 10.0 / 2000.0, rel=1e-9)


@pytest.mark.parametrize(("text", "number"), [
    # a circle of radius 3 with the tool's 5 mm on its inside
    ("T1 D1 M6\nG17 G90 G0 X0 Y0\nG41 G1 X10 Y0 F600\nG3 X4 Y0 CR=3\nG40 G1 X0 Y0\nM30\n", 10758),
    # an inside corner whose next side (2 mm) is shorter than the radius: the tool cannot get in
    ("T1 D1 M6\nG17 G90 G0 X0 Y0\nG41 G1 X10 Y10 F600\nX50\nY12\nX10\nG40 G1 X0 Y0\nM30\n", 10751),
])
def test_a_contour_that_cannot_be_offset_is_the_control_s_alarm(text: str, number: int) -> None:
    emulator = Emulator(parse_machine(MILL_WITH_TOOL, "test.toml"), clock=SimulatedClock())
    path = program_path("BAD.MPF")
    emulator.nck.programs.write(path, text.encode())
    result = run_offline(emulator, path)
    assert result.outcome == "alarm" and str(number) in result.alarms[0], result.alarms


@pytest.mark.parametrize(("machine", "text", "number"), [
    (LATHE, "G18 G90 G96 S200 M5\nG1 X10 F0.1\nM30\n", 14800),        # G96 feeds per revolution: M5 feeds nothing
    (LATHE, "G18 G90 S500 M3\nG33 Z-10\nM30\n", 12080),                # a thread without its pitch
    (LATHE, "G18 G90\nG331 Z-10 K1\nM30\n", 14800),                    # tapping without S
    (MILL, "G1 F100 RP=-5\nM30\n", 12080),                             # a negative polar radius
    (MILL, "FGROUP(Q)\nM30\n", 12550),                                 # no axis Q
    (MILL, "G17 G0 X0 Y0\nG3 X0 Y0 I10 TURN=-1 F100\nM30\n", 12080),   # negative turns
])
def test_bad_turning_polar_and_feed_group_words_are_alarms(machine: str, text: str, number: int) -> None:
    emulator = Emulator(parse_machine(machine, "test.toml"), clock=SimulatedClock())
    path = program_path("BAD.MPF")
    emulator.nck.programs.write(path, text.encode())
    result = run_offline(emulator, path)
    assert result.outcome == "alarm" and f"alarm {number}" in result.alarms[0], result.alarms
