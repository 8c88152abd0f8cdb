"""The lines of /Channel/GeometricAxis (module SGA): the channel's axes in the workpiece coordinate system,
whatever order and names the machine file gives its machine axes."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.emulator.machine.clock import SimulatedClock
from nckemu.emulator.machine.machine_file import parse_machine
from nckemu.emulator.machine.nck.geometric_axes import wcs_axes
from nckemu.emulator.machine.nck.model import NckModel
from nckemu.errors import NckAddressOutOfRange


def _model(axes: list[tuple[str, bool, bool]]) -> NckModel:
    """A machine with these machine axes in this order: (name, rotary, spindle)."""
    rows = []
    for number, (name, rotary, spindle) in enumerate(axes, start=1):
        rows.append(f'[[axis]]\nnumber = {number}\nname = "{name}"\n'
                    + ("rotary = true\n" if rotary else "") + ("spindle = true\n" if spindle else ""))
    return NckModel(parse_machine("\n".join(rows)), SimulatedClock(0.0))


@pytest.mark.parametrize("axes, expected", [
    ([("X1", False, False), ("Y1", False, False), ("SP1", True, True), ("Z1", False, False)],
     [("X", 1), ("Y", 2), ("Z", 4)]),
    ([("Z1", False, False), ("C1", True, False), ("X1", False, False), ("SP1", True, True)],   # a lathe
     [("X", 3), ("Z", 1), ("C", 2)]),
    ([("A1", True, False), ("X1", False, False), ("Y1", False, False), ("Z1", False, False)],
     [("X", 2), ("Y", 3), ("Z", 4), ("A", 1)]),
])
def test_geometry_axes_come_first_then_the_other_path_axes(axes: list[tuple[str, bool, bool]],
                                                           expected: list[tuple[str, int]]) -> None:
    assert wcs_axes(_model(axes), 1) == expected


def test_only_channel_1_holds_axes_and_a_line_past_the_last_is_refused() -> None:
    from nckemu.emulator.machine.nck.sources import SOURCES

    model = _model([("X1", False, False), ("Z1", False, False)])
    assert wcs_axes(model, 2) == []
    read = SOURCES["geometric_axes.actual_tool_base"].read
    assert read is not None
    with pytest.raises(NckAddressOutOfRange):
        read(model, 1, 3)
    assert SOURCES["geometric_axes.name"].read(model, 1, 3) == ""  # type: ignore[misc]


_AXIS = st.tuples(st.sampled_from(["X", "Y", "Z", "A", "B", "C", "U", "V", "W", "Q"]), st.booleans(), st.booleans())


@settings(max_examples=60, deadline=None)
@given(st.lists(_AXIS, min_size=1, max_size=8))
def test_every_path_axis_has_one_line(axes: list[tuple[str, bool, bool]]) -> None:
    """Each machine axis that is no spindle has exactly one line, a spindle none; the geometry axes present
    are lines 1.. in the order X, Y, Z (the first machine axis of each name)."""
    named = [(f"{letter}{index}", rotary, spindle) for index, (letter, rotary, spindle) in enumerate(axes, start=1)]
    lines = wcs_axes(_model(named), 1)
    path_axes = [number for number, (_name, _rotary, spindle) in enumerate(named, start=1) if not spindle]
    assert sorted(number for _name, number in lines) == path_axes
    present = sorted({letter for (letter, _rotary, spindle) in axes if not spindle and letter in "XYZ"},
                     key="XYZ".index)
    assert [name for name, _number in lines[:len(present)]] == present
    for name, number in lines[:len(present)]:  # the first machine axis of that name is the geometry axis
        assert number == next(n for n, (letter, _r, spindle) in enumerate(axes, start=1)
                              if letter == name and not spindle)
