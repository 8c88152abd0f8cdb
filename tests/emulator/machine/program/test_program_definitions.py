"""Definition files (GUD arrays, DEFINE macros) and system variables as a shop's programs use them,
offline on the emulated channel (the served path is in tests/emulator/machine/program/test_program_definitions_served.py)."""

from __future__ import annotations

import json

import pytest

from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.offline import run_offline
from nckemu.emulator.machine.program.environment import ProgramEnvironment
from nckemu.emulator.machine.program.language import Interpreter
from nckemu.emulator.machine.program.language.definitions import (
    MAX_DEFINITION_BYTES,
    DefinitionRefused,
    expand_macros,
    parse_definitions,
)
from nckemu.emulator.machine.program.motions import Move

MGUD = "/_N_DEF_DIR/_N_MGUD_DEF"
GUD_TEXT = b"""%_N_MGUD_DEF
;$PATH=/_N_DEF_DIR
DEF NCK REAL INI[100]          ; grinding parameters
DEF NCK APWP 1 APRP 7 REAL PHU 4 LLI 0 SAFE_Z=50
DEF CHAN STRING[1] AXIS_VER
DEF NCK INT COUNTS[3]=SET(1,2,3)
M30
"""


def _emulator() -> Emulator:
    return Emulator(None, clock=SimulatedClock())


def _run(emulator: Emulator, name: str, text: bytes) -> None:
    path = f"/_N_MPF_DIR/_N_{name}_MPF"
    emulator.nck.programs.write(path, text)
    result = run_offline(emulator, path, max_time_s=600.0)
    assert result.outcome == "ended", result.alarms


def _gud(emulator: Emulator, name: str, *indices: int) -> object:
    return emulator.nck.programs.definitions.variables()[name].get(indices)


def test_a_gud_array_of_the_definition_file_is_what_programs_read_and_write() -> None:
    emulator = _emulator()
    emulator.nck.programs.write(MGUD, GUD_TEXT)
    _run(emulator, "SETUP", b'INI[53]=1500\nAXIS_VER="X"\nR1=INI[53]+SAFE_Z+COUNTS[2]\nM30\n')
    assert _gud(emulator, "INI", 53) == 1500.0 and _gud(emulator, "AXIS_VER") == "X"
    assert emulator.nck.store.read_lines(emulator.nck.store.spec("R"), 1, 2, 1)[0] == 1553.0
    # GUD outlive the run: the next program reads what the last one wrote
    _run(emulator, "GRIND", b"IF INI[53]<>1500\n  SETAL(61000)\nENDIF\nG1 X=INI[53]/100 F1000\nM30\n")
    assert emulator.nck.axes.positions_mm[1] == pytest.approx(15.0)


def test_a_definition_file_with_an_error_is_refused_and_the_old_definitions_stay() -> None:
    emulator = _emulator()
    programs = emulator.nck.programs
    programs.write(MGUD, GUD_TEXT)
    programs.definitions.variables()["INI"].set((3,), 7.0)
    with pytest.raises(DefinitionRefused) as refused:
        programs.write(MGUD, b"DEF NCK REAL INI[100]\nDEF NCK REAL\nDEF NCK INT NEW_ONE\n")
    alarm = refused.value.alarm
    assert (alarm.number, alarm.program, alarm.line) == (12080, MGUD, 2)
    assert programs.read(MGUD) == GUD_TEXT
    assert "NEW_ONE" not in programs.definitions.variables() and _gud(emulator, "INI", 3) == 7.0
    with pytest.raises(DefinitionRefused) as refused:
        programs.write(MGUD, b"DEF NCK REAL A_1\nG1 X10 F100\n")
    assert refused.value.alarm.line == 2 and "DEF and DEFINE" in str(refused.value)


def test_a_10_mb_definition_file_is_refused_before_it_is_read() -> None:
    emulator = _emulator()
    huge = b"DEF NCK REAL BIG_%d\n" * 1 + b"; padding\n" * (10 * 1024 * 1024 // 10)
    assert len(huge) > MAX_DEFINITION_BYTES
    with pytest.raises(DefinitionRefused, match="at most"):
        emulator.nck.programs.write("/_N_DEF_DIR/_N_UGUD_DEF", huge)
    assert not emulator.nck.programs.exists("/_N_DEF_DIR/_N_UGUD_DEF")


def test_macros_of_a_define_as_file_expand_in_every_program() -> None:
    emulator = _emulator()
    programs = emulator.nck.programs
    programs.write("/_N_DEF_DIR/_N_UMAC_DEF", b"DEFINE M202 AS GAP_SET\nDEFINE LIFT AS G0 Z=-SAFE_HEIGHT\n"
                                               b"DEFINE SAFE_HEIGHT AS 120\n")
    programs.write("/_N_SPF_DIR/_N_GAP_SET_SPF", b"PROC GAP_SET(REAL _GAP)\nR2=_GAP*1000\nM17\n")
    _run(emulator, "MAIN", b'M202(0.0059)\nLIFT\nMSG("LIFT stays text")\nM30\n')
    assert emulator.nck.store.read_lines(emulator.nck.store.spec("R"), 1, 3, 1)[0] == pytest.approx(5.9)
    assert emulator.nck.axes.positions_mm[4] == pytest.approx(-120.0)
    assert expand_macros('LIFT MSG("LIFT") XLIFT', {"LIFT": "G0"}) == 'G0 MSG("LIFT") XLIFT'


def test_definition_files_parse_attributes_initial_values_and_refuse_names_in_them() -> None:
    parsed = parse_definitions(MGUD, GUD_TEXT)
    assert set(parsed.variables) == {"INI", "SAFE_Z", "AXIS_VER", "COUNTS"}
    assert parsed.variables["COUNTS"].value == [1, 2, 3] and parsed.variables["SAFE_Z"].value == 50.0
    with pytest.raises(Exception) as refused:
        parse_definitions(MGUD, "\ufeffDEF NCK REAL A_1=R1\n")
    assert getattr(refused.value, "number", None) == 12550 and refused.value.line == 1


def test_system_variables_a_cycle_reads() -> None:
    emulator = _emulator()
    program = (b"DEF AXIS _X, _Y, _Z, _AX\nG17\n_X=$P_AXN1 _Y=$P_AXN2 _Z=$P_AXN3\n"
               b"R10=$MA_MAX_AX_VELO[X] R11=$MA_MAX_AX_VELO[AX2] R12=$MC_TOOL_TEMP_COMP_ON\n"
               b"_AX=(Y)\nIF _AX<>\"Y\"\n SETAL(61001)\nENDIF\nIF AXNAME(\"Z\")<>_Z\n SETAL(61002)\nENDIF\n"
               b"G18\nIF $P_AXN1<>\"Z\"\n SETAL(61003)\nENDIF\nIF $P_MC\n SETAL(61004)\nENDIF\nIF $P_GG[6]<>2\n SETAL(61005)\nENDIF\nG91\nIF $P_GG[14]<>2\n SETAL(61006)\nENDIF\nG90\nR13=$A_YEAR\nM30\n")
    _run(emulator, "CYCLE_VARS", program)
    store = emulator.nck.store
    r = store.read_lines(store.spec("R"), 1, 11, 4)
    assert r[:2] == [store.active_value("MAX_AX_VELO", 1), store.active_value("MAX_AX_VELO", 2)]
    assert r[3] >= 2024


def test_writing_machine_data_is_the_controls_alarm_and_setting_data_are_written() -> None:
    emulator = _emulator()
    emulator.nck.programs.write("/_N_MPF_DIR/_N_MD_MPF", b"$SA_TEMP_COMP_ABS_VALUE[X]=0.25\n"
                                                         b"$MA_MAX_AX_VELO[X]=1\nM30\n")
    result = run_offline(emulator, "/_N_MPF_DIR/_N_MD_MPF", max_time_s=60.0)
    assert result.outcome == "alarm" and "alarm 17070" in result.alarms[0] and "line 2" in result.alarms[0]
    assert emulator.nck.store.active_value("MAX_AX_VELO", 1) != 1
    assert emulator.nck.store.read_lines(emulator.nck.store.spec("TEMP_COMP_ABS_VALUE"), 1, 1, 1)[0] == 0.25


def test_an_environment_without_definitions_and_one_with_them() -> None:
    class WithGud(ProgramEnvironment):
        def global_variables(self) -> dict:
            return parse_definitions(MGUD, GUD_TEXT).variables

        def macros(self) -> dict[str, str]:
            return {"TO_SAFE": "G0 Z=SAFE_Z"}

    events = list(Interpreter(WithGud(), "/_N_MPF_DIR/_N_A_MPF", "TO_SAFE\nM30").events())
    assert [event.target_mm for event in events if isinstance(event, Move)] == [{"Z": 50.0}]


@pytest.mark.parametrize("machine", ["mill_5axis", "boring_mill", "lathe", "corpus_nine_axes"])
def test_machine_show_lists_the_dynamics_and_travel_of_every_axis(machine: str, fixtures_dir, capsys) -> None:
    from nckemu.cli import main

    path = str(fixtures_dir / "machines" / f"{machine}.toml")
    assert main(["machine", "show", "--machine", path]) == 0
    axis_lines = [line for line in capsys.readouterr().out.splitlines()
                  if line.startswith("  axis ") and "spindle" not in line]
    assert axis_lines and all("MD32000 MAX_AX_VELO" in line and "MD32300 MAX_AX_ACCEL" in line
                              and "MD32060 POS_AX_VELO" in line for line in axis_lines)
    # a rotary axis' speeds in degrees/min, its acceleration in rev/s^2 and the degrees/s^2 it is timed with
    for line in axis_lines:
        assert ("mm" not in line.split("rotary", 1)[1]) if ": rotary" in line else "mm/min" in line
        assert ("deg/min" in line and "rev/s^2 (timed as" in line) if ": rotary" in line else "m/s^2" in line
    assert main(["machine", "show", "--machine", path, "--json"]) == 0
    axes = json.loads(capsys.readouterr().out)["axes"]
    x = next(axis for axis in axes if axis["name"] == "X1")
    assert x["MD32000"]["unit"] == "mm/min" and x["MD32000"]["value"] > 10000 and x["travel_mm"][1] > x["travel_mm"][0]
    assert x["MD32300"]["unit"] == "m/s^2" and "timed_as_deg_s2" not in x["MD32300"]
    for rotary in (axis for axis in axes if axis["rotary"] and not axis["spindle"]):
        assert rotary["MD32000"]["unit"] == rotary["MD32060"]["unit"] == "deg/min"
        assert rotary["MD32300"]["unit"] == "rev/s^2"
        assert rotary["MD32300"]["timed_as_deg_s2"] == rotary["MD32300"]["value"] * 1000.0
    emulator = Emulator(path, clock=SimulatedClock())
    assert emulator.nck.store.active_value("MAX_AX_VELO", 1) == x["MD32000"]["value"]
    assert emulator.nck.store.spec("R").lines == 1000  # R0..R999, as the shop's programs use them


def test_a_move_beyond_the_travel_says_which_setting_moves_the_limit() -> None:
    emulator = _emulator()
    emulator.nck.programs.write("/_N_MPF_DIR/_N_FAR_MPF", b"G0 X2000\nM30\n")
    result = run_offline(emulator, "/_N_MPF_DIR/_N_FAR_MPF", max_time_s=60.0)
    assert "alarm 10720" in result.alarms[0] and "travel_mm of axis X1 in the machine file" in result.alarms[0]


def test_the_nck_io_and_the_plc_nck_data_area_a_grinder_program_reads() -> None:
    emulator = _emulator()
    emulator.nck.nck_io.write("$A_DBB", 24, 1)  # as the PLC would set it
    emulator.nck.nck_io.digital_in[0] = True
    _run(emulator, "IO", b"WHILE $A_DBB[24]==0\nENDWHILE\n$A_DBW[2]=-5\nR20=$A_DBW[2]\nR21=$A_IN[1]\n"
                          b"$A_OUT[3]=1\n$A_DBR[8]=0.5\nR22=$A_DBR[8]\nM30\n")
    store = emulator.nck.store
    assert store.read_lines(store.spec("R"), 1, 21, 3) == [-5.0, 1.0, 0.5]
    assert emulator.nck.nck_io.digital_out[2] is True
    emulator.nck.programs.write("/_N_MPF_DIR/_N_IO2_MPF", b"R1=$A_DBB[5000]\nM30\n")
    result = run_offline(emulator, "/_N_MPF_DIR/_N_IO2_MPF", max_time_s=60.0)
    assert "alarm 12550" in result.alarms[0] and "byte offsets" in result.alarms[0]


def test_a_users_cycle_under_mcall_is_not_called_again_by_its_own_moves() -> None:
    """A shop's own CYCLE82.SPF moves the axes; under MCALL CYCLE82 those moves do not call it again."""
    emulator = _emulator()
    emulator.nck.programs.write("/_N_SPF_DIR/_N_CYCLE82_SPF", b"PROC CYCLE82(REAL RTP, REAL DP)\n"
                                                              b"G1 Z=DP F500\nG0 Z=RTP\nR5=R5+1\nM17\n")
    _run(emulator, "HOLES", b"G0 X10 Y10 Z-10\nMCALL CYCLE82(-10, -30)\nX20\nX30 Y20\nMCALL\nX40\nM30\n")
    assert emulator.nck.store.read_lines(emulator.nck.store.spec("R"), 1, 6, 1)[0] == 2.0


def test_positions_feed_and_time_a_program_reads_after_a_move() -> None:
    emulator = _emulator()
    _run(emulator, "READS", b"G0 X10 Y5\nG1 X20 F600\nR30=$AA_IM[X] R31=$P_EP[X] R32=$P_F R33=$AA_IW[X]\n"
                            b"G4 F2\nR34=$AC_TIME R35=$P_TOOLNO\nM30\n")
    store = emulator.nck.store
    r = store.read_lines(store.spec("R"), 1, 31, 6)
    assert r[:4] == [pytest.approx(20.0), 20.0, 600.0, pytest.approx(20.0)]
    assert 0.0 <= r[4] < 1.0 and r[5] >= 0  # $AC_TIME: since the block's start; no tool changed


VALUES_TEXT = b"""%_N_WHEEL_GUD
;$PATH=/_N_DEF_DIR
CHANDATA(1)
N10 INI[5]=3 INI[53]=1500 ; wheel speed
AXIS_VER="X"
COUNTS[1]=2*3
M17
"""


def test_a_gud_value_file_assigns_what_an_operator_entered_before_the_program_runs() -> None:
    emulator = _emulator()
    programs = emulator.nck.programs
    programs.write(MGUD, GUD_TEXT)
    programs.write("/_N_DEF_DIR/_N_WHEEL_GUD", VALUES_TEXT)
    assert (_gud(emulator, "INI", 5), _gud(emulator, "INI", 53), _gud(emulator, "AXIS_VER")) == (3.0, 1500.0, "X")
    assert _gud(emulator, "COUNTS", 1) == 6 and _gud(emulator, "COUNTS", 2) == 3  # the DEF's SET stays
    _run(emulator, "GRIND", b"R1=360/INI[5]\nG0 AX[AXNAME(AXIS_VER)]=R1\nM30\n")
    assert emulator.nck.axes.positions_mm[1] == pytest.approx(120.0)


@pytest.mark.parametrize(("text", "line", "number", "says"), [
    (b"INI[5]=3\nNO_SUCH[1]=2\n", 2, 12550, "NO_SUCH not defined"),
    (b"INI[5]=3\nINI[100]=1\n", 2, 17020, "outside 0..99"),
    (b'INI[5]=3\nINI[6]="text"\n', 2, 12150, "not a number"),
    (b"CHANDATA(2)\nINI[5]=3\n", 1, 12080, "channel 1"),
    (b"INI[5]=3\nINI[6]=SAFE_Z\n", 2, 12550, "SAFE_Z"),
    (b"INI[5]=3\nG1 X10\n", 2, 12550, "G1 not defined"),
])
def test_a_gud_value_file_with_an_error_is_refused_whole_with_its_line(text: bytes, line: int, number: int,
                                                                       says: str) -> None:
    emulator = _emulator()
    programs = emulator.nck.programs
    programs.write(MGUD, GUD_TEXT)
    with pytest.raises(DefinitionRefused) as refused:
        programs.write("/_N_DEF_DIR/_N_BAD_GUD", text)
    alarm = refused.value.alarm
    assert (alarm.number, alarm.program, alarm.line) == (number, "/_N_DEF_DIR/_N_BAD_GUD", line), alarm
    assert says in str(alarm)
    assert _gud(emulator, "INI", 5) == 0.0 and not programs.exists("/_N_DEF_DIR/_N_BAD_GUD")


def test_program_run_stores_definitions_before_the_gud_values_beside_the_program(tmp_path, capsys) -> None:
    from nckemu.cli import main

    (tmp_path / "ZVALUES.GUD").write_bytes(b"INI[5]=4\nM17\n")
    (tmp_path / "MGUD.DEF").write_bytes(GUD_TEXT)
    (tmp_path / "GRIND.MPF").write_bytes(b"R1=360/INI[5]\nM30\n")
    assert main(["program", "run", str(tmp_path / "GRIND.MPF"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["outcome"] == "ended"


PLC_ANSWERS = """
[nck_io]
initial = { "$A_IN[22]" = 1, "$A_DBB[12]" = 1 }

[[nck_io.answer]]
m = 48                                     # close the guard
set = { "$A_IN[10]" = 1, "$A_IN[9]" = 0 }
after_s = 2.0

[[nck_io.answer]]
m = 47                                     # open it
set = { "$A_IN[9]" = 1, "$A_IN[10]" = 0 }
after_s = 1.5

[[nck_io.answer]]
out = 5                                    # the program asks for the part
set = { "$A_DBB[30]" = 1 }
after_s = 0.4
"""


def _answering_machine(tmp_path) -> str:
    from nckemu.emulator.machine.machine_file import machine_text

    path = tmp_path / "answers.toml"
    path.write_text(machine_text(None)[0] + PLC_ANSWERS)
    return str(path)


def test_the_machine_files_plc_answers_the_programs_m_functions_and_outputs_on_time(tmp_path, capsys) -> None:
    from nckemu.cli import main

    program = tmp_path / "GUARD.MPF"
    # times by hand: M48 at 0 s, the guard reads closed from 2.0 s: ten dwells of 0.2 s; $A_OUT[5] at
    # 2.0 s, the part there at 2.4 s: two dwells; M47 at 2.4 s, open at 3.9 s: eight dwells (4.0 s)
    program.write_bytes(b"R1=$A_IN[22]+$A_DBB[12]\nM48\nWHILE ($A_IN[10]==0) OR ($A_IN[9]==1)\n  G4 F0.2\n"
                        b"ENDWHILE\nR2=$AC_TIME\n$A_OUT[5]=1\nWHILE $A_DBB[30]==0\n  G4 F0.2\nENDWHILE\n"
                        b"M47\nWHILE $A_IN[9]==0\n  G4 F0.2\nENDWHILE\nM30\n")
    assert main(["program", "run", str(program), "--machine", _answering_machine(tmp_path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["outcome"] == "ended"
    assert summary["net_time_s"] == pytest.approx(2.0 + 0.4 + 1.6, abs=1e-3)


def test_without_answers_the_program_waits_for_its_plc(tmp_path) -> None:
    emulator = _emulator()
    emulator.nck.programs.write("/_N_MPF_DIR/_N_WAIT_MPF", b"M48\nWHILE $A_IN[10]==0\n  G4 F0.2\nENDWHILE\nM30\n")
    assert run_offline(emulator, "/_N_MPF_DIR/_N_WAIT_MPF", max_time_s=30.0).outcome == "timeout"
    emulator = Emulator(_answering_machine(tmp_path), clock=SimulatedClock())
    emulator.nck.programs.write("/_N_MPF_DIR/_N_WAIT_MPF", b"M48\nWHILE $A_IN[10]==0\n  G4 F0.2\nENDWHILE\nM30\n")
    assert run_offline(emulator, "/_N_MPF_DIR/_N_WAIT_MPF", max_time_s=30.0).outcome == "ended"


@pytest.mark.parametrize(("table", "field"), [
    ('[nck_io]\ninitial = { "$A_OUT[1]" = 1 }', "nck_io.initial"),
    ('[nck_io]\ninitial = { "$A_IN[65]" = 1 }', "nck_io.initial"),
    ('[[nck_io.answer]]\nset = { "$A_IN[1]" = 1 }', "nck_io.answer[0].m"),
    ('[[nck_io.answer]]\nm = 48\nout = 2\nset = { "$A_IN[1]" = 1 }', "nck_io.answer[0].m"),
    ('[[nck_io.answer]]\nm = 48', "nck_io.answer[0].set"),
    ('[[nck_io.answer]]\nm = 48\nafter_s = -1\nset = { "$A_IN[1]" = 1 }', "nck_io.answer[0].after_s"),
    ('[[nck_io.answer]]\nm = 48\nwhen = 1\nset = { "$A_IN[1]" = 1 }', "nck_io.answer[0].when"),
    ('[nck_io]\ninputs = [1]', "nck_io.inputs"),
])
def test_a_faulty_nck_io_table_is_refused_naming_its_field(table: str, field: str) -> None:
    from nckemu.emulator.machine.machine_file import machine_text, parse_machine
    from nckemu.errors import NckConfigError

    with pytest.raises(NckConfigError) as refused:
        parse_machine(machine_text(None)[0] + "\n" + table + "\n")
    assert refused.value.field == field, refused.value


def test_an_r_value_file_sets_channel_1s_r_parameters_or_is_refused_whole() -> None:
    emulator = _emulator()
    programs, store = emulator.nck.programs, emulator.nck.store
    programs.write("/_N_DEF_DIR/_N_TAP_RPA", b"%_N_TAP_RPA\nCHANDATA(1)\nR1=2.5 R[8]=4 ; pitch, flutes\nR99=-1\nM17\n")
    assert store.read_lines(store.spec("R"), 1, 2, 1) == [2.5]
    assert store.read_lines(store.spec("R"), 1, 9, 1) == [4.0] and store.read_lines(store.spec("R"), 1, 100, 1) == [-1.0]
    with pytest.raises(DefinitionRefused) as refused:
        programs.write("/_N_DEF_DIR/_N_BAD_RPA", b"R1=7\nR100=1\n")
    alarm = refused.value.alarm
    assert (alarm.number, alarm.line) == (12550, 2) and "R0...R99" in str(alarm)
    assert store.read_lines(store.spec("R"), 1, 2, 1) == [2.5]
    with pytest.raises(DefinitionRefused):
        programs.write("/_N_DEF_DIR/_N_BAD_RPA", b"INI[5]=1\n")
    _run(emulator, "TAP", b"R2=R1*R8\nM30\n")
    assert store.read_lines(store.spec("R"), 1, 3, 1) == [10.0]


def test_an_inch_machine_reads_f_in_inch_per_minute_under_g70_and_g71(tmp_path, capsys) -> None:
    from nckemu.cli import main
    from nckemu.emulator.machine.machine_file import machine_text

    machine = tmp_path / "inch.toml"
    machine.write_text(machine_text(None)[0] + "\n[program]\ninch_basic_system = true\n")
    program = tmp_path / "INCH.MPF"
    # by hand: 1 in at F10 in/min is 6 s; G71 X2 (mm) from 25.4 mm is 23.4 mm at 10 in/min (254 mm/min),
    # 5.528 s; G710 X12 is 10 mm at F254 mm/min, 2.362 s; the ramps of a slow feed take milliseconds
    program.write_bytes(b"G1 X1 F10\nG71 X2\nG710 X12 F254\nM30\n")
    assert main(["program", "run", str(program), "--machine", str(machine), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["outcome"] == "ended"
    assert summary["net_time_s"] == pytest.approx(6.0 + 23.4 / 254 * 60 + 10 / 254 * 60, abs=0.05)
    program.write_bytes(b"G70 G1 X1 F10\nM30\n")  # on a metric machine G70 leaves F in mm/min: 25.4 mm at 10
    assert main(["program", "run", str(program), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["net_time_s"] == pytest.approx(152.4, abs=0.05)
