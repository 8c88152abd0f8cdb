"""The fleet file: what it accepts, and one line naming file, line and field for what it refuses."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.cli import main
from nckemu.emulator.fleet import Fleet, FleetMachine, FleetSpec, load_fleet, parse_fleet, quick_fleet
from nckemu.errors import NckConfigError

REPO = Path(__file__).resolve().parents[2]
MACHINES = REPO / "fixtures" / "machines"


def _refused(text: str, tmp_path: Path) -> str:
    path = tmp_path / "fleet.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(NckConfigError) as caught:
        load_fleet(path)
    return str(caught.value)


def test_the_lab_fixture_resolves_paths_against_the_fleet_file() -> None:
    spec = load_fleet(REPO / "fixtures" / "fleets" / "lab.toml")
    assert [(m.name, m.address) for m in spec.machines] == [
        ("mill-01", "127.0.0.1:21101"), ("mill-02", "127.0.0.1:21102"), ("lathe-01", "127.0.0.1:21103")]
    assert Path(spec.machines[0].machine or "").resolve() == (MACHINES / "bed_ramp.toml").resolve()
    assert Path(spec.machines[2].machine or "").resolve() == (MACHINES / "warm_z.toml").resolve()
    assert [m.line for m in spec.machines] == [8, 12, 16]


def test_loopback_addresses_with_port_102_are_distinct_machines() -> None:
    spec = load_fleet(REPO / "fixtures" / "fleets" / "loopback.toml")
    assert [m.address for m in spec.machines] == ["127.0.0.11:102", "127.0.0.12:102"]


@pytest.mark.parametrize(("text", "expected"), [
    ('[[machine]]\nname = "a"\nport = 2001\ncolour = "red"\n', "fleet.toml, line 1, field 'colour': unknown key"),
    ('[[machine]]\nname = "a"\nport = 2001\n\n[[machine]]\nname = "a"\nport = 2002\n',
     "fleet.toml, line 5, field 'name': 'a' is already the name of the machine on line 1"),
    ('[[machine]]\nname = "a"\nport = 2001\n\n[[machine]]\nname = "b"\nport = 2001\n',
     "fleet.toml, line 5, field 'port': 127.0.0.1:2001 is already taken by machine 'a'"),
    ('[[machine]]\nname = "a"\nport = 2001\nmachine = "nowhere.toml"\n',
     "fleet.toml, line 1, field 'machine': nowhere.toml: no such file"),
    ('[[machine]]\nname = "a"\nport = 70000\n', "fleet.toml, line 1, field 'port': 70000 is not a TCP port"),
    ('[[machine]]\nname = "a"\n', "fleet.toml, line 1, field 'port': missing"),
    ('[[machine]]\nport = 2001\n', "fleet.toml, line 1, field 'name': missing"),
    ('[[machine]]\nname = "a"\nport = 2001\nhost = "localhost"\n', "field 'host': 'localhost' is not an IP address"),
    ('[fleet]\nport = 1\n[[machine]]\nname = "a"\nport = 2001\n', "fleet.toml, line 1, field 'port': unknown key"),
    ('[machines]\n', "field 'machines': unknown table or key"),
    ('# nothing\n', "no [[machine]] in it"),
    ('[[machine]\n', "fleet.toml: "),
    ('[[machine]]\nname = "a"\nport = 2001\nopcua = "4840"\n', "fleet.toml, line 1, field 'opcua': '4840' is not a TCP"),
    ('[[machine]]\nname = "a"\nport = 2001\nopcua = 2001\n',
     "fleet.toml, line 1, field 'opcua': 127.0.0.1:2001 is already taken by machine 'a'"),
    ('[[machine]]\nname = "a"\nport = 2001\nopcua = 4840\n\n[[machine]]\nname = "b"\nport = 4840\n',
     "fleet.toml, line 6, field 'port': 127.0.0.1:4840 is already taken by machine 'a' (its OPC UA face)"),
])
def test_bad_fleet_files_are_refused_naming_line_and_field(tmp_path: Path, text: str, expected: str) -> None:
    assert expected in _refused(text, tmp_path)


def test_the_living_machine_keys_are_refused_not_ignored(tmp_path: Path) -> None:
    recording = tmp_path / "run.csv"
    recording.write_text("t_s\n0\n", encoding="utf-8")
    path = tmp_path / "fleet.toml"
    path.write_text('[[machine]]\nname = "a"\nport = 2001\ninputs = "run.csv"\n', encoding="utf-8")
    with pytest.raises(NckConfigError, match="line 1, field 'inputs': machine 'a': inputs needs the living machine"):
        Fleet(load_fleet(path))


def test_a_broken_machine_file_names_the_fleet_line_and_the_machine_file(tmp_path: Path) -> None:
    (tmp_path / "bad.toml").write_text('name = "x"\nspeed = 3\n', encoding="utf-8")
    path = tmp_path / "fleet.toml"
    path.write_text('[[machine]]\nname = "ok"\nport = 2001\n\n[[machine]]\nname = "b"\nport = 2002\n'
                    'machine = "bad.toml"\n', encoding="utf-8")
    with pytest.raises(NckConfigError) as caught:
        Fleet(load_fleet(path))
    message = str(caught.value)
    assert "fleet.toml, line 5, field 'machine': machine 'b': " in message and "bad.toml" in message


def test_quick_fleet_numbers_machines_and_ports() -> None:
    spec = quick_fleet(3, 2001)
    assert [(m.name, m.port) for m in spec.machines] == [("m001", 2001), ("m002", 2002), ("m003", 2003)]
    with pytest.raises(NckConfigError, match="not all in 1..65535"):
        quick_fleet(10, 65530)
    with pytest.raises(NckConfigError, match="at least one machine"):
        quick_fleet(0, 2001)
    with_opcua = quick_fleet(3, 2001, opcua_base_port=4841)
    assert [m.opcua for m in with_opcua.machines] == [4841, 4842, 4843]
    assert [m.opcua for m in spec.machines] == [None] * 3
    with pytest.raises(NckConfigError, match="overlap the S7 ports 2001..2003"):
        quick_fleet(3, 2001, opcua_base_port=2003)


def test_machines_of_one_file_share_the_parsed_machine_not_the_state() -> None:
    spec = quick_fleet(3, 2001, str(MACHINES / "bed_ramp.toml"))
    fleet = Fleet(spec)
    first, second, _ = fleet.machines
    assert first.emulator.machine is second.emulator.machine
    assert first.emulator.nck.store.stored is not second.emulator.nck.store.stored
    assert first.emulator.nck.store._index is second.emulator.nck.store._index


def test_state_dir_gives_each_machine_its_own_file(tmp_path: Path) -> None:
    fleet = Fleet(quick_fleet(2, 2001), state_dir=tmp_path)
    assert [m.ready()["state"] for m in fleet.machines] == [str(tmp_path / "m001.json"), str(tmp_path / "m002.json")]
    Fleet(quick_fleet(2, 2001), state_dir=tmp_path / "new")  # made, as its parent exists
    assert (tmp_path / "new").is_dir()
    with pytest.raises(NckConfigError, match="not a directory"):
        Fleet(quick_fleet(2, 2001), state_dir=tmp_path / "missing" / "deeper")


def test_cli_refuses_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "fleet.toml"
    path.write_text('[[machine]]\nname = "a"\nport = 2001\nmachin = "x.toml"\n', encoding="utf-8")
    assert main(["fleet", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "field 'machin': unknown key" in err and str(path) in err
    assert main(["fleet"]) == 1
    assert "give a fleet file, or --count N --base-port P" in capsys.readouterr().err
    assert main(["fleet", str(path), "--count", "2"]) == 1


_names = st.sampled_from(["a", "b", "c", "mill-1"])
_ports = st.sampled_from([2001, 2002, 2003])
_hosts = st.sampled_from(["127.0.0.1", "127.0.0.12"])


@given(st.lists(st.tuples(_names, _hosts, _ports), min_size=1, max_size=5))
def test_a_fleet_parses_exactly_when_names_and_addresses_are_unique(rows: list[tuple[str, str, int]]) -> None:
    text = "".join(f'[[machine]]\nname = "{n}"\nhost = "{h}"\nport = {p}\n\n' for n, h, p in rows)
    unique = len({n for n, _, _ in rows}) == len(rows) and len({(h, p) for _, h, p in rows}) == len(rows)
    if unique:
        spec = parse_fleet(text, "f.toml")
        assert [(m.name, m.host, m.port) for m in spec.machines] == rows
        assert [m.line for m in spec.machines] == [1 + 5 * i for i in range(len(rows))]
    else:
        with pytest.raises(NckConfigError, match="f.toml, line"):
            parse_fleet(text, "f.toml")


def test_fleet_machine_address() -> None:
    assert FleetMachine("a", "127.0.0.12", 102).address == "127.0.0.12:102"
    assert FleetSpec("x", ()).machines == ()


def test_the_living_fixture_names_its_recording_program_and_speed() -> None:
    spec = load_fleet(REPO / "fixtures" / "fleets" / "living.toml")
    alive, plain = spec.machines
    assert alive.living and not plain.living
    assert Path(alive.plc or "").name == "bed_only_z.awl" and alive.speed == "600x" and alive.loop
    with pytest.raises(NckConfigError, match="field 'loop': expected true or false"):
        parse_fleet('[[machine]]\nname = "a"\nport = 2001\nloop = "yes"\n', "f.toml")
