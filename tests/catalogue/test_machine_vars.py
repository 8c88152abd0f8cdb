"""Machine files add or override NCK variables ([[var]] rows), and ``nckemu vars`` lists the catalogue."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest

from nckemu.cli import main
from nckemu.emulator.faces.s7.dispatch import Dispatcher
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import load_machine, parse_machine
from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.errors import NckConfigError
from nckemu.protocol.addresses import NckAddress, NckArea

FIXTURE = Path(__file__).parents[2] / "fixtures" / "machines" / "extra_vars.toml"
ROW = """
[[var]]
name = "myVar"
number = "S500"
module = 0x7F
column = 500
areas = ["C"]
type = "REAL8"
default = 1.5
"""


def test_machine_file_adds_and_overrides_variables() -> None:
    emulator = Emulator(load_machine(FIXTURE))
    ctx = AccessContext(level=7)
    assert emulator.nck.read(NckAddress(NckArea.C, 1, 500, 1, 0x7F, 1), ctx) == [120.0]
    assert emulator.nck.read_typed(NckAddress(NckArea.N, 1, 18030, 1, 0x1A, 1), ctx) == \
        (emulator.nck.store.spec("HW_SERIAL_NUMBER").nck_type, 20, ["MIRROR-0001"])
    # the machine's own variable is written like any other, and [initial] reaches it by name
    emulator.nck.write(NckAddress(NckArea.C, 1, 500, 1, 0x7F, 1), [80.0], ctx)
    assert emulator.nck.read(NckAddress(NckArea.C, 1, 500, 1, 0x7F, 1), ctx) == [80.0]
    machine = parse_machine(ROW + "\n[initial]\nmyVar = { 1 = 2.5 }\n", "m.toml")
    assert Emulator(machine).nck.read(NckAddress(NckArea.C, 1, 500, 1, 0x7F, 1), ctx) == [2.5]


@pytest.mark.parametrize(("change", "line", "message"), [
    ('type = "REAL8"', 2, "'REAL9' is not one of"),
    ('column = 500', 2, "module 0x7F column 11 area C is already chanStatus"),
    ('name = "myVar"', 2, "unknown key"),
])
def test_bad_rows_are_one_line_naming_file_and_line(change: str, line: int, message: str) -> None:
    bad = {"type": ROW.replace('type = "REAL8"', 'type = "REAL9"'),
           "column": ROW.replace("column = 500", "column = 11"),
           "name": ROW.replace('name = "myVar"', 'name = "myVar"\nwrite_levle = 7')}[change.split(" ")[0]]
    with pytest.raises(NckConfigError) as caught:
        parse_machine(bad, "m.toml")
    text = str(caught.value)
    assert "\n" not in text and text.startswith(f"m.toml, line {line}") and message in text


def test_a_bad_machine_row_is_one_line_from_the_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(ROW.replace("column = 500", "column = 7").replace('areas = ["C"]', 'areas = ["N"]'))
    assert main(["vars", "--machine", str(path)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"{path}, line 2" in err and "already numAlarms" in err


def test_unknown_value_source_in_a_machine_file_is_refused() -> None:
    with pytest.raises(NckConfigError, match="unknown value source 'axes.teleport'"):
        Emulator(parse_machine(ROW.replace("default = 1.5", 'source = "axes.teleport"'), "m.toml"))


def test_vars_lists_name_number_address_type_limits_access_source(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["vars", "feedRateIpoOvr"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split() == ["name", "number", "NC", "(index", "from", "0)", "BTSS", "(line", "from", "1)",
                              "address", "type", "unit", "limits", "r/w", "source"]
    assert out[1].split() == ["feedRateIpoOvr", "S3", "feedRateIpoOvr", "/Channel/State/feedRateIpoOvr[u1]", "C",
                              "0x7F", "col", "3", "REAL8", "%", "0.0..200.0", "7/7", "channel.feed_override"]
    assert main(["vars", "MD18040"]) == 0
    assert "MD18040[0..5]      MD18040[u1,1..6]    N 0x1A col 18040  STRING(20)" in capsys.readouterr().out


def test_vars_json_pattern_and_machine(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["vars", "--json", "/Channel/State/*Parts"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {row["name"] for row in rows} == {"reqParts", "totalParts", "actParts", "specParts"}
    assert all(row["type"] == "REAL8" and row["bytes"] == 8 and row["module"] == 0x7F for row in rows)
    assert main(["vars", "--json", "--machine", str(FIXTURE), "S500"]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert (row["name"], row["source"], row["write_level"]) == ("shiftTarget", "stored", 7)
    assert main(["vars", "no-such-variable"]) == 1
    assert "no NCK variable name or number matches" in capsys.readouterr().err


def test_vars_help_example_runs(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["vars", "--help"]) == 0  # main turns argparse's exit into its return code
    help_text = capsys.readouterr().out
    example = next(line for line in help_text.splitlines() if "--machine fixtures" in line).split()
    assert main(example[1:3] + [str(FIXTURE)]) == 0
    assert "shiftTarget" in capsys.readouterr().out


def test_served_over_the_wire_with_the_machine_override() -> None:
    from nckemu.emulator.faces.s7.session import ServerSession
    from tests.emulator.faces.s7.test_field_catalogue import CR_LSC, SETUP_LSC, answer_items, item, read_frame
    session = ServerSession(Dispatcher.for_machine(Emulator(load_machine(FIXTURE))))
    session.receive(CR_LSC)
    session.receive(SETUP_LSC)
    (answer,) = session.receive(read_frame(item(0x01, 18030, 1, 0x1A), item(0x41, 500, 1, 0x7F)))
    (serial, target) = answer_items(answer)
    assert serial[2] == b"MIRROR-0001".ljust(20, b"\x00") and struct.unpack("<d", target[2]) == (120.0,)
