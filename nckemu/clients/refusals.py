"""What a machine has where a refused address points, asked of the controller as a tool would probe
it: its drives, the lines of a row, its tools and their cutting edges (``nckemu get`` and ``put`` add
it to a refusal, in NC syntax and BTSS). Each answer comes from reads, so it holds for a real NCK too."""

from __future__ import annotations

from typing import Any

from nckemu.catalogue.names import Variable
from nckemu.protocol.addresses import NckArea

from .async_client import MAX_VARIABLES, AsyncNckClient

PROBED_UNITS = 31        # a unit's five bits
PROBED_TOOLS = 32        # T numbers probed for a refused tool (a real TO unit may have more)


def _spans(numbers: list[int]) -> list[tuple[int, int]]:
    spans: list[tuple[int, int]] = []
    for number in numbers:
        if spans and spans[-1][1] == number - 1:
            spans[-1] = (spans[-1][0], number)
        else:
            spans.append((number, number))
    return spans


def ranges(numbers: list[int], prefix: str) -> str:
    """``V1..V4`` / ``col1, col2``: numbers as the fewest ranges."""
    return ", ".join(f"{prefix}{a}" if a == b else f"{prefix}{a}..{prefix}{b}" for a, b in _spans(numbers))


async def _answering(client: AsyncNckClient, variables: list[Variable]) -> list[bool]:
    """Which of ``variables`` the controller answers, 8 to a job (what a tool would probe by hand)."""
    answered: list[bool] = []
    for first in range(0, len(variables), MAX_VARIABLES):
        results = await client.get_items(*variables[first:first + MAX_VARIABLES])
        answered += [result.ok for result in results]
    return answered


def _at(variable: Variable, **changes: int) -> Variable:
    from dataclasses import replace

    address = replace(variable.address, line_count=1, **changes)
    return replace(variable, address=address)


async def unit_context(client: AsyncNckClient, spec: Any, variable: Variable, what: str, plural: str) -> str:
    """The units (drives) of an area that answer the same variable: ``drives V1..V4 (NC) or u1..4``."""
    probes = [_at(variable, unit=unit, line=spec_first_line(variable)) for unit in range(1, PROBED_UNITS + 1)]
    units = [unit for unit, ok in zip(range(1, PROBED_UNITS + 1), await _answering(client, probes), strict=True)
             if ok]
    letter = NckArea(variable.address.area).name
    if not units:
        return f"this machine has no {what} answering {spec.name}"
    return (f"this machine has {len(units)} {what if len(units) == 1 else plural}: {ranges(units, letter)} (NC) "
            f"or {ranges(units, 'u')} (BTSS)")


async def lines_context(client: AsyncNckClient, spec: Any, variable: Variable) -> str:
    """The lines this machine answers of a row (a machine file may give R fewer than the catalogue's
    100): the highest line that reads, found by halving."""
    from nckemu.catalogue.grammar import btss_base
    from nckemu.catalogue.table import short_name

    low, high = 0, spec.lines  # line ``low`` reads (0: none known), ``high + 1`` does not
    while low < high:
        middle = (low + high + 1) // 2
        if (await _answering(client, [_at(variable, line=middle)]))[0]:
            low = middle
        else:
            high = middle - 1
    if low == 0:
        return f"this machine answers no line of {spec.name}"
    name = short_name(spec)
    nc = f"R0..R{low - 1}" if spec.name == "R" else f"{name}[0..{low - 1}]"
    return (f"this machine has {low} line{'s' if low != 1 else ''}: {nc} (NC) or "
            f"{btss_base(spec)}[u{variable.address.unit},1..{low}] (BTSS)")


def spec_first_line(variable: Variable) -> int:
    return max(1, variable.address.line)


async def tool_context(client: AsyncNckClient, variable: Variable) -> str:
    """Which TO unit, tool or edge a refused tool offset lacks, with the machine's tools and edges."""
    from nckemu.catalogue.edges import describe_line

    address = variable.address
    (per_edge,) = await client.get("numCuttEdgeParams")
    per_edge = max(1, int(per_edge))
    probes = [_at(variable, unit=1, column=tool, line=1) for tool in range(1, PROBED_TOOLS + 1)]
    tools = [tool for tool, ok in zip(range(1, PROBED_TOOLS + 1), await _answering(client, probes), strict=True)
             if ok]
    listed = (f"its tools among T1..T{PROBED_TOOLS} are {ranges(tools, 'col')} (NC) or "
              f"{ranges(tools, 'c')} (BTSS)") if tools else f"it has no tools among T1..T{PROBED_TOOLS}"
    if address.unit != 1:
        return (f"no TO unit {address.unit}: T{address.unit} names the TO unit, not the tool (the tool is colN); "
                f"this machine has TO unit 1 (T1 / u1), where {listed}")
    if address.column not in tools:
        return f"no tool {address.column} (col{address.column} / c{address.column}) in TO unit 1: {listed}"
    edge_probes = [_at(variable, line=(edge - 1) * per_edge + 1) for edge in range(1, 10)]
    edges = [edge for edge, ok in zip(range(1, 10), await _answering(client, edge_probes), strict=True) if ok]
    last = len(edges) * per_edge
    asked = describe_line(address.line + address.line_count - 1, per_edge)
    return (f"tool {address.column} has {len(edges)} cutting edge{'s' if len(edges) != 1 else ''} "
            f"({ranges(edges, 'D')}) of {per_edge} parameters: lines 1..{last} (BTSS) or indices 0..{last - 1} "
            f"(NC); {asked} is past them")
