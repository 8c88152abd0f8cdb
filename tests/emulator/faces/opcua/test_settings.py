"""Users and rights of the OPC UA face from a machine file's [opcua] table."""

from __future__ import annotations

import pytest

from nckemu.emulator.faces.opcua.settings import OpcUaSettings, may
from nckemu.emulator.machine.machine_file import load_machine, parse_machine
from nckemu.errors import NckConfigError


def test_default_machine_anonymous_reads_nckemu_writes() -> None:
    settings = OpcUaSettings.from_machine(load_machine().opcua)
    assert may(settings.anonymous, "Sea", write=False) and not may(settings.anonymous, "Sea", write=True)
    user = settings.users["nckemu"]
    assert user.password == "SUNRISE" and may(user.rights, "Plc", write=True)
    assert (settings.max_sessions, settings.max_subscriptions) == (10, 10)


def test_realm_rights() -> None:
    rights = frozenset({"StateRead", "SeaWrite"})
    assert may(rights, "State", write=False) and not may(rights, "State", write=True)
    assert may(rights, "Sea", write=True) and may(rights, "Sea", write=False)
    assert not may(rights, "Plc", write=False)


def test_machine_file_table() -> None:
    machine = parse_machine('name = "m"\n[opcua]\nanonymous = []\nmax_sessions = 5\n'
                            '[opcua.users.op]\npassword = "x"\nrights = ["PlcRead"]\n')
    settings = OpcUaSettings.from_machine(machine.opcua)
    assert settings.anonymous == frozenset() and settings.max_sessions == 5
    assert settings.users["op"].rights == frozenset({"PlcRead"})


@pytest.mark.parametrize(("table", "field"), [
    ({"anonymus": []}, "opcua.anonymus"),
    ({"anonymous": ["ReadAll"]}, "opcua.anonymous"),
    ({"users": {"a": {"rights": []}}}, "opcua.users.a"),
    ({"max_sessions": 0}, "opcua.max_sessions"),
])
def test_bad_tables_name_the_field(table: dict[str, object], field: str) -> None:
    with pytest.raises(NckConfigError, match=field.replace(".", r"\.")):
        OpcUaSettings.from_machine(table, "m.toml")
