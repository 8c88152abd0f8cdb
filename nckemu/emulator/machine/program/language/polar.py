"""Polar coordinates: the pole (G110, G111, G112) and end points written as angle ``AP=`` and radius ``RP=``.

A pole lies in the working plane (G17: X/Y, G18: Z/X, G19: Y/Z), in work coordinates:

- G111: the block's plane axes are the pole in the work system (absolute);
- G110: relative to the last programmed position;
- G112: relative to the last pole.

The pole may be written in polar form too (``G111 AP=30 RP=50``: from the reference point above). A
program that never sets one has the work system's origin as its pole. ``AP=`` (degrees, counter-clockwise
from the plane's first axis) and ``RP=`` (mm, or inch under G70/G700) are modal: a block may write only
one of them. G0, G1 go to the polar point on a straight line; G2/G3 turn about the pole to it (the pole
is their centre). Other axes of the block (the infeed) move as written.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from ..motions import ALARM_SYNTAX, ProgramAlarm
from .expressions import number

POLE_CODES = frozenset({110, 111, 112})


@dataclass(frozen=True, slots=True)
class Polar:
    pole_mm: tuple[float, float] = (0.0, 0.0)   # work coordinates of the plane's two axes
    angle_deg: float = 0.0                      # AP
    radius_mm: float = 0.0                      # RP

    def with_words(self, address: dict[str, Any], unit_mm: float) -> Polar:
        """AP= and RP= of a block (each keeps its last value when not written); ``address`` loses them."""
        polar = self
        if "AP" in address:
            polar = replace(polar, angle_deg=float(number(address.pop("AP"))))
        if "RP" in address:
            radius = float(number(address.pop("RP"))) * unit_mm
            if radius < 0.0:
                raise ProgramAlarm(ALARM_SYNTAX, f"RP={radius / unit_mm:g}: a polar radius is not negative")
            polar = replace(polar, radius_mm=radius)
        return polar

    def point_mm(self, origin_mm: tuple[float, float] | None = None) -> tuple[float, float]:
        """The polar point (about the pole, or about ``origin_mm``) in the plane's two axes."""
        centre = self.pole_mm if origin_mm is None else origin_mm
        angle = math.radians(self.angle_deg)
        return (centre[0] + self.radius_mm * math.cos(angle), centre[1] + self.radius_mm * math.sin(angle))

    def new_pole(self, code: int, written_mm: dict[str, float], plane: tuple[str, str],
                 position_mm: tuple[float, float], polar_words: bool) -> Polar:
        """The pole a G110/G111/G112 block sets from its plane axes (``written_mm``, work mm) or its
        AP=/RP= (``polar_words``: this record already holds them)."""
        reference = {110: position_mm, 111: (0.0, 0.0), 112: self.pole_mm}[code]
        if polar_words:
            return replace(self, pole_mm=self.point_mm(reference))
        first, second = plane
        return replace(self, pole_mm=(reference[0] + written_mm.get(first, 0.0),
                                      reference[1] + written_mm.get(second, 0.0)))
