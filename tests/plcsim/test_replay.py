"""``nckemu plc run --inputs``: a program driven by a recording, on the emulator, row by row."""

from __future__ import annotations

import bisect
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.plcsim.replay import run_on_recording
from nckemu.thermal.recordings.recording import Recording, load_recording, write_recording

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
BED_RAMP = FIXTURES / "machines" / "bed_ramp.toml"
TC_Z = FIXTURES / "plc" / "tc_z.awl"
BED_ONLY = FIXTURES / "plc" / "bed_only_z.awl"
LOOP_MILL = FIXTURES / "machines" / "loop_mill.toml"


def seed000_law_um(temperature_C: np.ndarray) -> np.ndarray:
    """Seed 000: nothing up to 30 degC, then 0.3 mm per 10 K (Z grows, so the error is positive)."""
    return np.where(temperature_C > 30.0, (temperature_C - 30.0) / 10.0 * 300.0, 0.0)


def bed_recording(path: Path, seconds: int = 7200, step_s: int = 10) -> Recording:
    t = np.arange(0.0, seconds + 1.0, step_s)
    bed = 25.0 + 25.0 * t / seconds  # 25 -> 50 degC: through the 30 degC knee
    recording = Recording(str(path), t, {"temp_bed_C": bed}, None, {"Z": np.full_like(t, -1000.0)},
                          {"Z": seed000_law_um(bed)})
    write_recording(path, recording)
    return load_recording(path)


@pytest.fixture(scope="module")
def seed000_run(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    recording = bed_recording(tmp_path_factory.mktemp("rec") / "bed.csv")
    return recording, run_on_recording(TC_Z, BED_RAMP, recording, "Z", cycle_s=1.0, progress=False)


def test_sign_against_seed000(seed000_run) -> None:  # type: ignore[no-untyped-def]
    """40 degC -> K0 = 0.3 mm at Z = -1000: sim is +300 um, the error it cancels, so err - sim ~ 0."""
    recording, run = seed000_run
    row = int(np.argmin(np.abs(recording.temperatures_C["temp_bed_C"] - 40.0)))
    assert run.sim_um[row] == pytest.approx(300.0, abs=12.0)  # the program writes once a minute
    assert abs(recording.errors_um["Z"][row] - run.sim_um[row]) < 12.0
    assert run.log.errors == []


def test_sim_follows_the_law_row_by_row(seed000_run) -> None:  # type: ignore[no-untyped-def]
    recording, run = seed000_run
    t, bed = recording.t_s, recording.temperatures_C["temp_bed_C"]
    puts = run.log.puts
    assert len(puts) >= 110
    put_times = [p.time_s + run.clock_offset_s for p in puts]  # on the recording's time
    # What each PUT carried is the law at the temperature of its cycle (PIW quantization: 0.004 K).
    for put, time_s in zip(puts, put_times, strict=True):
        assert put.values["SD1"] * 1000.0 == pytest.approx(
            float(seed000_law_um(np.interp(time_s, t, bed))), abs=1.5)
    # What the NCK applies at each row is the last PUT at or before it: sampled one IPO cycle after the
    # row, and the MD32760 ramp covers one PUT's step within that cycle here.
    for row, time_s in enumerate(t):
        index = bisect.bisect_right(put_times, time_s) - 1
        assert index >= 0, "the program has written before the first row (two minutes of warm-up)"
        expected = puts[index].values["SD1"] * 1000.0
        assert run.sim_um[row] == pytest.approx(expected, abs=0.01), f"row {row}, t = {time_s} s"


def test_cli_writes_sim_column(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from nckemu.cli import main

    bed_recording(tmp_path / "rec.csv", seconds=600)
    out = tmp_path / "sim.csv"
    assert main(["plc", "run", str(TC_Z), "--machine", str(BED_RAMP), "--inputs", str(tmp_path / "rec.csv"),
                 "--out", str(out), "--axis", "Z"]) == 0
    written = load_recording(out)
    assert "Z" in written.simulated_um and len(written.t_s) == 61
    assert "RMS error" in capsys.readouterr().out
    assert not list(tmp_path.glob(".*partial"))


# ---------------------------------------------------------------------- bad input: one line, exit 1
def _machine_without_letter(tmp_path: Path) -> Path:
    text = BED_RAMP.read_text().replace('name = "Z1"', 'name = "4"')
    path = tmp_path / "noletter.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("case", ["missing_sensor_column", "no_ob1", "no_recording_letter", "time_backwards"])
def test_bad_input_one_line_exit_1_no_output(case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from nckemu.cli import main

    rec = tmp_path / "rec.csv"
    bed_recording(rec, seconds=300)
    program, machine, expected = TC_Z, BED_RAMP, ""
    if case == "missing_sensor_column":
        rows = [line.split(",") for line in rec.read_text().splitlines()]
        rec.write_text("\n".join(",".join(r[:1] + r[2:]) for r in rows) + "\n")
        expected = "no column 'temp_bed_C'"
    elif case == "no_ob1":
        program = tmp_path / "no_ob1.awl"
        text = TC_Z.read_text()
        program.write_text(text[:text.index("ORGANIZATION_BLOCK")])
        expected = "no ORGANIZATION_BLOCK OB 1"
    elif case == "no_recording_letter":
        machine = _machine_without_letter(tmp_path)
        expected = "no machine axis has the recording letter 'Z'"
    elif case == "time_backwards":
        lines = rec.read_text().splitlines()
        lines[5], lines[6] = lines[6], lines[5]
        rec.write_text("\n".join(lines) + "\n")
        expected = "does not increase"
    out = tmp_path / "sim.csv"
    status = main(["plc", "run", str(program), "--machine", str(machine), "--inputs", str(rec), "--out", str(out),
                   "--axis", "Z"])
    err = capsys.readouterr().err.strip()
    assert status == 1
    assert len(err.splitlines()) == 1 and expected in err and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.glob(".*partial"))


@settings(max_examples=5, deadline=None)
@given(st.lists(st.floats(0.0, 1500.0, allow_nan=False), min_size=3, max_size=40, unique=True),
       st.sampled_from([0.5, 1.0, 2.5, 7.0]), st.integers(0, 2 ** 16))
def test_any_time_base_samples_what_the_nck_applies(times: list[float], cycle_s: float, seed: int) -> None:
    """Irregular rows, any cycle: each PUT carries the law at its cycle's interpolated input, and each row
    shows the last PUT before it."""
    rng = np.random.default_rng(seed)
    t = np.asarray(sorted(times))
    if np.min(np.diff(t)) < 1e-3:
        return
    bed = 20.0 + np.cumsum(rng.normal(0.0, 0.5, len(t)))
    recording = Recording("<rows>", t, {"temp_bed_C": bed, "temp_spindle_C": np.full_like(t, 20.0)}, None, {},
                          {"Z": np.zeros_like(t)})
    run = run_on_recording(BED_ONLY, LOOP_MILL, recording, "Z", cycle_s=cycle_s, progress=False)
    times_put = [p.time_s + run.clock_offset_s for p in run.log.puts]
    for put, time_s in zip(run.log.puts, times_put, strict=True):
        law_um = 2.0 * (float(np.interp(time_s, t, bed)) - 20.0)
        assert put.values["SD1"] * 1000.0 == pytest.approx(law_um, abs=0.02)
    for row, time_s in enumerate(t):
        index = bisect.bisect_right(times_put, time_s) - 1
        if index < 0 or time_s - times_put[index] < 0.1:
            continue  # the MD32760 ramp may still be on its way
        assert run.sim_um[row] == pytest.approx(run.log.puts[index].values["SD1"] * 1000.0, abs=1e-6)


GET_ACT_SPEED = """
DATA_BLOCK DB 10
STRUCT
  ACT_SPEED : STRUCT
    SYNTAX_ID : BYTE := B#16#82;
    bereich_u_einheit : BYTE := B#16#41;
    spalte : WORD := W#16#2;
    zeile : WORD := W#16#1;
    bausteintyp : BYTE := B#16#72;
    ZEILENANZAHL : BYTE := B#16#1;
    typ : BYTE := B#16#F;
    laenge : BYTE := B#16#8;
  END_STRUCT;
END_STRUCT;
BEGIN
END_DATA_BLOCK

DATA_BLOCK DB 11
STRUCT
  RPM : REAL := -1.0;
END_STRUCT;
BEGIN
END_DATA_BLOCK

DATA_BLOCK DB 12
FB 2
BEGIN
END_DATA_BLOCK

ORGANIZATION_BLOCK OB 1
BEGIN
  AN M 1.0
  = M 1.1
  CALL FB 2, DB 12 (
    Req := M 1.1,
    NumVar := 1,
    Addr1 := DB10.ACT_SPEED,
    Error := M 1.2,
    NDR := M 1.3,
    State := MW 2,
    RD1 := DB11.RPM
  )
  A M 1.1
  S M 1.0
  A M 1.3
  O M 1.2
  R M 1.0
END_ORGANIZATION_BLOCK
"""


def test_the_recording_drives_the_nck_spindle_speed(tmp_path: Path) -> None:
    """With spindle_rpm in the recording, FB2 GET of actSpeed (spindle 1) reads the recorded speed of its cycle."""
    program = tmp_path / "get_speed.awl"
    program.write_text(GET_ACT_SPEED)
    t = np.arange(0.0, 600.0, 10.0)
    rpm = np.where(t < 300.0, 1500.0, 8000.0) + t   # a step, and a ramp so every request reads a new value
    recording = Recording("<rpm>", t, {"temp_bed_C": np.full_like(t, 20.0), "temp_spindle_C": np.full_like(t, 20.0)},
                          rpm, {}, {"Z": np.zeros_like(t)})
    run = run_on_recording(program, LOOP_MILL, recording, "Z", cycle_s=1.0, progress=False)
    assert run.log.errors == []
    gets = [g for g in run.log.gets if g.time_s + run.clock_offset_s >= t[0]]
    gets = [g for g in gets if "RD1" in g.values]   # the last request may still be on its way
    assert len(gets) >= 250   # a request every other cycle
    for get in gets:
        time_s = get.time_s + run.clock_offset_s
        assert get.values["RD1"] == pytest.approx(float(np.interp(time_s, t, rpm)), abs=1e-9)
    assert min(g.values["RD1"] for g in gets) == 1500.0 and max(g.values["RD1"] for g in gets) > 8500.0
