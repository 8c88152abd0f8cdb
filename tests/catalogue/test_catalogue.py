"""The catalogue: rows checked at load, lookups, and the public names re-exported beside it."""

from __future__ import annotations

import importlib

import pytest

from nckemu.catalogue import build_table, find_by_name, load_table, parse_variable
from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.machine_file import load_machine
from nckemu.emulator.machine.nck.model import NckModel, check_sources
from nckemu.errors import NckConfigError

GOOD = {"name": "X", "number": "MD1", "module": 0x1A, "column": 1, "areas": ["N"], "type": "REAL8"}


@pytest.mark.parametrize(("change", "field"), [
    ({"write_levle": 7}, "write_levle"),
    ({"type": "REAL16"}, "type"),
    ({"areas": ["Q"]}, "areas"),
    ({"module": 300}, "module"),
    ({"module": "0x1A"}, "module"),
    ({"effective": "tomorrow"}, "effective"),
    ({"type": "STRING"}, "length"),
    ({"write_level": 9}, "write_level"),
])
def test_bad_rows_name_the_field_and_line(change: dict[str, object], field: str) -> None:
    with pytest.raises(NckConfigError) as raised:
        build_table([{**GOOD, **change}], "m.toml", [12])
    assert f"field {field!r}" in str(raised.value) and "m.toml, line 12" in str(raised.value)


def test_missing_key_and_clashes() -> None:
    row = {key: value for key, value in GOOD.items() if key != "column"}
    with pytest.raises(NckConfigError, match="'column'"):
        build_table([row], "m.toml")
    with pytest.raises(NckConfigError, match="already X"):
        build_table([GOOD, {**GOOD, "name": "Y"}], "m.toml")
    with pytest.raises(NckConfigError, match="declared twice"):
        build_table([GOOD, {**GOOD, "column": 2}], "m.toml")


def test_a_machine_may_override_a_builtin_row_by_name() -> None:
    base = load_table()
    overridden = build_table([{**GOOD, "name": "TEMP_COMP_ABS_VALUE", "number": "SD43900", "module": 0x16,
                               "column": 43900, "areas": ["A"], "max": 2.0}], "m.toml", base=base)
    assert len(overridden) == len(base)
    assert next(s for s in overridden if s.name == "TEMP_COMP_ABS_VALUE").maximum == 2.0


def test_unknown_or_unwritable_source_refused_when_the_model_is_built() -> None:
    with pytest.raises(NckConfigError, match="unknown value source 'axes.teleport'"):
        check_sources(build_table([{**GOOD, "source": "axes.teleport"}], "m.toml"), "m.toml")
    with pytest.raises(NckConfigError, match="cannot be written"):
        check_sources(build_table([{**GOOD, "source": "alarms.count", "write_level": 7}], "m.toml"), "m.toml")
    specs = build_table([{**GOOD, "source": "axes.teleport"}], "m.toml", base=load_table())
    with pytest.raises(NckConfigError):
        NckModel(load_machine(), SimulatedClock(), specs)


def test_every_builtin_source_is_bound() -> None:
    check_sources(load_table(), "builtin")
    assert find_by_name("sd43900") is find_by_name("TEMP_COMP_ABS_VALUE")


@pytest.mark.parametrize(("module_name", "names"), [
    ("nckemu.protocol.errors", ["NckError", "NckConfigError", "NckProtocolError", "item_error_for"]),
    ("nckemu.errors", ["NckError", "NckProtocolError", "NckTruncatedError", "HeaderError", "ReturnCode"]),
    ("nckemu.protocol.codes", ["ReturnCode", "HeaderError", "describe_header_error"]),
    ("nckemu.clients", ["NckClient", "AsyncNckClient", "Variable", "parse_variable"]),
])
def test_public_names_answer_where_the_docs_name_them(module_name: str, names: list[str]) -> None:
    module = importlib.import_module(module_name)
    for name in names:
        assert getattr(module, name) is not None, f"{module_name}.{name}"


def test_re_exported_names_are_the_same_objects() -> None:
    from nckemu.clients import parse_variable as client_parse
    from nckemu.errors import NckProtocolError as base_error
    from nckemu.protocol.errors import NckProtocolError

    assert client_parse is parse_variable and base_error is NckProtocolError
