"""The line layouts of tool offsets and frames, for any table size: line (D - 1) * numCuttEdgeParams + P
reaches parameter P of edge D and nothing else; line frame * numMachAxes + axis reaches that axis of
that frame; lines past the table are out of range, never another value."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.machine.machine_file import (
    MAX_EDGE_PARAMS,
    STANDARD_EDGE_PARAMS,
    Axis,
    Machine,
    Tool,
    ToolSettings,
    WorkOffsets,
)
from nckemu.emulator.machine.nck.frames import IFRAME, MAX_ACTIVE_FRAME_INDEX, PFRAME, Frames
from nckemu.emulator.machine.nck.tools import Tools
from nckemu.errors import NckAddressOutOfRange, NckObjectDoesNotExist


@st.composite
def tool_tables(draw: st.DrawFn) -> tuple[int, int, int]:
    params = draw(st.integers(STANDARD_EDGE_PARAMS, MAX_EDGE_PARAMS))
    edges = draw(st.integers(1, 9))
    t_number = draw(st.integers(1, 32000))
    return params, edges, t_number


@given(tool_tables(), st.data())
def test_an_edge_line_reaches_one_parameter(table: tuple[int, int, int], data: st.DataObject) -> None:
    params, edges, t_number = table
    machine = Machine("m", "m.toml", tools=(Tool(t_number, "T", tuple((0.0,) * params for _ in range(edges))),),
                      tool_settings=ToolSettings(params, 0, 0))
    tools = Tools(machine)
    d_number = data.draw(st.integers(1, edges))
    parameter = data.draw(st.integers(1, params))
    line = (d_number - 1) * params + parameter
    tools.set_edge_param(t_number, line, 12.5)
    assert tools.parameter(t_number, d_number, parameter) == 12.5 == tools.edge_param(t_number, line)
    others = [tools.parameter(t_number, d, p) for d in range(1, edges + 1) for p in range(1, params + 1)]
    assert sorted(others) == [0.0] * (edges * params - 1) + [12.5]
    with pytest.raises(NckAddressOutOfRange):
        tools.edge_param(t_number, edges * params + data.draw(st.integers(1, 1000)))
    with pytest.raises(NckObjectDoesNotExist):
        tools.edge_param(t_number % 32000 + 1, 1)


@given(st.integers(1, 31), st.integers(5, 100), st.data())
def test_a_frame_line_reaches_one_axis_of_one_frame(axes: int, frames: int, data: st.DataObject) -> None:
    numbers = sorted(data.draw(st.sets(st.integers(1, 31), min_size=axes, max_size=axes)))
    active = data.draw(st.integers(0, frames - 1))
    machine = Machine("m", "m.toml", axes=tuple(Axis(number, f"A{number}") for number in numbers),
                      work_offsets=WorkOffsets(active=active, count=frames))
    table = Frames(machine, channels=1)
    frame = data.draw(st.integers(0, frames - 1))
    axis_index = data.draw(st.integers(1, axes))
    line = frame * axes + axis_index
    table.set_settable_shift(1, line, -3.25)
    assert table.settable_shift_mm(1, line) == -3.25
    assert table.shifts_mm[1][frame] == {numbers[axis_index - 1]: -3.25}
    # the active frames show it when, and only when, the frame is the active one
    shown = table.actual_frame_shift_mm(1, IFRAME * axes + axis_index)
    assert shown == (-3.25 if frame == active else 0.0)
    assert table.actual_frame_shift_mm(1, PFRAME * axes + axis_index) == 0.0
    with pytest.raises(NckAddressOutOfRange):
        table.settable_shift_mm(1, frames * axes + axis_index)
    with pytest.raises(NckAddressOutOfRange):
        table.actual_frame_shift_mm(1, (MAX_ACTIVE_FRAME_INDEX + 1) * axes + axis_index)
