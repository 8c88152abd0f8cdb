"""Leadscrew / measuring-system error compensation tables ($AA_ENC_COMP...) from an NC program.

The program sets ``$AA_ENC_COMP[e,N,AXi]`` (value in mm at point N), ``$AA_ENC_COMP_STEP``,
``_MIN``, ``_MAX`` and ``_IS_MODULO`` for measuring system e of axis AXi. Between points the value
is interpolated linearly; outside MIN..MAX the end values hold, unless the table is modulo.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass

from nckemu.errors import NckConfigError

_ASSIGNMENT = re.compile(
    r"^\$AA_ENC_COMP(?P<kind>_STEP|_MIN|_MAX|_IS_MODULO)?\s*\[(?P<index>[^\]]*)\]\s*=\s*(?P<value>\S+)$",
    re.IGNORECASE)
_IGNORED = re.compile(r"^(CHANDATA\s*\(\s*\d+\s*\)|M17|M30|M02|M2|M0|N\d+)$", re.IGNORECASE)


@dataclass(frozen=True)
class LeadscrewTable:
    axis: int
    encoder: int
    values_mm: tuple[float, ...]
    step_mm: float
    min_mm: float
    max_mm: float
    modulo: bool = False

    def value_mm(self, position_mm: float) -> float:
        points = self.values_mm
        if len(points) == 1 or self.step_mm <= 0:
            return points[0]
        span = self.max_mm - self.min_mm
        if self.modulo and span > 0:
            position_mm = self.min_mm + math.fmod(position_mm - self.min_mm, span)
            if position_mm < self.min_mm:
                position_mm += span
        if position_mm <= self.min_mm:
            return points[0]
        if position_mm >= self.max_mm:
            return points[-1]
        offset = (position_mm - self.min_mm) / self.step_mm
        index = min(int(offset), len(points) - 2)
        fraction = offset - index
        return points[index] + (points[index + 1] - points[index]) * fraction


def parse_leadscrew_program(text: str, source: str, axis_number: Callable[[str], int | None],
                            max_points: Callable[[int, int], int]) -> list[LeadscrewTable]:
    """Tables of an NC program; ``axis_number`` maps ``AX4``/``Z1`` to a machine axis number."""
    points: dict[tuple[int, int], dict[int, tuple[float, int]]] = {}
    params: dict[tuple[int, int], dict[str, tuple[float, int]]] = {}
    for line_number, raw_line in enumerate(text.splitlines(), start=1):
        line = raw_line.split(";", 1)[0].strip()
        if not line or _IGNORED.match(line) or line.startswith("%"):
            continue
        match = _ASSIGNMENT.match(line)
        if match is None:
            raise NckConfigError(f"not a leadscrew table line: {raw_line.strip()!r}", path=source,
                                 line=line_number)
        kind = (match["kind"] or "").upper()
        parts = [p.strip() for p in match["index"].split(",")]
        expected = 2 if kind else 3
        if len(parts) != expected:
            raise NckConfigError(f"expected {expected} indices in [{match['index']}]", path=source,
                                 line=line_number)
        try:
            encoder = int(parts[0])
            value = float(match["value"])
        except ValueError:
            raise NckConfigError(f"not a number in {line!r}", path=source, line=line_number) from None
        if encoder not in (0, 1):
            raise NckConfigError(f"measuring system {encoder}: expected 0 or 1", path=source, line=line_number)
        axis = axis_number(parts[-1])
        if axis is None:
            raise NckConfigError(f"unknown axis {parts[-1]!r}", path=source, line=line_number)
        key = (axis, encoder)
        if kind:
            params.setdefault(key, {})[kind] = (value, line_number)
        else:
            try:
                point = int(parts[1])
            except ValueError:
                raise NckConfigError(f"point index {parts[1]!r} is not a number", path=source,
                                     line=line_number) from None
            if point < 0:
                raise NckConfigError("negative point index", path=source, line=line_number)
            points.setdefault(key, {})[point] = (value, line_number)
    tables = []
    for key in sorted(set(points) | set(params)):
        axis, encoder = key
        table_points = points.get(key, {})
        table_params = params.get(key, {})
        if not table_points:
            line = min(v[1] for v in table_params.values())
            raise NckConfigError(f"axis {axis}: table parameters but no points", path=source, line=line)
        count = max(table_points) + 1
        missing = [n for n in range(count) if n not in table_points]
        if missing:
            raise NckConfigError(f"axis {axis}: point {missing[0]} missing (gap in the indices)",
                                 path=source, line=table_points[missing[0] + 1 if missing[0] + 1 in table_points
                                                                  else max(table_points)][1])
        allowed = max_points(axis, encoder)
        if count > allowed:
            raise NckConfigError(f"axis {axis}: {count} points but MD38000 allows {allowed}", path=source,
                                 line=table_points[allowed][1])
        for name in ("_STEP", "_MIN", "_MAX"):
            if name not in table_params:
                raise NckConfigError(f"axis {axis}: $AA_ENC_COMP{name} missing", path=source,
                                     line=max(v[1] for v in table_points.values()))
        step, minimum, maximum = (table_params[n][0] for n in ("_STEP", "_MIN", "_MAX"))
        if step <= 0 or maximum < minimum:
            raise NckConfigError(f"axis {axis}: STEP must be > 0 and MAX >= MIN", path=source,
                                 line=table_params["_STEP"][1])
        tables.append(LeadscrewTable(
            axis=axis, encoder=encoder, values_mm=tuple(table_points[n][0] for n in range(count)),
            step_mm=step, min_mm=minimum, max_mm=maximum,
            modulo=bool(table_params.get("_IS_MODULO", (0.0, 0))[0])))
    return tables
