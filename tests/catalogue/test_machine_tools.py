"""The machine file's tools and work offsets: good files load, each bad value is one line naming the
file, the line of its table and the field; the catalogue's multi-column rows and their names."""

from __future__ import annotations

import pytest

from nckemu.catalogue.names import parse_variable
from nckemu.catalogue.table import build_table
from nckemu.emulator.machine.machine_file import SETTABLE_FRAMES, load_machine, parse_machine
from nckemu.errors import NckConfigError
from nckemu.protocol.addresses import NckArea

GOOD = """name = "lathe"

[[axis]]
number = 1
name = "X1"

[[axis]]
number = 2
name = "Z1"

[tools]
cutting_edge_params = 30
active_t = 7
active_d = 2

[[tool]]
number = 7
ident = "ROUGHING"
edges = [{ type = 500, edge_position = 3, length1_mm = 40.0, length2_mm = 80.0, radius_mm = 0.8 },
         { type = 500, edge_position = 3, length1_mm = 41.0, length2_mm = 82.0, radius_mm = 0.4 }]

[work_offsets]
active = "G55"
G55 = { X1 = 10.0, Z1 = -200.0 }
G599 = { Z1 = 1.0 }
"""
TOOLS_LINE = GOOD.splitlines().index("[tools]") + 1
TOOL_LINE = GOOD.splitlines().index("[[tool]]") + 1
OFFSETS_LINE = GOOD.splitlines().index("[work_offsets]") + 1


def test_a_good_file_loads_tools_and_offsets() -> None:
    machine = parse_machine(GOOD, "lathe.toml")
    assert machine.tool_settings.cutting_edge_params == 30
    (tool,) = machine.tools
    assert (tool.number, tool.ident, len(tool.edges), len(tool.edges[0])) == (7, "ROUGHING", 2, 30)
    assert tool.edges[1][:6] == (500.0, 3.0, 41.0, 82.0, 0.0, 0.4)
    assert machine.work_offsets.active == SETTABLE_FRAMES["G55"] == 2
    assert machine.work_offsets.count == 100 and machine.work_offsets.shifts_mm[99] == {2: 1.0}


def test_the_default_machine_has_an_active_tool_and_work_offset() -> None:
    machine = load_machine()
    assert (machine.tool_settings.active_t, machine.tool_settings.active_d) == (1, 1)
    assert machine.tool(1) is not None and machine.work_offsets.active == 1


@pytest.mark.parametrize(("old", "new", "line", "field"), [
    ("number = 7", "number = 0", TOOL_LINE, "tool[0].number"),
    ("number = 7", "number = 32001", TOOL_LINE, "tool[0].number"),
    ('ident = "ROUGHING"', "ident = 5", TOOL_LINE, "tool[0].ident"),
    ('ident = "ROUGHING"', 'ident = "' + "N" * 33 + '"', TOOL_LINE, "tool[0].ident"),
    ("radius_mm = 0.8", 'radius_mm = "0.8"', TOOL_LINE, "tool[0].edges[0].radius_mm"),
    ("radius_mm = 0.8", "radius_mm = nan", TOOL_LINE, "tool[0].edges[0].radius_mm"),
    ("radius_mm = 0.8", "radius = 0.8", TOOL_LINE, "tool[0].edges[0].radius"),
    ('ident = "ROUGHING"', 'idnet = "ROUGHING"', TOOL_LINE, "tool[0].idnet"),
    ("cutting_edge_params = 30", "cutting_edge_params = 10", TOOLS_LINE, "tools.cutting_edge_params"),
    ("active_t = 7", "active_t = 8", TOOLS_LINE, "tools.active_t"),
    ("active_d = 2", "active_d = 3", TOOLS_LINE, "tools.active_d"),
    ("active_d = 2", "active_d = true", TOOLS_LINE, "tools.active_d"),
    ('active = "G55"', 'active = "G58"', OFFSETS_LINE, "work_offsets.active"),
    ("X1 = 10.0", "Q1 = 10.0", OFFSETS_LINE, "work_offsets.G55.Q1"),
    ("X1 = 10.0", 'X1 = "10"', OFFSETS_LINE, "work_offsets.G55.X1"),
    ("G599 = { Z1 = 1.0 }", "G600 = { Z1 = 1.0 }", OFFSETS_LINE, "work_offsets.G600"),
    ("G599 = { Z1 = 1.0 }", "G599 = 1.0", OFFSETS_LINE, "work_offsets.G599"),
])
def test_a_bad_value_is_one_line_naming_file_line_and_field(old: str, new: str, line: int, field: str) -> None:
    assert old in GOOD
    with pytest.raises(NckConfigError) as caught:
        parse_machine(GOOD.replace(old, new, 1), "lathe.toml")
    text = str(caught.value)
    assert "\n" not in text and text.startswith(f"lathe.toml, line {line}, field {field!r}: "), text
    assert (caught.value.line, caught.value.field) == (line, field)


def test_a_second_tool_with_the_same_number_is_refused() -> None:
    text = GOOD + '\n[[tool]]\nnumber = 7\nident = "AGAIN"\n'
    second = text.splitlines().index("[[tool]]", TOOL_LINE) + 1
    with pytest.raises(NckConfigError, match=rf"lathe.toml, line {second}, field 'tool\[1\].number': T7"):
        parse_machine(text, "lathe.toml")


ROW = {"name": "x", "number": "X", "module": 0x14, "column": 1, "areas": ["T"], "type": "REAL8"}


def test_a_row_over_several_columns_needs_a_source_and_room() -> None:
    with pytest.raises(NckConfigError, match="field 'columns'.*value source"):
        build_table([{**ROW, "columns": 5}], "m.toml", [3])
    with pytest.raises(NckConfigError, match="field 'columns'"):
        build_table([{**ROW, "column": 0xFFFF, "columns": 2, "source": "tools.edge_param"}], "m.toml")
    (spec,) = build_table([{**ROW, "columns": 5, "source": "tools.edge_param"}], "m.toml")
    assert spec.columns == 5
    # a variable in one of its columns clashes with it
    with pytest.raises(NckConfigError, match="column 4 area T is already x"):
        build_table([{**ROW, "columns": 5, "source": "tools.edge_param"},
                     {**ROW, "name": "y", "column": 4}], "m.toml")


def test_names_address_the_t_number_by_column() -> None:
    variable = parse_variable("cuttEdgeParam[2,T1,col7,x25]")
    address = variable.address
    assert (address.area, address.unit, address.column, address.line, address.module, address.line_count) == \
        (NckArea.T, 1, 7, 3, 0x14, 25)
    assert str(variable) == "TO1 cuttEdgeParam[2,T1,col7,x25]"
    assert parse_variable("linShift[4,C1]").address.line == 5
    with pytest.raises(NckConfigError, match="columns 1..32000"):
        parse_variable("cuttEdgeParam[col32001]")
