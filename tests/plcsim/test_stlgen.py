"""The generated STL program: loads in awlsim, reads only declared inputs, and its 32-bit REALs stay
within 0.1 um of the float64 model on a recording."""

from __future__ import annotations

import json
import math
import re
import struct
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nckemu.emulator.machine.machine_file import Machine, load_machine, parse_machine
from nckemu.plcsim.bridge import PlcRunner
from nckemu.plcsim.replay import RecordingRun, recording_axis, run_on_recording
from nckemu.plcsim.stlgen import STATE_DB, generate_program, lag_coefficient
from nckemu.thermal.model.lags import first_order_lag
from nckemu.thermal.model.terms import Term, ThermalModel
from nckemu.thermal.recordings.recording import Recording
from nckemu.thermal.synthetic.scenarios import make_loop_scenario

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
MACHINE = load_machine(FIXTURES / "machines" / "loop_mill.toml")
AXIS = recording_axis(MACHINE, "Z")
# The same mill with the spindle speed on PIW 424 (0..10000 rpm = 0..27648).
MACHINE_RPM = parse_machine((FIXTURES / "machines" / "loop_mill.toml").read_text()
                            + '\n[[sensor]]\nname = "spindle_rpm"\nplc_input = "PIW424"\nraw_per_C = 2.7648\n',
                            "loop_mill + spindle speed")
# The same mill without a spindle: nothing carries the spindle speed to the PLC.
MACHINE_NO_SPINDLE = parse_machine((FIXTURES / "machines" / "loop_mill.toml").read_text().replace("spindle = true\n", ""),
                                   "loop_mill without a spindle")


def _probe(name: str) -> Callable[[PlcRunner], float]:
    def read(runner: PlcRunner) -> float:
        db = runner.sim.cpu.getDB(STATE_DB)
        offset = db.struct.getField(name).offset.byteOffset
        return float(struct.unpack_from(">f", bytes(db.structInstance.memory.getDataBytes()), offset)[0])
    return read


def plc_run(model: ThermalModel, recording: Recording, cycle_s: float, tmp_path: Path,
            machine: Machine = MACHINE) -> tuple[np.ndarray, RecordingRun, str]:
    """What the generated program computes at each row: K0 + tan beta * position, in um."""
    program = generate_program(model, machine, AXIS, cycle_s)
    assert program.not_compensable == []
    path = tmp_path / "generated.awl"
    path.write_text(program.text)
    probes = {"k0": _probe("K0_MM"), "tan_beta": _probe("TAN_BETA")}
    if any(t.effect == "centrifugal_growth" for t in model.terms):
        probes["rpm"] = _probe("T_SPINDLE_RPM")
    run = run_on_recording(path, machine, recording, "Z", cycle_s, progress=False, probes=probes)
    assert run.log.errors == []
    return (run.probes["k0"] + run.probes["tan_beta"] * recording.positions_mm["Z"]) * 1000.0, run, program.text


def plc_values_um(model: ThermalModel, recording: Recording, cycle_s: float, tmp_path: Path,
                  machine: Machine = MACHINE) -> np.ndarray:
    return plc_run(model, recording, cycle_s, tmp_path, machine)[0]


EVERY_EFFECT = ThermalModel("Z", [
    Term("offset", {"value_um": -1.5}),
    Term("temperature", {"sensor": "bed", "t_ref_C": 20.0, "coeff_um_per_K": 2.0}),
    Term("thermal_lag", {"sensor": "spindle", "t_ref_C": 20.0, "tau_s": 2400.0, "coeff_um_per_K": 3.0}),
    Term("quadratic_temperature", {"sensor": "spindle", "t_ref_C": 20.0, "coeff_um_per_K2": 0.08}),
    Term("thermal_gradient", {"sensors": ["spindle", "bed"], "coeff_um_per_K": -1.2}),
    Term("heating_cooling_hysteresis", {"sensor": "bed", "t_ref_C": 20.0, "tau_heat_s": 1800.0,
                                        "tau_cool_s": 5400.0, "coeff_um_per_K": 0.7}),
    Term("position_dependent_expansion", {"sensor": "bed", "t_ref_C": 20.0, "p0_mm": 0.0,
                                          "slope_um_per_m_per_K": 11.5}),
    Term("centrifugal_growth", {"coeff_um_per_krpm2": -0.05}),
    Term("transient_gradient", {"sensor": "spindle", "tau_s": 5400.0, "coeff_um_per_K": 4.0}),
    Term("gain_error", {"gain": 1.1}),
])


def test_float32_program_within_0_1_um_of_the_float64_model(tmp_path: Path) -> None:
    recording = make_loop_scenario(seed=2).recording   # 36 h, one row a minute
    plc, _run, text = plc_run(EVERY_EFFECT, recording, 60.0, tmp_path, MACHINE_RPM)
    assert "L PIW 424" in text and "CALL FB 2" not in text   # the wired speed input, no GET
    reference = EVERY_EFFECT.predict_um(recording)
    assert float(np.max(np.abs(plc - reference))) < 0.1


def test_spindle_speed_by_fb2_get_within_0_1_um_of_the_float64_model(tmp_path: Path) -> None:
    """No speed input but a spindle: FB2 GET of actSpeed, which the recording's spindle_rpm drives."""
    recording = make_loop_scenario(seed=2).recording
    assert recording.spindle_rpm is not None and np.ptp(recording.spindle_rpm) > 5000.0
    plc, run, text = plc_run(EVERY_EFFECT, recording, 60.0, tmp_path, MACHINE)
    assert "CALL FB 2, DB 153" in text and "FB2 GET actSpeed" in text and "PIW424" not in text
    gets = [g for g in run.log.gets if "RD1" in g.values]
    assert len(gets) > len(recording.t_s) / 3
    # The speed the program used at each row: the recording's one or two cycles (60 s) before.
    rpm = run.probes["rpm"]
    t = recording.t_s
    earlier = [np.interp(t - lag_s, t, recording.spindle_rpm).astype(np.float32) for lag_s in (60.0, 120.0)]
    settled = t >= t[0] + 120.0
    assert np.all(((rpm == earlier[0]) | (rpm == earlier[1]))[settled])
    assert float(np.mean((rpm != recording.spindle_rpm.astype(np.float32))[settled])) < 0.2  # the speed steps rarely
    # And the compensation is the float64 model on that speed.
    used = Recording(recording.source, t, recording.temperatures_C, rpm.astype(float), recording.positions_mm,
                     recording.errors_um)
    assert float(np.max(np.abs(plc - EVERY_EFFECT.predict_um(used))[settled])) < 0.1


def test_only_declared_inputs_and_the_rest_listed_as_not_compensable() -> None:
    model = ThermalModel("Z", [
        Term("temperature", {"sensor": "bed", "t_ref_C": 20.0, "coeff_um_per_K": 2.0}),
        Term("temperature", {"sensor": "front", "t_ref_C": 20.0, "coeff_um_per_K": 1.0}),
        Term("time_drift", {"um_per_h": 0.25}),
        Term("centrifugal_growth", {"coeff_um_per_krpm2": -0.05})])
    program = generate_program(model, MACHINE_NO_SPINDLE, AXIS)
    declared = {s.plc_input for s in MACHINE.sensors}
    used = {f"PIW{n}" for n in re.findall(r"L PIW (\d+)", program.text)}
    assert used == {"PIW420"} and used <= declared
    listed = {item["effect"] for item in program.not_compensable}
    assert listed == {"temperature", "time_drift", "centrifugal_growth"}
    assert all(item["why"].startswith("not compensable in the PLC") for item in program.not_compensable)
    assert program.text.count("// not compensable in the PLC:") == 3
    assert not program.position_dependent and "MD32750" not in program.text


@given(st.floats(0.05, 10.0), st.floats(30.0, 20000.0), st.integers(1, 500), st.floats(-20.0, 20.0),
       st.floats(-20.0, 20.0))
def test_discrete_lag_is_the_continuous_solution(cycle_s: float, tau_s: float, cycles: int, start: float,
                                                 target: float) -> None:
    """For an input held over each cycle the recursion is exact: x(n) = u + (x0 - u) exp(-n dt / tau)."""
    alpha = lag_coefficient(cycle_s, tau_s)
    state = start
    for _ in range(cycles):
        state += alpha * (target - state)
    exact = target + (start - target) * math.exp(-cycles * cycle_s / tau_s)
    assert state == pytest.approx(exact, abs=1e-9 * (1 + abs(start) + abs(target)))
    t = np.arange(cycles + 1) * cycle_s
    signal = np.full(cycles + 1, target)
    signal[0] = start
    assert first_order_lag(t, signal, tau_s)[-1] == pytest.approx(exact, abs=1e-9 * (1 + abs(start) + abs(target)))


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(-5.0, 5.0), st.floats(-8.0, 8.0), st.floats(60.0, 20000.0), st.floats(-0.2, 0.2),
       st.floats(0.5, 2.0), st.integers(0, 2 ** 16))
def test_float32_program_against_float64_model_property(tmp_path: Path, coeff_bed: float, coeff_lag: float,
                                                        tau_s: float, quadratic: float, gain: float,
                                                        walk_seed: int) -> None:
    rng = np.random.default_rng(walk_seed)
    t = np.arange(0.0, 600.0, 1.0)
    bed = 20.0 + np.cumsum(rng.normal(0.0, 0.05, len(t)))
    spindle = 25.0 + np.cumsum(rng.normal(0.0, 0.2, len(t)))
    recording = Recording("<walk>", t, {"temp_bed_C": bed, "temp_spindle_C": spindle}, None,
                          {"Z": np.full_like(t, -500.0)}, {"Z": np.zeros_like(t)})
    model = ThermalModel("Z", [
        Term("temperature", {"sensor": "bed", "t_ref_C": 20.0, "coeff_um_per_K": coeff_bed}),
        Term("thermal_lag", {"sensor": "spindle", "t_ref_C": 20.0, "tau_s": tau_s, "coeff_um_per_K": coeff_lag}),
        Term("quadratic_temperature", {"sensor": "spindle", "t_ref_C": 20.0, "coeff_um_per_K2": quadratic}),
        Term("gain_error", {"gain": gain})])
    plc = plc_values_um(model, recording, 1.0, tmp_path)
    # The PLC reads quantized PIW words (1/276.48 K): the float64 model on those same inputs.
    quantized = Recording("<walk>", t, {k: np.round(v * 276.48) / 276.48 for k, v in recording.temperatures_C.items()},
                          None, recording.positions_mm, recording.errors_um)
    assert float(np.max(np.abs(plc - model.predict_um(quantized)))) < 0.1


def test_plc_run_warns_when_md32750_bit_1_is_missing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from nckemu.cli import main
    from nckemu.thermal.recordings.recording import write_recording

    model = ThermalModel("Z", [Term("position_dependent_expansion", {"sensor": "bed", "t_ref_C": 20.0, "p0_mm": -100.0,
                                                                     "slope_um_per_m_per_K": 11.5})])
    program = generate_program(model, MACHINE, AXIS)
    assert program.position_dependent and "MD32750 bit 1" in program.text
    (tmp_path / "pos.awl").write_text(program.text)
    recording = make_loop_scenario(seed=1, duration_h=0.5).recording
    write_recording(tmp_path / "rec.csv", recording)
    args = ["plc", "run", str(tmp_path / "pos.awl"), "--machine", str(FIXTURES / "machines" / "loop_mill.toml"),
            "--inputs", str(tmp_path / "rec.csv"), "--axis", "Z", "--json"]
    assert main(args) == 0
    assert "does not set MD32750 bit 1 for axis 4" in capsys.readouterr().err
    fixed = tmp_path / "bit1.toml"
    fixed.write_text((FIXTURES / "machines" / "loop_mill.toml").read_text().replace("MD32750 = { 4 = 1 }",
                                                                                     "MD32750 = { 4 = 3 }"))
    args[4] = str(fixed)
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "MD32750" not in captured.err
    summary = json.loads(captured.out)
    # With bit 1 set the NCK applies tan beta * (P - P0): the generated program's compensation follows the model.
    assert summary["rms_residual_um"] < summary["rms_error_um"] or summary["sim_max_um"] != 0.0


def test_position_dependent_program_on_the_nck_follows_the_model(tmp_path: Path) -> None:
    """With MD32750 bit 1 the NCK applies K0 + tan beta (P - P0) from the generated SD43910/43920."""
    model = ThermalModel("Z", [
        Term("temperature", {"sensor": "bed", "t_ref_C": 20.0, "coeff_um_per_K": 2.0}),
        Term("position_dependent_expansion", {"sensor": "bed", "t_ref_C": 20.0, "p0_mm": -100.0,
                                              "slope_um_per_m_per_K": 11.5})])
    machine = parse_machine((FIXTURES / "machines" / "loop_mill.toml").read_text()
                            .replace("MD32750 = { 4 = 1 }", "MD32750 = { 4 = 3 }"), "loop_mill, MD32750 = 3")
    program = generate_program(model, machine, AXIS, cycle_s=1.0)
    (tmp_path / "pos.awl").write_text(program.text)
    t = np.arange(0.0, 1800.0, 1.0)
    bed = 20.0 + 10.0 * t / 1800.0
    position = -1000.0 + 1000.0 * (t % 600.0) / 600.0   # a sawtooth over the whole travel
    recording = Recording("<saw>", t, {"temp_bed_C": bed, "temp_spindle_C": np.full_like(t, 20.0)}, None,
                          {"Z": position}, {"Z": np.zeros_like(t)})
    run = run_on_recording(tmp_path / "pos.awl", machine, recording, "Z", 1.0, progress=False)
    assert run.warnings == [] and run.log.errors == []
    settled = (t % 600.0) >= 5.0   # the MD32760 ramp after each jump back to -1000 mm
    # Exactly what the NCK does with the last PUT: K0 + tan beta (P - P0), at the position of the row.
    put_times = np.asarray([p.time_s + run.clock_offset_s for p in run.log.puts])
    last = np.searchsorted(put_times, t + 1e-6, side="right") - 1  # a job is awaited within its cycle
    applied = np.asarray([1000.0 * (run.log.puts[i].values["SD1"] + run.log.puts[i].values["SD2"]
                                    * (p - run.log.puts[i].values["SD3"])) for i, p in zip(last, position, strict=True)])
    assert float(np.max(np.abs(run.sim_um - applied)[settled])) < 1e-3
    # And the model, up to one write period (10 s + two cycles) of a temperature rising 10 K in 30 min.
    expected = model.predict_um(recording)
    assert float(np.max(np.abs(run.sim_um - expected)[settled])) < 12.0 * 10.0 / 1800.0 * (2.0 + 11.5 * 0.9)
    assert float(np.max(np.abs(expected))) > 50.0   # the position part matters: up to -100 um


def test_plc_run_inputs_runs_the_fb2_get_program(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`plc run --inputs` loads the generated program with FB2 GET in awlsim and runs it on a recording."""
    from nckemu.cli import main
    from nckemu.thermal.recordings.recording import write_recording

    model = ThermalModel("Z", [Term("temperature", {"sensor": "bed", "t_ref_C": 20.0, "coeff_um_per_K": 2.0}),
                               Term("centrifugal_growth", {"coeff_um_per_krpm2": -0.05})])
    program = generate_program(model, MACHINE, AXIS, cycle_s=1.0)
    assert program.not_compensable == [] and "CALL FB 2" in program.text
    (tmp_path / "get.awl").write_text(program.text)
    write_recording(tmp_path / "rec.csv", make_loop_scenario(seed=1, duration_h=2.0).recording)
    assert main(["plc", "run", str(tmp_path / "get.awl"), "--machine", str(FIXTURES / "machines" / "loop_mill.toml"),
                 "--inputs", str(tmp_path / "rec.csv"), "--axis", "Z", "--out", str(tmp_path / "sim.csv"),
                 "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["errors"] == [] and summary["puts"] > 0
    assert (tmp_path / "sim.csv").is_file()
