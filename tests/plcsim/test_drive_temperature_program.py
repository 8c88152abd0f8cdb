"""An STL program that compensates Z from a drive temperature (issue 32): FB2 GET reads r0035 of the
spindle drive (area V, a REAL4) once a minute and FB3 PUT writes K0 from it, run by `plc run`."""

from __future__ import annotations

from pathlib import Path

import pytest

from nckemu.plcsim.run import run_program

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
PROGRAM = FIXTURES / "plc" / "drive_temp_z.awl"


def warming_lathe(tmp_path: Path) -> Path:
    """The 828D lathe with its spindle motor warming from 25 to 55 degC over the first hour."""
    text = (FIXTURES / "machines" / "lathe_828d.toml").read_text(encoding="utf-8")
    warming = text.replace('name = "spindle_motor"\ntemperature_C = 32.0',
                           'name = "spindle_motor"\nprofile = [[0.0, 25.0], [3600.0, 55.0]]')
    assert warming != text
    path = tmp_path / "warming_lathe.toml"
    path.write_text(warming, encoding="utf-8")
    return path


def test_k0_follows_the_spindle_motor_temperature_read_from_the_drive(tmp_path: Path) -> None:
    run = run_program(PROGRAM, machine=warming_lathe(tmp_path), duration_s=5400.0, axis=2, sensor="spindle_motor")
    gets, puts = run.log.gets, run.log.puts
    assert len(gets) >= 80 and all(job.return_codes == [0xFF] for job in gets)
    assert len(puts) == len(gets) and all(job.return_codes == [0xFF] for job in puts)
    # each PUT carries 0.01 mm per K above 30 degC of the temperature its GET read
    for put in puts:
        expected = max(0.0, (25.0 + 30.0 * min(put.time_s, 3600.0) / 3600.0) - 30.0) * 0.01
        assert put.values["SD1"] == pytest.approx(expected, abs=0.01 * 30.0 * 62.0 / 3600.0 + 1e-6)
    assert puts[0].values["SD1"] == 0.0                       # 25 degC at the start: below 30
    final = run.samples[-1]
    assert final.sensor_C == pytest.approx(55.0) and final.tc_value_mm == pytest.approx(0.25, abs=1e-3)


def test_cli_counts_the_jobs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from nckemu.cli import main

    assert main(["plc", "run", str(PROGRAM), "--machine", str(warming_lathe(tmp_path)), "--duration", "5min",
                 "--axis", "2"]) == 0
    assert "4 FB3 PUT jobs, 4 FB2 GET jobs, 0 FB4 PI_SERV jobs, 0 errors" in capsys.readouterr().out


def test_on_a_recording_the_program_follows_its_motor_temperature_column(tmp_path: Path) -> None:
    """`plc run --inputs` (the code path of `loop` and a living serve): the recording's
    temp_spindle_motor_C drives the sensor, r0035 reports it, the program's K0 follows."""
    from nckemu.plcsim.replay import run_on_recording
    from nckemu.thermal.recordings.recording import load_recording

    rows = ["t_s,temp_spindle_motor_C,temp_bed_C,spindle_rpm,err_Z_um"]
    for i in range(61):
        t = i * 60.0
        rows.append(f"{t:g},{28.0 + 20.0 * t / 3600.0:.4f},21.0,{0 if i < 30 else 3000},{0.0}")
    path = tmp_path / "lathe.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    recording = load_recording(path)
    run = run_on_recording(PROGRAM, FIXTURES / "machines" / "lathe_828d.toml", recording, "Z", progress=False)
    motor = recording.temperatures_C["temp_spindle_motor_C"]
    expected_um = [max(0.0, float(t) - 30.0) * 10.0 for t in motor]
    # sim_um is the applied compensation at each row: at most a minute (and a ramp) behind the column
    late = [abs(sim - want) for sim, want in zip(run.sim_um, expected_um, strict=True)]
    assert max(late) < 20.0 / 60.0 * 10.0 * 1.2 + 1.0
    assert run.sim_um[-1] == pytest.approx(expected_um[-1], abs=4.0) and expected_um[-1] == pytest.approx(180.0)
