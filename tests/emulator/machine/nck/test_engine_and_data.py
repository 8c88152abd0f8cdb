"""The NCK model without a network: compensation engine, leadscrew tables, access, retained data."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.machine_file import load_machine, parse_machine
from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.emulator.machine.nck.model import NckModel
from nckemu.emulator.machine.state import RetainedStore
from nckemu.errors import (
    NckAccessDenied,
    NckAddressOutOfRange,
    NckConfigError,
    NckItemError,
    NckObjectDoesNotExist,
    NckServiceError,
)
from nckemu.protocol.addresses import NckAddress

ROOT = AccessContext(level=0)
USER = AccessContext(level=7)
Z = 4


def sd(number: int, axis: int = Z) -> NckAddress:
    return NckAddress(3, axis, number, 1, 0x16)


def md(number: int, axis: int = Z, line: int = 1) -> NckAddress:
    return NckAddress(3, axis, number, line, 0x1A)


@pytest.fixture
def clock() -> SimulatedClock:
    return SimulatedClock()


@pytest.fixture
def nck(clock: SimulatedClock) -> NckModel:
    return NckModel(load_machine(), clock)


def settle(nck: NckModel, clock: SimulatedClock, seconds: float = 60.0) -> None:
    clock.advance(seconds)


def seed000_k0_mm(temperature_C: float) -> float:
    """Seed 000: 0 at <= 30 degC, 0.3 mm per 10 K above."""
    return 0.0 if temperature_C <= 30 else (temperature_C - 30) / 10 * 0.3


@pytest.mark.parametrize("temperature_C", [25.0, 30.0, 40.0, 50.0])
def test_seed000_position_independent(nck: NckModel, clock: SimulatedClock, temperature_C: float) -> None:
    nck.write(md(32750), [1], ROOT)
    nck.power_on()
    nck.write(sd(43900), [seed000_k0_mm(temperature_C)], USER)
    settle(nck, clock)
    for position_mm in (-1000.0, -500.0, 0.0):
        nck.set_axis_position(Z, position_mm)
        assert nck.compensation_mm(Z) == pytest.approx(seed000_k0_mm(temperature_C), abs=1e-12)
        # A positive value moves the axis negative.
        assert nck.actual_position_mm(Z) == pytest.approx(position_mm - seed000_k0_mm(temperature_C))


def test_seed000_position_dependent_follows_the_formula(nck: NckModel, clock: SimulatedClock) -> None:
    nck.write(md(32750), [2], ROOT)
    nck.power_on()
    slope = -0.0003  # 0.3 mm at Z = -1000 with P0 = 0
    nck.write(sd(43910), [slope], USER)
    nck.write(sd(43920), [0.0], USER)
    for position_mm in (-1000.0, -500.0, 0.0):
        nck.set_axis_position(Z, position_mm)
        settle(nck, clock)
        assert nck.compensation_mm(Z) == pytest.approx(slope * position_mm, abs=1e-12)


def test_machine_data_take_effect_at_power_on_only(nck: NckModel, clock: SimulatedClock) -> None:
    nck.write(sd(43900), [0.3], USER)
    nck.write(md(32750), [1], ROOT)
    settle(nck, clock)
    assert nck.compensation_mm(Z) == 0.0
    assert nck.read(md(32750), USER) == [1]  # the stored value reads back at once
    nck.power_on()
    settle(nck, clock)
    assert nck.compensation_mm(Z) == pytest.approx(0.3)


def test_change_per_ipo_cycle_is_limited(nck: NckModel, clock: SimulatedClock) -> None:
    nck.write(md(32750), [1], ROOT)
    nck.power_on()
    nck.write(sd(43900), [1.0], USER)
    step_mm = 0.01 * 10000.0 / 60.0 * 0.004  # MD32760 * MD32000 (mm/min -> mm/s) * T_IPO
    assert nck.tc_max_step_mm(Z) == pytest.approx(step_mm)
    clock.advance(10 * 0.004)
    assert nck.tc_value_mm(Z) == pytest.approx(10 * step_mm)
    clock.advance(3600.0 * 2)  # two simulated hours: closed form, not 1.8 million cycles
    assert nck.tc_value_mm(Z) == pytest.approx(1.0)


def channel(number: int, module: int, line: int = 1) -> NckAddress:
    return NckAddress(2, 1, number, line, module)


def test_tc_in_tool_direction_needs_bit_2_and_md20390_and_is_limited(nck: NckModel, clock: SimulatedClock) -> None:
    nck.write(channel(42960, 0x16, line=1), [0.05], USER)     # SD42960[0]: L1, on Z under G17
    nck.write(channel(42960, 0x16, line=3), [0.02], USER)     # SD42960[2]: L3, on X
    nck.write(md(32750), [4], ROOT)
    nck.power_on()
    settle(nck, clock)
    assert nck.compensation_mm(Z) == 0.0                    # MD20390 still off
    nck.write(channel(20390, 0x1A), [1], ROOT)
    nck.power_on()
    settle(nck, clock)
    assert nck.compensation_mm(Z) == pytest.approx(0.05)
    assert nck.compensation_mm(1) == 0.0                    # X1 has bit 2 off
    nck.write(channel(42960, 0x16, line=1), [2.5], USER)      # beyond MD20392[0] = 1 mm: limited, no alarm
    settle(nck, clock)
    assert nck.compensation_mm(Z) == pytest.approx(1.0) and nck.alarms == []
    nck.write(md(32750), [5], ROOT)                          # bits 0 and 2 add up
    nck.write(sd(43900), [0.3], USER)
    nck.power_on()
    settle(nck, clock)
    assert nck.compensation_mm(Z) == pytest.approx(1.3)


def test_which_sd42960_component_acts_on_an_axis_is_a_setting() -> None:
    default = load_machine()
    assert {a.name: a.tool_temp_comp_component for a in default.axes} == {"X1": 3, "Y1": 2, "SP1": None, "Z1": 1}
    text = '[[axis]]\nnumber = 1\nname = "W"\ntool_temp_comp_component = 1\n'
    assert parse_machine(text).axes[0].tool_temp_comp_component == 1
    with pytest.raises(NckConfigError, match="tool_temp_comp_component"):
        parse_machine(text.replace("= 1\n", "= 4\n").replace("number = 4", "number = 1"))


def test_840c_tc_is_immediate_and_erased_at_power_on(nck: NckModel) -> None:
    nck.set_axis_position(Z, -100.0)
    nck.apply_840c_tc(Z, 0.02, 0.0001, 100.0, True, True)
    assert nck.tc_value_mm(Z) == pytest.approx(0.02 + 0.0001 * (-200.0))
    nck.power_on()
    assert nck.tc_value_mm(Z) == 0.0


LEC = """; leadscrew table of Z1
CHANDATA(1)
$AA_ENC_COMP[0,0,AX4]=0.0
$AA_ENC_COMP[0,1,AX4]=0.010
$AA_ENC_COMP[0,2,AX4]=0.004
$AA_ENC_COMP_STEP[0,AX4]=100.0
$AA_ENC_COMP_MIN[0,AX4]=-200.0
$AA_ENC_COMP_MAX[0,AX4]=0.0
$AA_ENC_COMP_IS_MODULO[0,AX4]=0
M17
"""


def test_leadscrew_table_interpolates_and_holds_end_values(nck: NckModel) -> None:
    nck.load_leadscrew_program(LEC, "z.mpf")
    assert nck.lec_value_mm(Z) == 0.0  # not active before power-on with MD32700 = 1
    nck.write(md(32700), [1], ROOT)
    nck.power_on()
    for position_mm, expected in ((-200.0, 0.0), (-150.0, 0.005), (-100.0, 0.010), (-50.0, 0.007),
                                  (0.0, 0.004), (-900.0, 0.0)):
        nck.set_axis_position(Z, position_mm)
        assert nck.lec_value_mm(Z) == pytest.approx(expected)
    with pytest.raises(NckServiceError):
        nck.load_leadscrew_program(LEC, "z.mpf")  # only while MD32700 = 0 is active
    nck.set_referenced(Z, False)
    assert nck.lec_value_mm(Z) == 0.0


@pytest.mark.parametrize(("text", "line", "why"), [
    (LEC.replace("[0,1,AX4]", "[0,5,AX4]"), None, "gap"),
    (LEC.replace("AX4]=0.010", "AX9]=0.010"), 4, "unknown axis"),
    (LEC.replace("M17", "G01 X10"), 10, "not a leadscrew"),
    (LEC.replace("=0.010", "=abc"), 4, "not a number"),
])
def test_bad_leadscrew_programs_name_the_line(nck: NckModel, text: str, line: int | None, why: str) -> None:
    with pytest.raises(NckConfigError, match=why) as error:
        nck.load_leadscrew_program(text, "bad.mpf")
    assert "bad.mpf" in str(error.value)
    if line is not None:
        assert f"line {line}" in str(error.value)


def test_more_points_than_md38000_are_refused(nck: NckModel) -> None:
    nck.write(md(38000), [2], ROOT)
    nck.power_on()
    with pytest.raises(NckConfigError, match="MD38000 allows 2"):
        nck.load_leadscrew_program(LEC, "z.mpf")


def test_addressing_errors(nck: NckModel) -> None:
    with pytest.raises(NckObjectDoesNotExist):
        nck.read(NckAddress(3, 4, 43900, 1, 0x55), USER)      # module not served
    with pytest.raises(NckObjectDoesNotExist):
        nck.read(NckAddress(2, 1, 43900, 1, 0x16), USER)      # SD43900 is not a channel datum
    with pytest.raises(NckObjectDoesNotExist):
        nck.read(sd(43900, axis=9), USER)                     # no machine axis 9
    with pytest.raises(NckAddressOutOfRange):
        nck.read(NckAddress(3, 4, 43900, 2, 0x16), USER)
    with pytest.raises(NckAddressOutOfRange):
        nck.read(NckAddress(2, 1, 1, 99, 0x15, line_count=5), USER)
    assert len(nck.read(NckAddress(2, 1, 1, 1, 0x15, line_count=100), USER)) == 100


def test_access_and_limits(nck: NckModel) -> None:
    with pytest.raises(NckAccessDenied):
        nck.write(md(32750), [1], USER)
    with pytest.raises(NckAccessDenied):
        nck.write(NckAddress(2, 1, 2, 1, 0x74), [1.0], ROOT)  # state data are read only
    with pytest.raises(NckItemError) as error:
        nck.write(md(32750), [9], ROOT)                        # 0..7
    assert error.value.return_code == 0x05
    ctx = AccessContext(level=7)
    nck.pi_service("_N_LOGIN_", ["/NC", "EVENING"], ctx)
    assert ctx.level == 2
    nck.pi_service("_N_LOGOUT", ["/NC"], ctx)
    assert ctx.level == 7


def test_retained_round_trip_and_store(tmp_path: Path, nck: NckModel, clock: SimulatedClock) -> None:
    nck.write(sd(43900), [0.125], USER)
    nck.write(md(32750), [3], ROOT)
    nck.load_leadscrew_program(LEC, "z.mpf")
    store = RetainedStore(tmp_path / "state.json")
    store.save(nck.retained_snapshot())
    again = NckModel(load_machine(), clock)
    again.restore_retained(store.load() or {})
    assert again.read(sd(43900), USER) == [0.125]
    assert again.read(md(32750), USER) == [3]
    assert again.store.active_value("TEMP_COMP_TYPE", Z) == 3  # restored machine data are active, as after power-on
    (tmp_path / "state.json").write_text('{"format": "nckemu-retained", "version": 1, "values": ')
    with pytest.raises(NckConfigError, match="state.json"):
        store.load()
    assert RetainedStore(tmp_path / "missing.json").load() is None


def test_machine_file_errors_name_the_field(tmp_path: Path) -> None:
    with pytest.raises(NckConfigError, match=r"axis\[0\].number"):
        parse_machine('[[axis]]\nnumber = 40\nname = "X"\n', "m.toml")
    with pytest.raises(NckConfigError, match="m.toml"):
        parse_machine("name = ", "m.toml")
    with pytest.raises(NckConfigError, match=r"initial.MD99999"):
        NckModel(parse_machine('[initial]\nMD99999 = { 1 = 1 }\n', "m.toml"), SimulatedClock())
    machine = parse_machine('[[axis]]\nnumber = 1\nname = "X1"\n[initial]\nSD43900 = { 1 = 0.5 }\n', "m.toml")
    assert NckModel(machine, SimulatedClock()).read(sd(43900, 1), USER) == [0.5]
    json.dumps(machine.data_blocks)


class CompensationRamp(RuleBasedStateMachine):
    """The applied TC never changes faster than the rate limit and converges to its target."""

    def __init__(self) -> None:
        super().__init__()
        self.clock = SimulatedClock()
        self.nck = NckModel(load_machine(), self.clock)
        self.nck.write(md(32750), [3], ROOT)
        self.nck.power_on()
        self.last_value = self.nck.tc_value_mm(Z)
        self.last_time = self.clock.now_s()

    @rule(k0=st.floats(-2.0, 2.0), slope=st.floats(-0.01, 0.01), p0=st.floats(-1000.0, 0.0))
    def write_setting_data(self, k0: float, slope: float, p0: float) -> None:
        self.nck.write(sd(43900), [k0], USER)
        self.nck.write(sd(43910), [slope], USER)
        self.nck.write(sd(43920), [p0], USER)

    @rule(position=st.floats(-1000.0, 0.0))
    def move(self, position: float) -> None:
        self.nck.set_axis_position(Z, position)

    @rule(dt=st.floats(0.0, 5.0))
    def advance(self, dt: float) -> None:
        self.clock.advance(dt)
        value = self.nck.tc_value_mm(Z)
        cycles = (self.clock.now_s() - self.last_time) / 0.004 + 1
        assert abs(value - self.last_value) <= cycles * self.nck.tc_max_step_mm(Z) + 1e-9
        self.last_value, self.last_time = value, self.clock.now_s()

    @precondition(lambda self: True)
    @rule()
    def settle(self) -> None:
        self.clock.advance(3600.0)
        assert self.nck.tc_value_mm(Z) == pytest.approx(self.nck.tc_target_mm(Z), abs=1e-9)
        self.last_value, self.last_time = self.nck.tc_value_mm(Z), self.clock.now_s()

    @invariant()
    def finite(self) -> None:
        assert abs(self.nck.tc_value_mm(Z)) < 100


TestCompensationRamp = CompensationRamp.TestCase
TestCompensationRamp.settings = settings(max_examples=40, stateful_step_count=20, deadline=None)
