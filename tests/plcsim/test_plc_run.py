"""The user's STL program, run by awlsim against the emulator for two simulated hours."""

from __future__ import annotations

from pathlib import Path

import pytest

from nckemu.plcsim.run import run_program, seed000_problems

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
MACHINE = FIXTURES / "machines" / "bed_ramp.toml"


@pytest.fixture(scope="module")
def good_run():  # type: ignore[no-untyped-def]
    return run_program(FIXTURES / "plc" / "tc_z.awl", machine=MACHINE, duration_s=7200.0)


def test_program_writes_the_three_setting_data_every_minute(good_run) -> None:  # type: ignore[no-untyped-def]
    puts = good_run.log.puts
    assert len(puts) >= 110
    assert all(set(p.values) == {"SD1", "SD2", "SD3"} for p in puts)
    assert all(p.return_codes == [0xFF, 0xFF, 0xFF] for p in puts)
    intervals = [b.time_s - a.time_s for a, b in zip(puts, puts[1:], strict=False)]
    # A self-restarting S5T#1M on-delay timer fires every 60 s plus two PLC cycles (1 s cycles here).
    assert max(intervals) <= 60.0 + 2 * 1.0 and min(intervals) >= 60.0


def test_compensation_follows_seed000(good_run) -> None:  # type: ignore[no-untyped-def]
    assert seed000_problems(good_run) == []
    final = good_run.samples[-1]
    assert final.sensor_C == pytest.approx(50.0) and final.tc_value_mm == pytest.approx(0.6, abs=0.01)


def test_an_inverted_comparison_is_caught_in_plain_words() -> None:
    run = run_program(FIXTURES / "plc" / "tc_z_inverted.awl", machine=MACHINE, duration_s=7200.0)
    problems = seed000_problems(run)
    assert problems
    assert "at 40.0 degC" in problems[0] or "at 50.0 degC" in " ".join(problems)
    assert "check the comparison with 30 degC" in problems[0]


def test_cli(capsys: pytest.CaptureFixture[str]) -> None:
    from nckemu.cli import main

    assert main(["plc", "run", str(FIXTURES / "plc" / "tc_z.awl"), "--machine", str(MACHINE),
                 "--duration", "10min"]) == 0  # a PUT every 62 s (60 s timer + 2 cycles)
    out = capsys.readouterr().out
    assert "9 FB3 PUT jobs, 0 FB2 GET jobs, 0 FB4 PI_SERV jobs, 0 errors" in out
