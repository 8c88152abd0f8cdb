"""The planner: how long each canonical motion takes on this machine, in simulated seconds.

It never sees program text. Each axis moves on a trapezoid (accelerate at MD32300 MAX_AX_ACCEL,
cruise, decelerate) whose top speed is MD32000 MAX_AX_VELO; a path move is limited by every axis it
moves (an axis carrying a share ``d_i / L`` of the path may not exceed its own speed or acceleration).

- Rapid (G0): every axis at its own maximum speed times ``rapFeedRateOvr``; the slowest axis sets the
  time (the others are interpolated to arrive with it, as SINUMERIK's linear G0 does).
- Feed (G1, G2, G3): ``F`` along the path (mm/min under G94, mm/rev under G95 times the spindle's actual
  speed, 1/min under G93) times ``feedRateIpoOvr``, limited by the axes; an arc counts its length
  (helix included).
- Exact stop (G60, G9: ``exact_stop`` True) ends a block at standstill; under G64 a block hands its
  speed to the next one, so only the first block of a run accelerates and only the last decelerates
  (a block shorter than its ramps is taken as a triangle: an approximation of SINUMERIK's look-ahead).
- The spindle ramps to ``S`` times ``speedOvr`` at the machine file's spindle acceleration (rev/s²),
  clipped to MD35100 SPIND_VELO_LIMIT.
- Dwell (G4 F seconds) is exact; G4 S counts revolutions of the spindle at its speed then.

The same motion takes the same time whatever the clock: nothing here reads a clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from nckemu.emulator.machine.program.motions import Arc, Dwell, Move

MM_PER_M = 1000.0
S_PER_MIN = 60.0
# A path shorter than this is no move (positions of one block equal within rounding).
EPSILON_MM = 1.0e-9


@dataclass(frozen=True)
class AxisLimits:
    """MD32000 (mm/min, or degrees/min for a rotary axis) and MD32300 (m/s², or rev/s² for a rotary
    axis: taken here as 1000 degrees/s² per unit, like the linear axis' mm/s²; UNCONFIRMED)."""

    max_velocity_mm_min: float = 10000.0
    max_accel_m_s2: float = 1.0

    @property
    def velocity_mm_s(self) -> float:
        return self.max_velocity_mm_min / S_PER_MIN

    @property
    def accel_mm_s2(self) -> float:
        return self.max_accel_m_s2 * MM_PER_M


@dataclass(frozen=True)
class MotionLimits:
    """What the planner needs of the machine: per-axis limits by channel axis name, the spindle."""

    axes: dict[str, AxisLimits] = field(default_factory=dict)
    spindle_accel_rev_s2: float = 20.0
    spindle_max_rpm: float = 10000.0

    def axis(self, name: str) -> AxisLimits:
        return self.axes.get(name, AxisLimits())


@dataclass(frozen=True)
class Overrides:
    """Overrides in % as the channel reads them when a block starts (a change applies from the next block)."""

    feed_pct: float = 100.0
    rapid_pct: float = 100.0
    spindle_pct: float = 100.0


@dataclass(frozen=True)
class Timed:
    """A planned motion: how long it takes and the path speed it runs at (mm/min, 0 for a dwell)."""

    duration_s: float
    feed_mm_min: float = 0.0
    length_mm: float = 0.0


def ramp_time_s(length_mm: float, speed_mm_s: float, accel_mm_s2: float, ramps: int) -> float:
    """Time to cover ``length_mm`` at up to ``speed_mm_s`` with ``ramps`` (0, 1 or 2) ramps of
    ``accel_mm_s2`` (starting and/or ending at standstill). Short moves never reach full speed."""
    if length_mm <= EPSILON_MM:
        return 0.0
    if ramps <= 0 or math.isinf(accel_mm_s2):
        return length_mm / speed_mm_s
    ramp_length = ramps * speed_mm_s * speed_mm_s / (2.0 * accel_mm_s2)
    if length_mm >= ramp_length:
        return length_mm / speed_mm_s + ramps * speed_mm_s / (2.0 * accel_mm_s2)
    # never at full speed: accelerate (and decelerate) over the whole length
    return ramps * math.sqrt(2.0 * (length_mm / ramps) / accel_mm_s2)


class Planner:
    """Times canonical motions. ``moving`` says whether the last block handed on its speed (G64)."""

    def __init__(self, limits: MotionLimits) -> None:
        self.limits = limits
        self.moving = False
        # (mm/s, mm/s²) by axis, computed once: the planner runs once per block
        self._axes = {name: (axis.velocity_mm_s, axis.accel_mm_s2) for name, axis in limits.axes.items()}
        default = AxisLimits()
        self._default = (default.velocity_mm_s, default.accel_mm_s2)

    def reset(self) -> None:
        self.moving = False

    def _ramps(self, exact_stop: bool) -> int:
        ramps = (0 if self.moving else 1) + (1 if exact_stop else 0)
        self.moving = not exact_stop
        return ramps

    def move(self, start_mm: dict[str, float], move: Move, overrides: Overrides, spindle_rpm: float) -> Timed:
        deltas = {axis: target - start_mm.get(axis, 0.0) for axis, target in move.target_mm.items()}
        deltas = {axis: delta for axis, delta in deltas.items() if abs(delta) > EPSILON_MM}
        length = math.sqrt(sum(delta * delta for delta in deltas.values()))
        if move.feed is None:
            return self._rapid(deltas, length, overrides, move.exact_stop)
        return self._path(deltas, length, move.feed, move.feed_mode, overrides, spindle_rpm, move.exact_stop)

    def straight(self, deltas: list[tuple[str, float]], feed: float | None, feed_mode: str, exact_stop: bool,
                 feed_pct: float, rapid_pct: float, spindle_rpm: float) -> tuple[float, float, float]:
        """:meth:`move` for the channel's hot path: ``deltas`` (axis, target - start) of the axes that
        move (|delta| above EPSILON_MM), overrides as numbers; (duration_s, feed_mm_min, length_mm).
        The same arithmetic in the same order as :meth:`move` (a property test holds them equal), with
        no dictionaries or records built and the single-segment trapezoid inlined."""
        squares = 0.0
        for _, delta in deltas:
            squares += delta * delta
        length = math.sqrt(squares)
        if feed is None:
            if not deltas:
                return 0.0, 0.0, 0.0
            timed = self._rapid(dict(deltas), length, Overrides(feed_pct, rapid_pct, 100.0), exact_stop)
            return timed.duration_s, timed.feed_mm_min, timed.length_mm
        if length <= EPSILON_MM:
            return 0.0, 0.0, 0.0
        factor = max(feed_pct, 0.0) / 100.0
        if feed_mode == "G95":
            speed_mm_s = feed * abs(spindle_rpm) / S_PER_MIN
        elif feed_mode == "G93":
            speed_mm_s = length * feed / S_PER_MIN
        else:
            speed_mm_s = feed / S_PER_MIN
        speed_mm_s *= factor
        accel = math.inf
        axes, default = self._axes, self._default
        for axis, delta in deltas:
            part = abs(delta) / length
            if part <= 0.0:
                continue
            velocity, acceleration = axes.get(axis, default)
            if velocity < speed_mm_s * part:
                speed_mm_s = velocity / part
            if acceleration < accel * part:
                accel = acceleration / part
        if speed_mm_s <= 0.0:
            return math.inf, 0.0, length
        ramps = (0 if self.moving else 1) + (1 if exact_stop else 0)
        self.moving = not exact_stop
        # ramp_time_s, inlined
        if ramps <= 0 or accel == math.inf:
            duration = length / speed_mm_s
        elif length >= ramps * speed_mm_s * speed_mm_s / (2.0 * accel):
            duration = length / speed_mm_s + ramps * speed_mm_s / (2.0 * accel)
        else:
            duration = ramps * math.sqrt(2.0 * (length / ramps) / accel)
        return duration, speed_mm_s * S_PER_MIN, length

    def arc(self, start_mm: dict[str, float], arc: Arc, overrides: Overrides, spindle_rpm: float) -> Timed:
        first, second = _plane_axes(arc.plane)
        centre_a = arc.centre_mm.get(first, start_mm.get(first, 0.0))
        centre_b = arc.centre_mm.get(second, start_mm.get(second, 0.0))
        start_a, start_b = start_mm.get(first, 0.0) - centre_a, start_mm.get(second, 0.0) - centre_b
        end_a = arc.target_mm.get(first, start_mm.get(first, 0.0)) - centre_a
        end_b = arc.target_mm.get(second, start_mm.get(second, 0.0)) - centre_b
        radius = math.hypot(start_a, start_b)
        sweep = math.atan2(end_b, end_a) - math.atan2(start_b, start_a)
        if arc.clockwise:
            sweep = -sweep
        sweep %= 2.0 * math.pi
        if sweep <= 1.0e-12:
            sweep = 2.0 * math.pi  # start = end: a full circle
        sweep += 2.0 * math.pi * arc.turns
        helix = {axis: target - start_mm.get(axis, 0.0) for axis, target in arc.target_mm.items()
                 if axis not in (first, second)}
        rise = math.sqrt(sum(delta * delta for delta in helix.values()))
        length = math.hypot(radius * sweep, rise)
        # Every plane axis may carry the whole path speed somewhere on the circle.
        shares = {first: length, second: length, **{axis: abs(delta) for axis, delta in helix.items()}}
        return self._path(shares, length, arc.feed, arc.feed_mode, overrides, spindle_rpm, arc.exact_stop)

    def dwell(self, dwell: Dwell, spindle_rpm: float) -> Timed:
        self.moving = False
        if dwell.seconds is not None:
            return Timed(max(0.0, dwell.seconds))
        revolutions = dwell.spindle_revolutions or 0.0
        if abs(spindle_rpm) < 1.0e-9:
            return Timed(0.0)  # no spindle turning: the revolutions pass at once (documented)
        return Timed(abs(revolutions) / (abs(spindle_rpm) / S_PER_MIN))

    def spindle_ramp_s(self, from_rpm: float, to_rpm: float) -> float:
        accel = self.limits.spindle_accel_rev_s2
        return abs(to_rpm - from_rpm) / S_PER_MIN / accel if accel > 0 else 0.0

    def spindle_target_rpm(self, programmed_rpm: float, overrides: Overrides) -> float:
        return min(abs(programmed_rpm) * overrides.spindle_pct / 100.0, self.limits.spindle_max_rpm)

    # ------------------------------------------------------------------ internals
    def _rapid(self, deltas: dict[str, float], length: float, overrides: Overrides, exact_stop: bool) -> Timed:
        if not deltas:
            return Timed(0.0)
        factor = max(overrides.rapid_pct, 0.0) / 100.0
        self.moving = False  # G0 always ends at standstill before and after (no look-ahead into a rapid)
        if factor <= 0.0:
            return Timed(math.inf, 0.0, length)
        axes, default = self._axes, self._default
        slowest = max(ramp_time_s(abs(delta), axes.get(axis, default)[0] * factor, axes.get(axis, default)[1], 2)
                      for axis, delta in deltas.items())
        return Timed(slowest, S_PER_MIN * length / slowest if slowest > 0 else 0.0, length)

    def _path(self, shares: dict[str, float], length: float, feed: float, feed_mode: str, overrides: Overrides,
              spindle_rpm: float, exact_stop: bool) -> Timed:
        if length <= EPSILON_MM:
            return Timed(0.0)
        factor = max(overrides.feed_pct, 0.0) / 100.0
        if feed_mode == "G95":
            speed_mm_s = feed * abs(spindle_rpm) / S_PER_MIN
        elif feed_mode == "G93":
            speed_mm_s = length * feed / S_PER_MIN  # F blocks per minute
        else:
            speed_mm_s = feed / S_PER_MIN
        speed_mm_s *= factor
        accel = math.inf
        axes, default = self._axes, self._default
        for axis, share in shares.items():
            part = abs(share) / length
            if part <= 0.0:
                continue
            velocity, acceleration = axes.get(axis, default)
            if velocity < speed_mm_s * part:
                speed_mm_s = velocity / part
            if acceleration < accel * part:
                accel = acceleration / part
        if speed_mm_s <= 0.0:
            return Timed(math.inf, 0.0, length)
        duration = ramp_time_s(length, speed_mm_s, accel, self._ramps(exact_stop))
        return Timed(duration, speed_mm_s * S_PER_MIN, length)


def _plane_axes(plane: str) -> tuple[str, str]:
    return {"G17": ("X", "Y"), "G18": ("Z", "X"), "G19": ("Y", "Z")}.get(plane, ("X", "Y"))


@dataclass
class SpindleRamp:
    """The spindle's actual speed going linearly from ``from_rpm`` at ``start_s`` to ``to_rpm`` at ``end_s``."""

    from_rpm: float
    to_rpm: float
    start_s: float
    end_s: float

    def rpm_at(self, t_s: float) -> float:
        if t_s >= self.end_s or self.end_s <= self.start_s:
            return self.to_rpm
        if t_s <= self.start_s:
            return self.from_rpm
        return self.from_rpm + (self.to_rpm - self.from_rpm) * (t_s - self.start_s) / (self.end_s - self.start_s)
