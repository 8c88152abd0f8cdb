"""The modal settings that decide what F means and how X is read: the feed group (FGROUP), constant
cutting speed (G96/G97 with S in m/min and LIMS), radius or diameter programming (DIAMON/DIAMOF/DIAM90)
and the thread pitch of G33/G331/G332.

One immutable record (:class:`FeedRules`), held by the interpreter beside its other modal state and
copied with it for SAVE: each setting returns a new record. What it changes reaches the planner as fields
of the motion events (``Move.fgroup``, ``Move.css``, ``Move.thread``), never as program text.

- ``FGROUP(X, Y, C)``: F applies to these axes' path; ``FGROUP()`` goes back to the geometry axes.
- ``G96 S.. LIMS=..``: S is the cutting speed (m/min), the spindle turns at S over the circumference at the
  transverse axis' radius (X, about the work's X0), at most LIMS rpm; G96 switches feed per revolution
  (G95) on as the control does (group 15). G97 keeps the speed the spindle has and stays at G95;
  G93/G94/G95 end G96.
- DIAMON: X values (absolute and incremental) are diameters; DIAM90: absolute ones are, incremental ones
  radii; DIAMOF: radii (the default). The interpolation parameter I stays a radius.
- G33 ``K``/``I``/``J``: the thread's pitch along Z/X/Y (mm per revolution, modal for the next thread
  blocks); G331/G332: tapping, the pitch the same way, at the programmed S (the spindle runs as an axis,
  so no M3 is needed).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

from ..motions import ALARM_SYNTAX, ConstantCuttingSpeed, ProgramAlarm
from .expressions import number

# The axis G96 and diameter programming refer to: the transverse axis of a lathe (the first geometry axis).
TRANSVERSE_AXIS = "X"
THREAD_MOTIONS = frozenset({33, 331, 332})
DIAMETER_WORDS = frozenset({"DIAMON", "DIAMOF", "DIAM90"})
# The pitch word of each axis (G33 K for a thread along Z)
PITCH_WORDS = (("K", "Z"), ("I", "X"), ("J", "Y"))


@dataclass(frozen=True, slots=True)
class FeedRules:
    fgroup: frozenset[str] | None = None   # None: the geometry axes
    constant_speed: bool = False           # G96 active
    cutting_speed_m_min: float = 0.0
    limit_rpm: float = 0.0                 # LIMS (0: the spindle's own limit)
    diameter: str = "DIAMOF"
    pitch_mm: float = 0.0                  # the last thread pitch
    # nothing of this record changes a move (the interpreter's fast path then builds moves alone); a
    # field, not a property: the fast path reads it for every block
    plain: bool = field(init=False, compare=False, default=True)

    def __post_init__(self) -> None:
        object.__setattr__(self, "plain", self.fgroup is None and not self.constant_speed
                           and self.diameter == "DIAMOF")

    def word(self, name: str, args: list | None, names_of: Any) -> FeedRules:
        """DIAMON/DIAMOF/DIAM90 and FGROUP(...) (``names_of`` turns FGROUP's arguments into axis names)."""
        if name in DIAMETER_WORDS:
            return replace(self, diameter=name)
        if name == "FGROUP":
            axes = names_of(args or [])
            return replace(self, fgroup=frozenset(axes) if axes else None)
        return self

    def g(self, code: int) -> FeedRules:
        """A G function of group 15 (feed type)."""
        if code == 96:
            return replace(self, constant_speed=True)
        if code in (93, 94, 95, 97) and self.constant_speed:
            return replace(self, constant_speed=False)
        return self

    def spindle_words(self, speed: float | None, limit: Any) -> FeedRules:
        """S (the cutting speed under G96) and LIMS= of a block."""
        rules = self
        if limit is not None:
            rules = replace(rules, limit_rpm=abs(float(number(limit))))
        if speed is not None and rules.constant_speed:
            rules = replace(rules, cutting_speed_m_min=abs(speed))
        return rules

    def css(self, centre_mm: float, spindle: int = 1) -> ConstantCuttingSpeed | None:
        if not self.constant_speed:
            return None
        return ConstantCuttingSpeed(self.cutting_speed_m_min, self.limit_rpm, TRANSVERSE_AXIS, centre_mm, spindle)

    def radius_of(self, axis: str, value: float, incremental: bool) -> float:
        """A programmed X as a radius (the position the axis goes to)."""
        if axis != TRANSVERSE_AXIS or self.diameter == "DIAMOF" or (self.diameter == "DIAM90" and incremental):
            return value
        return value / 2.0

    def programmed_of(self, axis: str, radius: float) -> float:
        """A position back as the program writes it (a diameter under DIAMON/DIAM90), for block tables."""
        if axis == TRANSVERSE_AXIS and self.diameter != "DIAMOF":
            return radius * 2.0
        return radius

    def with_pitch(self, address: dict, unit_mm: float) -> FeedRules:
        """The pitch a thread block programs (K, I or J), else the last one."""
        for word, _axis in PITCH_WORDS:
            if word in address:
                value, _mode = address[word]
                return replace(self, pitch_mm=abs(float(number(value))) * unit_mm)
        if self.pitch_mm <= 0.0:
            raise ProgramAlarm(ALARM_SYNTAX, "thread without its pitch (K, I or J)")
        return self
