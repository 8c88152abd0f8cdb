"""Tool offsets: the TO unit's tools with their cutting edges, and the active tool of each channel.

Module TO (0x14) in area T, unit 1 (the TO unit) addresses one value of one edge: the column is the T
number, the line ``(D - 1) * numCuttEdgeParams + P`` for parameter P of edge D (A2 for the 802D sl;
LSC reads column = tool, line = parameter with a line count of 7 or 35; OPCTD reads
``cuttEdgeParam[u1, c<T>, first, last]``). The active tool's lengths and radius in module S follow
the table: what a collector reads at actToolLength1 is what it reads at the active T and D.
"""

from __future__ import annotations

from nckemu.emulator.machine.machine_file import EDGE_PARAMETERS, Machine
from nckemu.errors import NckAddressOutOfRange, NckObjectDoesNotExist

P_LENGTH1 = EDGE_PARAMETERS["length1_mm"]
P_RADIUS = EDGE_PARAMETERS["radius_mm"]
P_WEAR_LENGTH1 = EDGE_PARAMETERS["wear_length1_mm"]
P_WEAR_RADIUS = EDGE_PARAMETERS["wear_radius_mm"]
P_H_NUMBER = EDGE_PARAMETERS["h_number"]


class Tools:
    """Edge parameters by T number; ``params_per_edge`` is numCuttEdgeParams."""

    def __init__(self, machine: Machine) -> None:
        self.params_per_edge = machine.tool_settings.cutting_edge_params
        self.idents = {tool.number: tool.ident for tool in machine.tools}
        self.edges: dict[int, list[list[float]]] = {
            tool.number: [list(edge) for edge in tool.edges] for tool in machine.tools}

    def _edge_and_param(self, t_number: int, line: int) -> tuple[list[list[float]], int, int]:
        edges = self.edges.get(t_number)
        if edges is None:
            raise NckObjectDoesNotExist(f"no tool T{t_number}")
        edge, param = divmod(line - 1, self.params_per_edge)
        if not 0 <= edge < len(edges):
            raise NckAddressOutOfRange(f"T{t_number} has {len(edges)} cutting edge(s); line {line} is D{edge + 1}")
        return edges, edge, param

    def edge_param(self, t_number: int, line: int) -> float:
        edges, edge, param = self._edge_and_param(t_number, line)
        return edges[edge][param]

    def set_edge_param(self, t_number: int, line: int, value: float) -> None:
        edges, edge, param = self._edge_and_param(t_number, line)
        edges[edge][param] = value

    def has_edge(self, t_number: int, d_number: int) -> bool:
        return 1 <= d_number <= len(self.edges.get(t_number, []))

    def parameter(self, t_number: int, d_number: int, number: int) -> float:
        """Parameter ``number`` (1-based) of edge D of tool T; 0 when T0 / D0 (no offset active)."""
        if not self.has_edge(t_number, d_number):
            return 0.0
        return self.edges[t_number][d_number - 1][number - 1]

    def active_length_mm(self, t_number: int, d_number: int, component: int) -> float:
        """Length ``component`` (1..3) of the active edge, geometry plus wear (assumed: the NCK shows the
        length it compensates with)."""
        return (self.parameter(t_number, d_number, P_LENGTH1 + component - 1)
                + self.parameter(t_number, d_number, P_WEAR_LENGTH1 + component - 1))

    def h_number(self, t_number: int, d_number: int) -> int:
        """The H number of edge D of tool T (edge parameter 26); 0 when the machine's edges have fewer
        parameters, or with T0 / D0."""
        if self.params_per_edge < P_H_NUMBER:
            return 0
        return round(self.parameter(t_number, d_number, P_H_NUMBER))

    def active_radius_mm(self, t_number: int, d_number: int) -> float:
        return self.parameter(t_number, d_number, P_RADIUS) + self.parameter(t_number, d_number, P_WEAR_RADIUS)
