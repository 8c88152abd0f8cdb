"""FB2 GET, FB3 PUT and FB4 PI_SERV stubs in awlsim, their bridge, and the standalone hardware module."""

from __future__ import annotations

import math
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.clients import NckClient
from nckemu.clients.fb import STATE_NEGATIVE_ACK, item_state
from nckemu.emulator.runner import EmulatorThread
from nckemu.errors import NckConfigError
from nckemu.plcsim.bridge import (
    STUB_SOURCES,
    nck_to_plc_bytes,
    pi_arguments,
    pi_service_name,
    plc_string,
    plc_to_nck_value,
)
from nckemu.plcsim.run import run_program
from nckemu.protocol.addresses import NckType

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
SEQUENCE = FIXTURES / "plc" / "put_get_pi.awl"


def _assert_sequence_ran(run) -> None:  # type: ignore[no-untyped-def]
    assert run.log.errors == []
    assert [job.block for job in run.log.jobs] == ["PUT", "GET", "PI"]
    put, get, pi_call = run.log.jobs
    assert put.values == {"SD1": 0.25} and put.return_codes == [0xFF]
    assert get.values == {"RD1": 0.25} and get.return_codes == [0xFF]
    assert pi_call.values == {"service": "_N_SETUDT", "arguments": ["/NC"]}
    assert run.flag(10, 1) and run.flag(10, 2) and run.flag(10, 3), "each step saw its Done/NDR"
    assert run.flag_real(104) == 0.25, "FB2 put the value read into RD1 = MD 104"


def test_put_get_pi_in_sequence_on_simulated_time() -> None:
    run = run_program(SEQUENCE, duration_s=10.0)
    _assert_sequence_ran(run)
    # Each job ends one cycle after it starts: the cycle never waits on the network.
    assert [job.time_s for job in run.log.jobs] == [0.0, 1.0, 2.0]


def _program(tmp_path: Path, body: str, entry_column: str = "W#16#AB7C") -> Path:
    source = (SEQUENCE.read_text().split("ORGANIZATION_BLOCK")[0]).replace("W#16#AB7C", entry_column)
    path = tmp_path / "program.awl"
    path.write_text(f"{source}ORGANIZATION_BLOCK OB 1\nBEGIN\n{body}\nEND_ORGANIZATION_BLOCK\n")
    return path


def test_get_of_a_missing_variable_sets_error_and_the_item_state(tmp_path: Path) -> None:
    body = """
  A M 10.0
  = M 12.1
  S M 10.0
  CALL FB 2, DB 142 (
    Req := M 12.1, NumVar := 1, Addr1 := DB140.K0_Z,
    Error := M 11.1, NDR := M 13.1, State := MW 22, RD1 := MD 104)
  A M 11.1
  S M 30.0
  A M 11.1
  JCN keep
  L MW 22
  T MW 32
keep: NOP 0
"""
    # M 10.0 starts at 0: the first cycle sets Req after the call, so set it up front instead.
    body = body.replace("  A M 10.0\n  = M 12.1\n  S M 10.0", "  SET\n  = M 12.1")
    run = run_program(_program(tmp_path, body, entry_column="W#16#FFF0"), duration_s=5.0)
    assert run.flag(30, 0), "Error was set for one call"
    state = struct.unpack_from(">H", run.flags, 32)[0]
    rc = run.log.gets[0].return_codes[0]
    assert rc != 0xFF and state == item_state(rc, 1)
    assert not run.flag(13, 1)
    assert "variable 1" in run.log.errors[0]


def test_an_unknown_pi_service_gets_a_negative_acknowledgement(tmp_path: Path) -> None:
    program = _program(tmp_path, """
  SET
  = M 12.2
  CALL FB 4, DB 144 (
    Req := M 12.2, PIService := DB141.SETUDT, Unit := 1,
    Error := M 11.2, Done := M 13.2, State := MW 24)
  A M 11.2
  JCN keep
  L MW 24
  T MW 34
keep: NOP 0
""")
    program.write_text(program.read_text().replace("'_N_SETUDT'", "'_N_NOSUCH'"))
    run = run_program(program, duration_s=5.0)
    assert struct.unpack_from(">H", run.flags, 34)[0] == STATE_NEGATIVE_ACK
    assert run.log.pi_calls[0].values["service"] == "_N_NOSUCH"


def test_against_a_running_emulator_in_real_time() -> None:
    with EmulatorThread() as emu:
        run = run_program(SEQUENCE, emulator=f"127.0.0.1:{emu.port}", duration_s=1.5, cycle_s=0.1,
                          sample_every_s=0.5)
        _assert_sequence_ran(run)
        assert len(run.samples) >= 3 and not math.isnan(run.samples[-1].tc_value_mm), "nckemu's own variables"
        with NckClient("127.0.0.1", emu.port) as client:
            assert client.get("SD43900[AX4]") == [0.25]


def test_the_emulator_option_is_checked() -> None:
    with pytest.raises(NckConfigError, match="HOST:PORT"):
        run_program(SEQUENCE, emulator="localhost")
    with pytest.raises(NckConfigError, match="--machine"):
        run_program(SEQUENCE, emulator="127.0.0.1:1102", machine=FIXTURES / "machines" / "bed_ramp.toml")


def test_awlsim_loads_the_standalone_hardware_module(tmp_path: Path) -> None:
    """awlsim's own command line, with ``-H nckemu``, runs the program against the emulator."""
    awlsim_test = Path(sys.executable).parent / "awlsim-test"
    if not awlsim_test.exists():
        pytest.skip("awlsim-test is not installed")
    combined = tmp_path / "all.awl"
    combined.write_text("\n".join(p.read_text() for p in (*STUB_SOURCES, SEQUENCE)))
    with EmulatorThread() as emu:
        result = subprocess.run([str(awlsim_test), "-q", "-H", f"nckemu:host=127.0.0.1:port={emu.port}",
                                 "-M", "2", str(combined)], capture_output=True, text=True, timeout=60)
        assert result.returncode == 0, result.stdout + result.stderr
        with NckClient("127.0.0.1", emu.port) as client:
            assert client.get("SD43900[AX4]") == [0.25]


def test_plc_stubs_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from nckemu.cli import main

    assert main(["plc", "stubs", str(tmp_path / "stubs")]) == 0
    assert sorted(p.name for p in (tmp_path / "stubs").iterdir()) == ["fb2_get.awl", "fb3_put.awl", "fb4_pi_serv.awl"]
    assert main(["plc", "run", str(SEQUENCE), "--speed", "fast"]) == 1
    assert "--speed" in capsys.readouterr().err
    assert main(["plc", "run", str(SEQUENCE), "--duration", "20s", "--speed", "1000x"]) == 0
    assert "1 FB3 PUT jobs, 1 FB2 GET jobs, 1 FB4 PI_SERV jobs, 0 errors" in capsys.readouterr().out
    assert main(["plc", "run", str(tmp_path / "missing.awl")]) == 1
    assert "missing.awl" in capsys.readouterr().err


def test_a_program_awlsim_cannot_parse_names_the_file(tmp_path: Path) -> None:
    broken = tmp_path / "broken.awl"
    broken.write_text("ORGANIZATION_BLOCK OB 1\nBEGIN\n  L PIW 420\n  XYZ M 1.0\nEND_ORGANIZATION_BLOCK\n")
    with pytest.raises(NckConfigError, match="broken.awl"):
        run_program(broken, duration_s=2.0)


@given(st.floats(width=32, allow_nan=False, allow_infinity=False))
def test_real_values_cross_fb_boundaries_unchanged(value: float) -> None:
    raw = nck_to_plc_bytes(value, NckType.REAL8, 4, 8, 1)
    assert plc_to_nck_value(raw, 8, NckType.REAL8) == value
    assert plc_to_nck_value(nck_to_plc_bytes(value, NckType.REAL8, 8, 2, 1), 2, NckType.REAL8) == value


@given(st.integers(-2**31, 2**31 - 1))
def test_integer_values_cross_fb_boundaries_unchanged(value: int) -> None:
    raw = nck_to_plc_bytes(value, NckType.DINT, 4, 7, 1)
    assert plc_to_nck_value(raw, 7, NckType.DINT) == value


@given(st.text(alphabet=st.characters(min_codepoint=33, max_codepoint=126), min_size=1, max_size=20))
def test_s7_strings_and_plain_text(text: str) -> None:
    encoded = text.encode()
    assert plc_string(bytes([len(encoded) + 4, len(encoded)]) + encoded + b"\x00" * 4) == text
    if len(encoded) >= 2:  # one character and a NUL read as an empty S7 STRING: the layouts overlap there
        assert plc_string(encoded + b"\x00\x00") == text


def test_pi_service_names_and_arguments() -> None:
    assert pi_service_name("PI.SETUDT") == pi_service_name("SETUDT") == pi_service_name("_N_SETUDT") == "_N_SETUDT"
    assert pi_arguments("_N_SETUDT", [], [1, 0, 0]) == ["/NC"]
    assert pi_arguments("_N_SELECT", ["/_N_MPF_DIR/_N_TC_MPF"], [0]) == ["/NC", "/_N_MPF_DIR/_N_TC_MPF"]
    assert pi_arguments("_N_LOGIN_", [], [7, 0]) == ["/NC", "7"]


def test_stub_sources_exist() -> None:
    assert all(path.is_file() for path in STUB_SOURCES)
