"""The channel runs part programs on the emulator's clock (issue 41): the planner's time model checked
by hand, the channel's commands and refusals, the PLC's DB21/DB11 signals, bad programs as alarms."""

from __future__ import annotations

import math

import pytest

from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import parse_machine
from nckemu.emulator.machine.nck.channel import (
    AC_RUNNING,
    AC_STOPPED,
    CHAN_ACTIVE,
    CHAN_INTERRUPTED,
    CHAN_RESET,
    MODE_AUTOMATIC,
    MODE_JOG,
    PROG_ABORTED,
    PROG_INTERRUPTED,
    PROG_RUNNING,
    PROG_STOPPED,
    Channel,
)
from nckemu.emulator.machine.offline import run_offline
from nckemu.emulator.machine.program.motions import Arc, Dwell, Move
from nckemu.emulator.machine.program.planner import AxisLimits, MotionLimits, Overrides, Planner, ramp_time_s
from nckemu.errors import NckNoSuchFile, NckPiStateError
from nckemu.protocol.addresses import S7Area

MACHINE = """
name = "test mill"
[[axis]]
number = 1
name = "X1"
travel_mm = [-1000.0, 1000.0]
[[axis]]
number = 2
name = "Y1"
travel_mm = [-1000.0, 1000.0]
[[axis]]
number = 3
name = "Z1"
travel_mm = [-500.0, 500.0]
[[axis]]
number = 4
name = "SP1"
rotary = true
spindle = true
[[sensor]]
name = "spindle"
temperature_C = 20.0
plc_input = "PIW256"
heat_spindle_K_per_krpm = 2.0
heat_time_constant_s = 100.0
[initial]
MD32000 = { 1 = 6000.0, 2 = 6000.0, 3 = 3000.0 }
MD32300 = { 1 = 1.0, 2 = 1.0, 3 = 0.5 }
[program]
spindle_accel_rev_s2 = 20.0
"""

V_XY, A_XY = 100.0, 1000.0        # mm/s, mm/s² (6000 mm/min, 1 m/s²)
V_Z, A_Z = 50.0, 500.0


def emulator(cycle_s: float = 0.1, machine: str = MACHINE) -> tuple[Emulator, SimulatedClock]:
    clock = SimulatedClock()
    emu = Emulator(parse_machine(machine, "test.toml"), clock=clock)
    emu.cycle_s = cycle_s
    return emu, clock


def run(emu: Emulator, clock: SimulatedClock, until_s: float, cycle_s: float | None = None) -> None:
    step = cycle_s or emu.cycle_s
    while clock.now_s() + step <= until_s + 1e-9:
        clock.advance(step)
        emu.step_machine(clock.now_s())


def store(emu: Emulator, name: str, text: str) -> str:
    from nckemu.catalogue.program_names import program_path

    path = program_path(name)
    emu.nck.programs.write(path, text.encode())
    return path


def started(emu: Emulator, name: str, text: str) -> tuple[Channel, list[str]]:
    """Store the program, select it in channel 1 and start it; the list collects the channel's changes."""
    channel = emu.nck.channels[1]
    changes: list[str] = []
    channel.on_change.append(changes.append)
    channel.select(store(emu, name, text))
    channel.start()
    return channel, changes


# ------------------------------------------------------------------ the planner, by hand
def test_trapezoid_and_triangle_by_hand() -> None:
    # 100 mm at 100 mm/s, 1000 mm/s²: 1 s cruising + 2 half ramps of 0.1 s
    assert ramp_time_s(100.0, 100.0, 1000.0, 2) == pytest.approx(1.1)
    # 4 mm never reaches 100 mm/s: accelerate 2 mm, decelerate 2 mm, each sqrt(2*2/1000) s
    assert ramp_time_s(4.0, 100.0, 1000.0, 2) == pytest.approx(2 * math.sqrt(0.004))
    assert ramp_time_s(100.0, 100.0, 1000.0, 0) == pytest.approx(1.0)


def test_rapid_the_slowest_axis_sets_the_time_and_the_override_scales_it() -> None:
    planner = Planner(MotionLimits({"X": AxisLimits(6000.0, 1.0), "Z": AxisLimits(3000.0, 0.5)}))
    timed = planner.move({"X": 0.0, "Z": 0.0}, Move({"X": 100.0, "Z": 100.0}), Overrides(), 0.0)
    assert timed.duration_s == pytest.approx(100.0 / V_Z + V_Z / A_Z)       # Z: 2.0 + 0.1
    half = planner.move({"X": 0.0}, Move({"X": 100.0}), Overrides(rapid_pct=50.0), 0.0)
    assert half.duration_s == pytest.approx(100.0 / 50.0 + 50.0 / A_XY)


def test_feed_path_limited_by_its_axes_and_overridden() -> None:
    planner = Planner(MotionLimits({"X": AxisLimits(6000.0, 1.0), "Y": AxisLimits(6000.0, 1.0)}))
    slow = planner.move({"X": 0.0, "Y": 0.0}, Move({"X": 30.0, "Y": 40.0}, feed=600.0), Overrides(), 0.0)
    # F600 = 10 mm/s on 50 mm; the path may accelerate at 1000 mm/s² over Y's share 4/5: 1250 mm/s²
    assert slow.duration_s == pytest.approx(50.0 / 10.0 + 10.0 / 1250.0)
    # F60000 is beyond the axes: X carries 3/5 of the path, Y 4/5: Y limits the path to 100 * 5/4 mm/s
    fast = planner.move({"X": 0.0, "Y": 0.0}, Move({"X": 30.0, "Y": 40.0}, feed=60000.0), Overrides(), 0.0)
    v, a = 125.0, 1250.0
    assert fast.duration_s == pytest.approx(ramp_time_s(50.0, v, a, 2))
    half = planner.move({"X": 0.0}, Move({"X": 100.0}, feed=600.0), Overrides(feed_pct=50.0), 0.0)
    assert half.duration_s == pytest.approx(100.0 / 5.0 + 5.0 / A_XY)
    # G95: mm per revolution of the spindle
    per_rev = planner.move({"X": 0.0}, Move({"X": 100.0}, feed=0.1, feed_mode="G95"), Overrides(), 3000.0)
    assert per_rev.duration_s == pytest.approx(100.0 / 5.0 + 5.0 / A_XY)


def test_g64_hands_the_speed_on() -> None:
    planner = Planner(MotionLimits({"X": AxisLimits(6000.0, 1.0)}))
    first = planner.move({"X": 0.0}, Move({"X": 100.0}, feed=600.0, exact_stop=False), Overrides(), 0.0)
    second = planner.move({"X": 100.0}, Move({"X": 200.0}, feed=600.0, exact_stop=True), Overrides(), 0.0)
    assert first.duration_s == pytest.approx(10.0 + 0.005)       # accelerates only
    assert second.duration_s == pytest.approx(10.0 + 0.005)      # decelerates only


def test_arc_by_its_length_and_dwell_exact() -> None:
    planner = Planner(MotionLimits({"X": AxisLimits(6000.0, 1.0), "Y": AxisLimits(6000.0, 1.0)}))
    quarter = planner.arc({"X": 10.0, "Y": 0.0}, Arc({"X": 0.0, "Y": 10.0}, {"X": 0.0, "Y": 0.0}, clockwise=False,
                                                      feed=600.0), Overrides(), 0.0)
    assert quarter.length_mm == pytest.approx(10.0 * math.pi / 2)
    assert quarter.duration_s == pytest.approx(ramp_time_s(10.0 * math.pi / 2, 10.0, 1000.0, 2))
    assert planner.dwell(Dwell(seconds=2.5), 0.0).duration_s == 2.5
    assert planner.dwell(Dwell(spindle_revolutions=30.0), 600.0).duration_s == pytest.approx(3.0)


def test_a_circle_above_the_axes_speed_runs_at_the_slower_plane_axis() -> None:
    # F10000 on a full circle of radius 10 mm (62.83 mm): X may go 6000 mm/min, Y only 3000; each plane axis
    # carries the whole path speed where the tangent runs along it, so the circle runs at Y's 50 mm/s and
    # ramps at the smaller acceleration (Y, 0.5 m/s²): 62.83 / 50 + 50 / 500 s
    planner = Planner(MotionLimits({"X": AxisLimits(6000.0, 1.0), "Y": AxisLimits(3000.0, 0.5)}))
    circle = planner.arc({"X": 10.0, "Y": 0.0}, Arc({"X": 10.0, "Y": 0.0}, {"X": 0.0, "Y": 0.0}, clockwise=True,
                                                     feed=10000.0), Overrides(), 0.0)
    length = 2.0 * math.pi * 10.0
    assert circle.length_mm == pytest.approx(length)
    assert circle.feed_mm_min == pytest.approx(3000.0)
    assert circle.duration_s == pytest.approx(length / 50.0 + 50.0 / 500.0)


def test_a_helix_is_held_to_its_slow_infeed_axis() -> None:
    # One turn of radius 10 mm while Z goes down 50 mm at F6000: the path is hypot(62.83, 50) = 80.30 mm,
    # of which Z carries 50/80.30; Z's 600 mm/min (10 mm/s) hold the path to 10 / (50/80.30) = 16.06 mm/s
    # (the plane axes would allow 100 / (62.83/80.30)), and Z's 0.1 m/s² its acceleration likewise
    limits = {"X": AxisLimits(6000.0, 1.0), "Y": AxisLimits(6000.0, 1.0), "Z": AxisLimits(600.0, 0.1)}
    planner = Planner(MotionLimits(limits))
    helix = planner.arc({"X": 10.0, "Y": 0.0, "Z": 0.0},
                        Arc({"X": 10.0, "Y": 0.0, "Z": -50.0}, {"X": 0.0, "Y": 0.0}, clockwise=False, feed=6000.0),
                        Overrides(), 0.0)
    length = math.hypot(2.0 * math.pi * 10.0, 50.0)
    speed_mm_s = 10.0 * length / 50.0
    accel_mm_s2 = 100.0 * length / 50.0
    assert helix.length_mm == pytest.approx(length)
    assert helix.feed_mm_min == pytest.approx(speed_mm_s * 60.0)
    assert helix.duration_s == pytest.approx(length / speed_mm_s + speed_mm_s / accel_mm_s2)
    # Z never runs faster than it may: its share of the path speed is its own limit
    assert speed_mm_s * 50.0 / length == pytest.approx(10.0)


# ------------------------------------------------------------------ a program on the channel
PROGRAM = """; a test program
N10 G0 X100
N20 S1200 M3
N30 G1 X200 F600
N40 G4 F2
N50 M5
N60 M30
"""
# G0 100 mm: 1.1 s; S1200 at 20 rev/s²: 1 s ramp, the G1 waits for it; 100 mm at 10 mm/s: 10.01 s; dwell 2 s
PROGRAM_S = 1.1 + 1.0 + 10.01 + 2.0


def test_program_takes_its_time_whatever_the_cycle() -> None:
    results = []
    for cycle_s in (0.1, 1.0, 0.37):
        emu, clock = emulator(cycle_s)
        channel, changes = started(emu, "TIMED.MPF", PROGRAM)
        run(emu, clock, 20.0)
        assert changes == ["selected", "started", "ended"]
        state = channel.state
        assert (state.status, state.program_status) == (CHAN_RESET, PROG_ABORTED)
        results.append(state.old_net_time_s)
        assert state.actual_parts == state.total_parts == 1.0
        assert (state.start_counter, state.end_counter) == (1, 1)
        assert emu.nck.axes.positions_mm[1] == 200.0
    assert results == pytest.approx([PROGRAM_S] * 3, abs=1e-9)


def test_offline_run_is_the_served_channel() -> None:
    emu, _clock = emulator()
    path = store(emu, "TIMED.MPF", PROGRAM)
    blocks = []
    result = run_offline(emu, path, on_block=blocks.append)
    assert result.outcome == "ended" and result.net_time_s == pytest.approx(PROGRAM_S)
    assert [b.number for b in blocks] == ["N10", "N20", "N30", "N40", "N50", "N60"]
    assert blocks[2].start_s == pytest.approx(1.1) and blocks[2].end_s == pytest.approx(1.1 + 1.0 + 10.01)
    assert blocks[-1].m_codes == [30]


def test_positions_feed_and_spindle_while_it_runs() -> None:
    emu, clock = emulator()
    channel = emu.nck.channels[1]
    channel.select(store(emu, "TIMED.MPF", PROGRAM))
    channel.start()
    run(emu, clock, 7.1)             # the G1 started at 2.1 s: 5 s at 10 mm/s (the ramp is 0.01 s)
    assert emu.nck.axes.positions_mm[1] == pytest.approx(150.0, abs=0.1)
    assert channel.actual_feed_mm_min == pytest.approx(600.0)
    assert channel.spindle_speed_rpm(1) == 1200.0 and channel.spindle_commanded_rpm(1) == 1200.0
    assert (channel.state.block_number, channel.state.line_number) == ("N30", 4)
    assert channel.state.block_text == "N30 G1 X200 F600"
    assert channel.ac_prog == AC_RUNNING
    # the sensor warms with 100 s towards 2 K per 1000 rpm (2.4 K) plus 0.2 K per m/min of path (0.12 K):
    # the spindle turns from 1.1 s (full speed at 2.1 s), the path moves from 2.1 s: about 5.5 s of it
    target_K = 2.4 + 0.2 * 0.6
    assert emu.nck.sensor_temperature_C("spindle") == pytest.approx(20.0 + target_K * (1 - math.exp(-0.055)),
                                                                    abs=0.015)


def test_stop_holds_and_start_resumes_the_remaining_path() -> None:
    emu, clock = emulator()
    channel, changes = started(emu, "TIMED.MPF", PROGRAM)
    run(emu, clock, 5.0)
    channel.stop()
    x_stopped = emu.nck.axes.positions_mm[1]
    assert (channel.state.status, channel.state.program_status, channel.ac_prog) == \
        (CHAN_INTERRUPTED, PROG_STOPPED, AC_STOPPED)
    run(emu, clock, 65.0)                                     # a minute of standing
    assert emu.nck.axes.positions_mm[1] == x_stopped and channel.net_time_s == pytest.approx(5.0)
    channel.start()
    run(emu, clock, 90.0)
    assert changes == ["selected", "started", "interrupted", "resumed", "ended"]
    assert channel.state.old_net_time_s == pytest.approx(PROGRAM_S, abs=1e-6)
    assert channel.state.start_counter == 2


def test_reset_aborts_and_counts() -> None:
    emu, clock = emulator()
    channel, changes = started(emu, "TIMED.MPF", PROGRAM)
    run(emu, clock, 3.0)
    assert emu.nck.programs.running == "/_N_MPF_DIR/_N_TIMED_MPF"
    with pytest.raises(NckPiStateError):
        emu.nck.programs.write("/_N_MPF_DIR/_N_TIMED_MPF", b"M30\n")
    channel.reset()
    assert changes[-1] == "aborted" and channel.state.reset_counter == 1 and channel.state.actual_parts == 0
    assert emu.nck.programs.running == "" and channel.run is None
    run(emu, clock, 10.0)
    assert channel.spindle_speed_rpm(1) == 0.0        # reset stops the spindle (it runs down in 1 s)


def test_m0_interrupts_until_nc_start() -> None:
    emu, clock = emulator()
    channel = emu.nck.channels[1]
    channel.select(store(emu, "PAUSE.MPF", "G0 X10\nM0\nG0 X20\nM30\n"))
    channel.start()
    run(emu, clock, 5.0)
    assert (channel.state.status, channel.state.program_status) == (CHAN_INTERRUPTED, PROG_STOPPED)
    assert emu.nck.axes.positions_mm[1] == 10.0
    channel.start()
    run(emu, clock, 10.0)
    assert channel.state.status == CHAN_RESET and emu.nck.axes.positions_mm[1] == 20.0



def test_a_frame_the_program_selects_becomes_the_nck_s_active_frame() -> None:
    """G54/G55/G500 in a block make that settable frame the NCK's active one (actFrameIndex, work
    positions), at that block: what the program moves in is what the NCK reports."""
    machine = MACHINE + '[work_offsets]\nG54 = { X1 = 100.0 }\nG55 = { X1 = 300.0 }\n'
    emu, clock = emulator(machine=machine)
    channel = emu.nck.channels[1]
    assert emu.nck.frames.active[1] == 0
    channel.select(store(emu, "FRAMES.MPF", "G54\nG0 X10\nM0\nG55 X10\nM0\nG500 X10\nM30\n"))
    channel.start()
    run(emu, clock, 5.0)
    assert emu.nck.frames.active[1] == 1 and emu.nck.axes.positions_mm[1] == 110.0
    channel.start()
    run(emu, clock, 10.0)
    assert emu.nck.frames.active[1] == 2 and emu.nck.axes.positions_mm[1] == 310.0
    channel.start()
    run(emu, clock, 20.0)
    assert emu.nck.frames.active[1] == 0 and emu.nck.axes.positions_mm[1] == 10.0

def test_r_parameters_are_the_nck_s() -> None:
    from nckemu.emulator.machine.nck.access import AccessContext
    from nckemu.protocol.addresses import NckAddress, NckArea

    emu, clock = emulator()
    channel = emu.nck.channels[1]
    r = emu.nck.store.spec("R")
    emu.nck.store.write_lines(r, 1, 2, [40.0])                       # R1 = 40, as `nckemu put R1=40`
    channel.select(store(emu, "R.MPF", "R2=R1*2+1\nG0 X=R2\nM30\n"))
    channel.start()
    run(emu, clock, 5.0)
    assert emu.nck.axes.positions_mm[1] == 81.0
    address = NckAddress(area=NckArea.C, unit=1, module=0x15, column=1, line=3)
    assert emu.nck.read(address, AccessContext()) == [81.0]            # `nckemu get R2`


# ------------------------------------------------------------------ refusals and alarms
def test_select_start_and_mode_refusals() -> None:
    emu, clock = emulator()
    channel = emu.nck.channels[1]
    with pytest.raises(NckNoSuchFile):
        channel.select("/_N_MPF_DIR/_N_NOTHERE_MPF")
    with pytest.raises(NckPiStateError):
        channel.unselect()
    with pytest.raises(NckPiStateError, match="no program selected"):
        channel.start()
    assert emu.nck.alarm_list.pending[-1].number == 16912 and channel.state.status == CHAN_RESET
    channel.reset()                                    # reset clears the refusal's alarm
    assert emu.nck.alarm_list.count == 0
    channel.select(store(emu, "TIMED.MPF", PROGRAM))
    channel.set_mode(MODE_JOG)
    with pytest.raises(NckPiStateError, match="JOG"):
        channel.start()
    channel.reset()
    channel.set_mode(MODE_AUTOMATIC)
    channel.start()
    with pytest.raises(NckPiStateError):
        channel.select(store(emu, "OTHER.MPF", "M30\n"))          # select while running
    with pytest.raises(NckPiStateError):
        channel.set_mode(MODE_JOG)
    assert emu.nck.alarm_list.pending[-1].number == 16913
    with pytest.raises(NckPiStateError):
        channel.unselect()
    run(emu, clock, 1.0)
    assert channel.state.status == CHAN_ACTIVE and channel.selected == "/_N_MPF_DIR/_N_TIMED_MPF"


@pytest.mark.parametrize(("text", "number"), [
    ("G0 X10\nG1 X=)\nM30\n", 12080),                            # syntax error
    ("EXTERN NOSUCHSUB(REAL)\nG0 X10\nNOSUCHSUB(1)\nM30\n", 14011),  # missing subprogram
    ("G0 X10\nGOTOF NOWHERE\nM30\n", 14080),                      # jump to nowhere
    ("R1=0\nR2=5/R1\nM30\n", None),                                # division by zero: the interpreter's alarm
    ("G0 X5000\nM30\n", 10720),                                    # beyond the travel
    ("G1 X10 F0\nM30\n", None),                                    # F0: 14800 (or the interpreter's own)
])
def test_bad_programs_end_in_an_alarm_and_reset_clears_it(text: str, number: int | None) -> None:
    emu, clock = emulator()
    channel, changes = started(emu, "BAD.MPF", text)
    run(emu, clock, 5.0)
    assert (channel.state.status, channel.state.program_status) == (CHAN_INTERRUPTED, PROG_INTERRUPTED)
    assert changes[-1] == "interrupted" and len(channel.alarms) == 1
    alarm = emu.nck.alarm_list.pending[-1]
    if number is not None:
        assert alarm.number == number, alarm
    with pytest.raises(NckPiStateError):
        channel.start()                                # no start with the alarm pending
    channel.reset()
    assert emu.nck.alarm_list.count == 0 and channel.state.status == CHAN_RESET and changes[-1] == "aborted"


def test_an_endless_loop_runs_bounded_per_cycle_and_reset_stops_it() -> None:
    emu, clock = emulator()
    channel = emu.nck.channels[1]
    channel.select(store(emu, "LOOP.MPF", "LOOP1:\nR1=R1+1\nGOTOB LOOP1\n"))
    channel.start()
    run(emu, clock, 1.0)                               # ten cycles of at most max_blocks_per_cycle blocks
    blocks = channel.run.blocks if channel.run is not None else 0
    assert 0 < blocks <= 10 * emu.machine.program.max_blocks_per_cycle
    assert channel.state.status == CHAN_ACTIVE
    channel.reset()
    assert channel.state.status == CHAN_RESET and channel.run is None


# ------------------------------------------------------------------ the PLC's interface
def test_db21_edges_start_stop_reset_and_dbb35_answers() -> None:
    emu, clock = emulator()
    plc = emu.plc
    channel = emu.nck.channels[1]
    channel.select(store(emu, "TIMED.MPF", PROGRAM))
    assert plc.read(S7Area.DB, 21, 35, 1) == bytes([0x80 | 0x10])          # reset, aborted
    plc.write_bit(S7Area.DB, 21, 7, 1, True)                              # NC start
    assert channel.state.status == CHAN_ACTIVE
    assert plc.read(S7Area.DB, 21, 35, 1) == bytes([0x20 | 0x01])          # active, running
    plc.write_bit(S7Area.DB, 21, 7, 1, True)                              # still set: no new edge
    run(emu, clock, 2.0)
    plc.write_bit(S7Area.DB, 21, 7, 1, False)
    plc.write_bit(S7Area.DB, 21, 7, 3, True)                              # NC stop
    assert plc.read(S7Area.DB, 21, 35, 1) == bytes([0x40 | 0x04])          # interrupted, stopped
    plc.write(S7Area.DB, 21, 7, bytes([0x80]))                            # reset (stop released)
    assert plc.read(S7Area.DB, 21, 35, 1) == bytes([0x80 | 0x10])
    assert channel.state.reset_counter == 1


def test_db11_mode_requests_and_active_mode() -> None:
    emu, _clock = emulator()
    plc = emu.plc
    channel = emu.nck.channels[1]
    assert plc.read(S7Area.DB, 11, 6, 1) == b"\x01"                      # AUTOMATIC
    plc.write(S7Area.DB, 11, 0, b"\x04")                                  # JOG requested
    assert channel.state.mode == MODE_JOG and plc.read(S7Area.DB, 11, 6, 1) == b"\x04"
    channel.select(store(emu, "TIMED.MPF", PROGRAM))
    plc.write(S7Area.DB, 21, 7, b"\x02")                                  # NC start in JOG: refused
    assert channel.state.status == CHAN_RESET and emu.nck.alarm_list.pending[-1].number == 16912
    plc.write(S7Area.DB, 11, 0, b"\x01")                                  # AUTOMATIC
    plc.write(S7Area.DB, 21, 7, b"\x80")                                  # reset clears the alarm
    plc.write(S7Area.DB, 21, 7, b"\x02")
    assert channel.state.status == CHAN_ACTIVE and emu.nck.alarm_list.count == 0


def test_channel_2_answers_in_db22() -> None:
    emu, _clock = emulator(machine=MACHINE.replace('name = "test mill"', 'name = "two"\nchannels = 2'))
    assert emu.plc.read(S7Area.DB, 22, 35, 1) == bytes([0x90])
    store(emu, "TIMED.MPF", PROGRAM)
    emu.nck.channels[2].select("/_N_MPF_DIR/_N_TIMED_MPF")
    emu.plc.write(S7Area.DB, 22, 7, b"\x02")
    assert emu.nck.channels[2].state.status == CHAN_ACTIVE and emu.nck.channels[1].state.status == CHAN_RESET


def test_warm_up_moves_the_piw_word() -> None:
    emu, clock = emulator()
    channel = emu.nck.channels[1]
    before = emu.plc.read(S7Area.P, 0, 256, 2)
    channel.select(store(emu, "WARM.MPF", "S5000 M3\nG4 F300\nM5\nM30\n"))
    channel.start()
    run(emu, clock, 300.0)
    # 10 K towards which the sensor rises with 100 s: 300 s later about 10 * (1 - e^-3) (the ramp aside)
    assert emu.nck.sensor_temperature_C("spindle") == pytest.approx(20.0 + 10.0 * (1 - math.exp(-3.0)), abs=0.3)
    assert emu.plc.read(S7Area.P, 0, 256, 2) != before
    assert channel.state.program_status in (PROG_RUNNING, PROG_ABORTED)


def test_the_environment_reads_the_nck() -> None:
    emu, clock = emulator()
    channel = emu.nck.channels[1]
    channel.state.actual_parts = 7.0
    emu.nck.frames.shifts_mm[1][1][1] = 10.0                        # G54 shifts X by 10 mm
    channel.select(store(emu, "ENV.MPF", "G54\nG0 X25\nR1=$AA_IM[X]\nR2=$AC_ACTUAL_PARTS\n"
                                         "$AC_REQUIRED_PARTS=3\nM30\n"))
    channel.start()
    run(emu, clock, 5.0)
    r = emu.nck.store.spec("R")
    assert emu.nck.store.read_lines(r, 1, 2, 2) == [35.0, 7.0]          # G54 + X25: machine X 35
    assert channel.state.required_parts == 3.0 and channel.state.actual_parts == 8.0


def test_a_subprogram_is_found_in_the_subprogram_directory() -> None:
    emu, clock = emulator()
    channel = emu.nck.channels[1]
    store(emu, "MOVE_TWICE.SPF", "PROC MOVE_TWICE(REAL DIST)\nG1 X=DIST F6000\nG1 X=2*DIST\nRET\n")
    channel.select(store(emu, "CALLER.MPF", "EXTERN MOVE_TWICE(REAL)\nMOVE_TWICE(30)\nM30\n"))
    blocks = []
    channel.block_listeners.append(blocks.append)
    channel.start()
    run(emu, clock, 10.0)
    assert channel.state.status == CHAN_RESET and emu.nck.axes.positions_mm[1] == 60.0
    assert {b.program for b in blocks} == {"/_N_MPF_DIR/_N_CALLER_MPF", "/_N_SPF_DIR/_N_MOVE_TWICE_SPF"}


def test_a_feed_override_of_0_holds_the_move_as_long_as_it_lasts() -> None:
    """Held by an override of 0 for 1 000 cycles and more (it once wrapped the event stream once per
    cycle and ended in an internal error), the move runs on when the override opens again."""
    emu, clock = emulator()
    channel, changes = started(emu, "HOLD.MPF", "G1 X10 F600\nM30\n")
    channel.state.feed_override_pct = 0.0
    run(emu, clock, 150.0)                                    # 1 500 cycles of 0.1 s
    assert channel.alarms == [] and emu.nck.axes.positions_mm[1] == 0.0
    channel.state.feed_override_pct = 100.0
    run(emu, clock, 152.0)
    assert emu.nck.axes.positions_mm[1] == pytest.approx(10.0) and changes[-1] == "ended"
