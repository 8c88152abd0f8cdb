"""`machine show` is the machine (issue 44, item 4): everything the file sets, and the same refusals as
`serve --opcua` (what `make serve` runs), with file, line and field, through one validation path."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from nckemu.cli import main


def test_show_lists_tools_drives_opcua_and_users_without_passwords(capsys) -> None:
    assert main(["machine", "show"]) == 0
    text = capsys.readouterr().out
    for shown in ("tool T1 END_MILL_D10", "length 1 125 mm", "number of teeth 4", "drive V3: axis 3",
                  "sensor bed: PIW420", "OPC UA (with serve --opcua)", "user nckemu: SinuReadAll, SinuWriteAll",
                  "work offsets: 5 settable frames"):
        assert shown in text, shown
    assert main(["machine", "show", "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["tools"][0]["edges"][0]["P3"] == 125.0 and len(document["drives"]) == 4
    assert document["opcua"]["users"] == {"nckemu": {"rights": ["SinuReadAll", "SinuWriteAll"], "admin": True}}
    assert "password" not in json.dumps(document["opcua"]).lower()


def test_no_passwords_is_said_not_left_blank(tmp_path: Path, capsys) -> None:
    path = tmp_path / "m.toml"
    path.write_text('name = "m"\npasswords = {}\n', encoding="utf-8")
    assert main(["machine", "show", "--machine", str(path)]) == 0
    assert "passwords: none" in capsys.readouterr().out


BAD = [
    ('[opcua]\nanonymous = ["SinuReadAll"]\nsecurity = ["Basic256Sha256"]\n', "line 5, field 'opcua.security'"),
    ('[opcua.users.alice]\npassword = "x"\nrights = ["Nope"]\n', "line 5, field 'opcua.users.alice.rights'"),
    ('[opcua]\nmax_sessions = 0\n', "line 4, field 'opcua.max_sessions'"),
    ('[[axis]]\nnumber = 1\nname = "X1"\ncolour = "red"\n', "field 'axis[0].colour'"),
]


@pytest.mark.parametrize(("body", "where"), BAD, ids=[where for _, where in BAD])
def test_show_refuses_exactly_what_serve_refuses(body: str, where: str, tmp_path: Path, capsys) -> None:
    path = tmp_path / "m.toml"
    path.write_text(f'name = "m"\n\n{body}', encoding="utf-8")
    assert main(["machine", "show", "--machine", str(path)]) == 1
    shown = capsys.readouterr().err.strip().removeprefix("nckemu machine show: ")
    assert main(["serve", "--machine", str(path), "--port", "0", "--opcua", "0"]) == 1
    served = capsys.readouterr().err.strip().removeprefix("nckemu serve: ")
    assert shown == served and where in shown and str(path) in shown


def test_a_fleet_names_the_machine_files_line_too(tmp_path: Path, capsys) -> None:
    (tmp_path / "bad.toml").write_text(f'name = "m"\n\n{BAD[0][0]}', encoding="utf-8")
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[[machine]]\nname = "m1"\nport = 1\nopcua = 2\nmachine = "bad.toml"\n', encoding="utf-8")
    assert main(["fleet", str(fleet)]) == 1
    assert f"{tmp_path / 'bad.toml'}, {BAD[0][1]}" in capsys.readouterr().err
