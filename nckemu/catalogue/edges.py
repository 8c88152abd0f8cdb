"""The tool offsets' address as the controller reads it, and each edge parameter's own unit.

``cuttEdgeParam`` (module TO, area T) has four numbers, each with one meaning everywhere (the grammar,
the docs, the refusals):

* the **TO unit** is the NCK unit of area T: ``T1`` in NC syntax, ``u1`` in BTSS (one TO unit per
  machine in the emulator; a real NCK has one per channel group);
* the **tool** is the column: its T number, ``colN`` in NC syntax, ``cN`` in BTSS;
* the **edge** D and the **parameter** P share the line: ``(D - 1) * numCuttEdgeParams + P``; NC syntax
  writes the index (line - 1), BTSS the line.

Only lengths and radii are in mm; angles are in degrees; the type, the edge position, the H number,
the number of teeth and the reserved parameters are numbers without a unit (the $TC_DP list of the
840D sl: sources in docs/assumptions.md, "Tool offsets").
"""

from __future__ import annotations

from collections.abc import Iterable

TOOL_OFFSETS = "cuttEdgeParam"
STANDARD_EDGE_PARAMS = 25  # A2: "currently 25 parameters are reserved for each tool edge"

# parameter number -> unit; a parameter not listed is a bare number (type, edge position, counts)
EDGE_PARAMETER_UNITS: dict[int, str] = {
    **dict.fromkeys((3, 4, 5, 6, 7, 8), "mm"),        # geometry: lengths 1..3, radius, slot width, projection
    **dict.fromkeys((10, 11), "deg"),                 # holder angle, cone angle of milling tools
    **dict.fromkeys((12, 13, 14, 15, 16, 17), "mm"),  # wear of the geometry above
    **dict.fromkeys((19, 20), "deg"),                 # wear of the angles
    **dict.fromkeys((21, 22, 23), "mm"),              # adapter lengths 1..3
    24: "deg",                                        # clearance angle
}

# names of the parameters the emulator's machine file sets (and the ones collectors read)
EDGE_PARAMETER_NAMES: dict[int, str] = {
    1: "type", 2: "edge position", 3: "length 1", 4: "length 2", 5: "length 3", 6: "radius",
    12: "wear of length 1", 13: "wear of length 2", 14: "wear of length 3", 15: "wear of the radius",
    26: "H number", 34: "number of teeth",
}


def edge_and_parameter(line: int, params_per_edge: int) -> tuple[int, int]:
    """(D, P) of a cuttEdgeParam line (counted from 1)."""
    edge, parameter = divmod(line - 1, params_per_edge)
    return edge + 1, parameter + 1


def parameter_unit(parameter: int) -> str:
    return EDGE_PARAMETER_UNITS.get(parameter, "")


def lines_unit(first_line: int, count: int, params_per_edge: int) -> str:
    """The one unit of ``count`` lines from ``first_line``; "" when they are bare numbers or mix units."""
    units = {parameter_unit(edge_and_parameter(line, params_per_edge)[1])
             for line in range(first_line, first_line + count)}
    return units.pop() if len(units) == 1 else ""


def describe_line(line: int, params_per_edge: int) -> str:
    """``D1 P3 (length 1)``: what one line of a tool's offsets is."""
    edge, parameter = edge_and_parameter(line, params_per_edge)
    name = EDGE_PARAMETER_NAMES.get(parameter)
    return f"D{edge} P{parameter}" + (f" ({name})" if name else "")


def units_text(parameters: Iterable[int] = range(1, 36)) -> str:
    """``mm: P3..P8, ...; deg: ...``: the units by parameter, for help and descriptions."""
    by_unit: dict[str, list[int]] = {}
    for parameter in parameters:
        unit = parameter_unit(parameter)
        if unit:
            by_unit.setdefault(unit, []).append(parameter)
    return "; ".join(f"{unit}: {', '.join(f'P{p}' for p in numbers)}" for unit, numbers in by_unit.items())
