"""Loading a leadscrew table into a running emulator: ``nckemu lec`` and the PI service behind it."""

from __future__ import annotations

from pathlib import Path

import pytest

from nckemu.cli import main
from nckemu.clients import NckClient
from nckemu.emulator.runner import EmulatorThread
from nckemu.errors import NckServiceError

TABLE = Path(__file__).resolve().parents[4] / "fixtures" / "lec" / "z_axis.mpf"


def _lec(port: int, *extra: str) -> int:
    return main(["lec", "--port", str(port), *extra])


def test_load_enable_power_on_and_see_the_table_act(capsys: pytest.CaptureFixture[str]) -> None:
    with EmulatorThread() as emu:
        assert _lec(emu.port, "--password", "EVENING", str(TABLE)) == 0
        assert "active after power-on" in capsys.readouterr().out
        with NckClient("127.0.0.1", emu.port) as nck:
            nck.login("EVENING")
            nck.put({"NCKEMU_COMMANDED_POS[AX4]": -150.0})
            assert nck.get("NCKEMU_LEC_VALUE[AX4]") == [0.0]     # loaded, not yet active
            nck.put({"MD32700[AX4]": 1})
            nck.pi_service("_N_NCKRES", "/NC")
            assert nck.get("NCKEMU_LEC_VALUE[AX4]")[0] == pytest.approx(0.005)
        # With MD32700 = 1 active, the control refuses a new table.
        assert _lec(emu.port, "--password", "EVENING", str(TABLE)) == 1
        assert "refused the table" in capsys.readouterr().err


def test_loading_needs_the_machine_data_access_level() -> None:
    with EmulatorThread() as emu, NckClient("127.0.0.1", emu.port) as nck:
        with pytest.raises(NckServiceError) as refused:
            nck.pi_service("_N_NCKEMU_LEC", "/NC", str(TABLE))
        assert (refused.value.error_class, refused.value.error_code) == (0x87, 0x03)


def test_bad_tables_are_refused_naming_the_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gap = tmp_path / "gap.mpf"
    gap.write_text(TABLE.read_text().replace("[0,1,AX4]", "[0,5,AX4]"))
    unknown_axis = tmp_path / "ax9.mpf"
    unknown_axis.write_text(TABLE.read_text().replace("AX4]=0.010", "AX9]=0.010"))
    with EmulatorThread() as emu:
        assert _lec(emu.port, "--password", "EVENING", str(gap)) == 1
        err = capsys.readouterr().err
        assert "gap.mpf" in err and "gap" in err
        assert _lec(emu.port, "--password", "EVENING", str(unknown_axis)) == 1  # only the controller knows
        assert "ax9.mpf" in capsys.readouterr().err
        assert _lec(emu.port, str(tmp_path / "missing.mpf")) == 1
        assert "missing.mpf" in capsys.readouterr().err
        with NckClient("127.0.0.1", emu.port) as nck, pytest.raises(NckServiceError) as refused:
            nck.login("EVENING")
            nck.pi_service("_N_NCKEMU_LEC", "/NC", str(tmp_path / "nowhere.mpf"))
        assert (refused.value.error_class, refused.value.error_code) == (0xD2, 0x01)
