"""The planner: how long each canonical motion takes on this machine, in simulated seconds.

It never sees program text. Each axis moves on a trapezoid (accelerate at MD32300 MAX_AX_ACCEL,
cruise, decelerate) whose top speed is MD32000 MAX_AX_VELO; a path move is limited by every axis it
moves (an axis carrying a share ``d_i / L`` of the path may not exceed its own speed or acceleration).

- Rapid (G0): every axis at its own maximum speed times ``rapFeedRateOvr``; the slowest axis sets the
  time (the others are interpolated to arrive with it, as SINUMERIK's linear G0 does).
- Feed (G1, G2, G3): ``F`` along the path (mm/min under G94, mm/rev under G95 times the spindle's actual
  speed, 1/min under G93) times ``feedRateIpoOvr``, limited by the axes; an arc counts its length
  (helix included). The path is the axes of the feed group (``FGROUP``; by default the geometry axes
  X, Y, Z): its length is theirs alone, and every other axis of the block (a rotary axis, a special
  axis) travels in the same time within its own MD32000/MD32300, slowing the path where it must. A
  block that moves no axis of the group takes F along the axes it moves (degrees/min for a rotary axis).
- Constant cutting speed (G96): the spindle turns at ``S`` m/min over the transverse axis' radius,
  at most ``LIMS``; the path speed (feed per revolution) follows it along the block, whose time is
  the integral of the path over that speed. A thread (G33) is feed per revolution at its pitch, its
  feed override fixed at 100 %.
- Exact stop (G60, G9: ``exact_stop`` True) ends a block at standstill; under G64 a block hands its
  speed to the next one, so only the first block of a run accelerates and only the last decelerates
  (a block shorter than its ramps is taken as a triangle: an approximation of SINUMERIK's look-ahead).
- The spindle ramps to ``S`` times ``speedOvr`` at the machine file's spindle acceleration (rev/s²),
  clipped to MD35100 SPIND_VELO_LIMIT.
- Dwell (G4 F seconds) is exact; G4 S counts revolutions of the spindle at its speed then.

Every motion comes back as a :class:`Timed` segment: its duration, its geometry (a straight line, or
an :class:`ArcPath` for a circle or helix) and its time law (how far along the path it is at any
instant: the trapezoid it was timed with, or a table for G96), so the channel can put the axes on the
path at any instant, not only where a block ends.

The same motion takes the same time whatever the clock: nothing here reads a clock.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from nckemu.emulator.machine.machine_file import GEOMETRY_AXIS_NAMES
from nckemu.emulator.machine.program.motions import Arc, ConstantCuttingSpeed, Dwell, Move

MM_PER_M = 1000.0
S_PER_MIN = 60.0
# A path shorter than this is no move (positions of one block equal within rounding).
EPSILON_MM = 1.0e-9
# Pieces a G96 block is integrated in (its spindle speed changes along it); the time is exact for a
# line at a constant speed and within 0.01 % for a facing cut from X100 to X0 (tests).
CSS_STEPS = 256


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
    """What the planner needs of the machine: per-axis limits by channel axis name, the spindle, and the
    axes F applies to when no FGROUP is programmed (the geometry axes, MD20060)."""

    axes: dict[str, AxisLimits] = field(default_factory=dict)
    spindle_accel_rev_s2: float = 20.0
    spindle_max_rpm: float = 10000.0
    path_axes: tuple[str, ...] = GEOMETRY_AXIS_NAMES

    def axis(self, name: str) -> AxisLimits:
        return self.axes.get(name, AxisLimits())


@dataclass(frozen=True)
class Overrides:
    """Overrides in % as the channel reads them when a block starts (a change applies from the next block)."""

    feed_pct: float = 100.0
    rapid_pct: float = 100.0
    spindle_pct: float = 100.0


class Trapezoid:
    """The time law of a move timed by :func:`ramp_time_s`: accelerate from standstill (``ramp_in``), cruise
    at ``speed_mm_s``, decelerate to standstill (``ramp_out``); a move shorter than its ramps never reaches
    full speed (a triangle). :meth:`fraction` says how much of ``length_mm`` is behind at an instant."""

    __slots__ = ("length_mm", "speed_mm_s", "accel_mm_s2", "in_s", "cruise_s", "out_s", "in_mm", "cruise_mm")

    def __init__(self, length_mm: float, speed_mm_s: float, accel_mm_s2: float, ramp_in: bool,
                 ramp_out: bool) -> None:
        ramps = int(ramp_in) + int(ramp_out)
        self.length_mm = length_mm
        self.accel_mm_s2 = accel_mm_s2
        if ramps and not math.isinf(accel_mm_s2) and \
                length_mm < ramps * speed_mm_s * speed_mm_s / (2.0 * accel_mm_s2):
            speed_mm_s = math.sqrt(2.0 * accel_mm_s2 * length_mm / ramps)  # the triangle's peak
        self.speed_mm_s = speed_mm_s
        ramp_s = 0.0 if math.isinf(accel_mm_s2) or speed_mm_s <= 0.0 else speed_mm_s / accel_mm_s2
        self.in_s = ramp_s if ramp_in else 0.0
        self.out_s = ramp_s if ramp_out else 0.0
        self.in_mm = speed_mm_s * self.in_s / 2.0
        self.cruise_mm = max(0.0, length_mm - self.in_mm - speed_mm_s * self.out_s / 2.0)
        self.cruise_s = self.cruise_mm / speed_mm_s if speed_mm_s > 0.0 else math.inf

    def fraction(self, t_s: float) -> float:
        if self.length_mm <= 0.0:
            return 1.0
        if t_s <= 0.0:
            return 0.0
        if t_s < self.in_s:
            done = self.accel_mm_s2 * t_s * t_s / 2.0
        elif t_s < self.in_s + self.cruise_s:
            done = self.in_mm + self.speed_mm_s * (t_s - self.in_s)
        else:
            braking_s = min(t_s - self.in_s - self.cruise_s, self.out_s)
            done = self.in_mm + self.cruise_mm + self.speed_mm_s * braking_s \
                - (self.accel_mm_s2 * braking_s * braking_s / 2.0 if braking_s > 0.0 else 0.0)
        return min(1.0, done / self.length_mm)

    def speed_at(self, t_s: float) -> float:
        """Path speed (mm/s) at ``t_s`` after the start."""
        if t_s <= 0.0 and self.in_s > 0.0:
            return 0.0
        if t_s < self.in_s:
            return self.accel_mm_s2 * t_s
        if t_s < self.in_s + self.cruise_s:
            return self.speed_mm_s
        return max(0.0, self.speed_mm_s - self.accel_mm_s2 * (t_s - self.in_s - self.cruise_s)) if self.out_s else \
            self.speed_mm_s


class Tabulated:
    """A time law as a table: ``fractions[i]`` of the path is behind at ``times_s[i]`` (both rising from 0);
    linear between rows. For a path whose speed changes along it (G96: the spindle follows the radius)."""

    __slots__ = ("times_s", "fractions")

    def __init__(self, times_s: list[float], fractions: list[float]) -> None:
        self.times_s = times_s
        self.fractions = fractions

    def fraction(self, t_s: float) -> float:
        times = self.times_s
        if t_s <= 0.0:
            return 0.0
        if t_s >= times[-1]:
            return 1.0
        index = bisect.bisect_right(times, t_s)
        before, after = times[index - 1], times[index]
        share = (t_s - before) / (after - before) if after > before else 1.0
        return self.fractions[index - 1] + (self.fractions[index] - self.fractions[index - 1]) * share

    def speed_at(self, t_s: float) -> float:
        return 0.0


TimeLaw = Trapezoid | Tabulated
# A Trapezoid's arguments, not built yet (Planner.straight)
LawArgs = tuple[float, float, float, bool, bool]


def time_law(law: TimeLaw | LawArgs) -> TimeLaw:
    """The law itself, built from its arguments where :meth:`Planner.straight` left them."""
    return Trapezoid(*law) if law.__class__ is tuple else law  # type: ignore[arg-type,return-value]


@dataclass(frozen=True, slots=True)
class ArcPath:
    """A circle or helix in machine coordinates: the plane axes ``first``/``second`` turn about the centre by
    ``sweep_rad`` (counter-clockwise positive, full turns included) from ``start_angle_rad``, the radius
    going from ``start_radius_mm`` to ``end_radius_mm`` (equal within the circle tolerance, so the end
    point is met exactly); every other axis (the helix) goes linearly from its start to its end."""

    first: str
    second: str
    centre: tuple[float, float]
    start_radius_mm: float
    end_radius_mm: float
    start_angle_rad: float
    sweep_rad: float
    linear: tuple[tuple[str, float, float], ...] = ()

    def position(self, fraction: float) -> dict[str, float]:
        angle = self.start_angle_rad + self.sweep_rad * fraction
        radius = self.start_radius_mm + (self.end_radius_mm - self.start_radius_mm) * fraction
        position = {self.first: self.centre[0] + radius * math.cos(angle),
                    self.second: self.centre[1] + radius * math.sin(angle)}
        for axis, start, end in self.linear:
            position[axis] = start + (end - start) * fraction
        return position


@dataclass(frozen=True)
class Timed:
    """A planned motion, the segment the channel runs: how long it takes, the path speed it cruises at
    (mm/min, 0 for a dwell), its length, its time law (None: no motion) and, for a circle or helix, its
    geometry (a straight move goes from its start to its target along a line)."""

    duration_s: float
    feed_mm_min: float = 0.0
    length_mm: float = 0.0
    law: TimeLaw | None = None
    arc: ArcPath | None = None


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


def css_rpm(css: ConstantCuttingSpeed, position_mm: float, max_rpm: float) -> float:
    """The spindle speed G96 turns at with the transverse axis at ``position_mm``: the cutting speed over
    the circumference at that radius, at most LIMS and the spindle's own limit."""
    radius_mm = abs(position_mm - css.centre_mm)
    limit = min(css.limit_rpm or max_rpm, max_rpm)
    if radius_mm <= EPSILON_MM:
        return limit
    return min(limit, css.speed_m_min * MM_PER_M / (2.0 * math.pi * radius_mm))


class Planner:
    """Times canonical motions. ``moving`` says whether the last block handed on its speed (G64)."""

    def __init__(self, limits: MotionLimits) -> None:
        self.limits = limits
        self.moving = False
        # (mm/s, mm/s²) by axis, computed once: the planner runs once per block
        self._axes = {name: (axis.velocity_mm_s, axis.accel_mm_s2) for name, axis in limits.axes.items()}
        default = AxisLimits()
        self._default = (default.velocity_mm_s, default.accel_mm_s2)
        self._path_axes = frozenset(limits.path_axes)

    def reset(self) -> None:
        self.moving = False

    def _ramps(self, exact_stop: bool) -> tuple[bool, bool]:
        ramps = (not self.moving, exact_stop)
        self.moving = not exact_stop
        return ramps

    def move(self, start_mm: dict[str, float], move: Move, overrides: Overrides, spindle_rpm: float) -> Timed:
        deltas = {axis: target - start_mm.get(axis, 0.0) for axis, target in move.target_mm.items()}
        deltas = {axis: delta for axis, delta in deltas.items() if abs(delta) > EPSILON_MM}
        if move.feed is None:
            length = math.sqrt(sum(delta * delta for delta in deltas.values()))
            return self._rapid(deltas, length, overrides, move.exact_stop)
        length = self.path_length_mm(deltas, move.fgroup)
        if move.css is not None and move.feed_mode == "G95":
            axis = move.css.axis
            start, end = start_mm.get(axis, 0.0), move.target_mm.get(axis, start_mm.get(axis, 0.0))
            return self._css(deltas, length, move, overrides, lambda fraction: start + (end - start) * fraction)
        pct = 100.0 if move.thread else overrides.feed_pct
        return self._path(deltas, length, move.feed, move.feed_mode, pct, spindle_rpm, move.exact_stop)

    def path_length_mm(self, deltas: dict[str, float], fgroup: frozenset[str] | None = None) -> float:
        """The length F applies to: the feed group's axes (the geometry axes unless FGROUP says), or,
        when the block moves none of them, every axis it moves."""
        group = self._path_axes if fgroup is None else fgroup
        squares = sum(delta * delta for axis, delta in deltas.items() if axis in group)
        if squares <= EPSILON_MM * EPSILON_MM:
            squares = sum(delta * delta for delta in deltas.values())
        return math.sqrt(squares)

    def straight(self, deltas: list[tuple[str, float]], feed: float | None, feed_mode: str, exact_stop: bool,
                 feed_pct: float, rapid_pct: float, spindle_rpm: float,
                 fgroup: frozenset[str] | None = None) -> tuple[float, float, float, TimeLaw | LawArgs | None]:
        """:meth:`move` for the channel's hot path: ``deltas`` (axis, target - start) of the axes that
        move (|delta| above EPSILON_MM), overrides as numbers; (duration_s, feed_mm_min, length_mm, law).
        The same arithmetic in the same order as :meth:`move` (a property test holds them equal), with
        no dictionaries built and the single-segment trapezoid inlined. A move at feed gives its law as
        the :class:`Trapezoid`'s arguments (:func:`time_law` builds it): most moves end within a cycle
        and nobody asks where they were in between."""
        if feed is None:
            if not deltas:
                return 0.0, 0.0, 0.0, None
            squares = 0.0
            for _, delta in deltas:
                squares += delta * delta
            timed = self._rapid(dict(deltas), math.sqrt(squares), Overrides(feed_pct, rapid_pct, 100.0), exact_stop)
            return timed.duration_s, timed.feed_mm_min, timed.length_mm, timed.law
        group = self._path_axes if fgroup is None else fgroup
        squares = 0.0
        for axis, delta in deltas:
            if axis in group:
                squares += delta * delta
        if squares <= EPSILON_MM * EPSILON_MM:  # no axis of the feed group moves: F along the others
            squares = 0.0
            for _, delta in deltas:
                squares += delta * delta
        length = math.sqrt(squares)
        if length <= EPSILON_MM:
            return 0.0, 0.0, 0.0, None
        factor = (0.0 if 0.0 > feed_pct else feed_pct) / 100.0  # max(feed_pct, 0.0) without the call
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
            return math.inf, 0.0, length, None
        ramp_in = not self.moving
        self.moving = not exact_stop
        # ramp_time_s, inlined
        ramps = ramp_in + exact_stop
        if ramps <= 0 or accel == math.inf:
            duration = length / speed_mm_s
        elif length >= ramps * speed_mm_s * speed_mm_s / (2.0 * accel):
            duration = length / speed_mm_s + ramps * speed_mm_s / (2.0 * accel)
        else:
            duration = ramps * math.sqrt(2.0 * (length / ramps) / accel)
        return duration, speed_mm_s * S_PER_MIN, length, (length, speed_mm_s, accel, ramp_in, exact_stop)

    def arc(self, start_mm: dict[str, float], arc: Arc, overrides: Overrides, spindle_rpm: float) -> Timed:
        path = arc_path(start_mm, arc)
        radius = path.start_radius_mm
        group = self._path_axes if arc.fgroup is None else arc.fgroup
        helix = {axis: end - start for axis, start, end in path.linear if abs(end - start) > EPSILON_MM}
        rise = math.sqrt(sum(delta * delta for axis, delta in helix.items() if axis in group))
        turned = radius * abs(path.sweep_rad)
        length = math.hypot(turned, rise)
        if length <= EPSILON_MM:
            length = math.sqrt(sum(delta * delta for delta in helix.values()))
        # Every plane axis may carry the whole circle's speed somewhere on it.
        shares = {path.first: turned, path.second: turned, **{axis: abs(delta) for axis, delta in helix.items()}}
        if arc.css is not None and arc.feed_mode == "G95":
            axis = arc.css.axis
            timed = self._css(shares, length, arc, overrides,
                              lambda fraction: path.position(fraction).get(axis, start_mm.get(axis, 0.0)))
        else:
            timed = self._path(shares, length, arc.feed, arc.feed_mode, overrides.feed_pct, spindle_rpm,
                               arc.exact_stop)
        return replace(timed, arc=path)

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
        slowest, law = -1.0, None
        for axis, delta in deltas.items():
            velocity, acceleration = axes.get(axis, default)
            duration = ramp_time_s(abs(delta), velocity * factor, acceleration, 2)
            if duration > slowest:
                slowest = duration
                # the other axes are interpolated to arrive with the slowest: its law is the block's
                law = Trapezoid(abs(delta), velocity * factor, acceleration, True, True)
        return Timed(slowest, S_PER_MIN * length / slowest if slowest > 0 else 0.0, length, law)

    def _path_speed_mm_s(self, shares: dict[str, float], length: float, speed_mm_s: float) -> tuple[float, float]:
        """The path speed and acceleration the axes allow, each carrying ``share / length`` of the path."""
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
        return speed_mm_s, accel

    def _path(self, shares: dict[str, float], length: float, feed: float, feed_mode: str, feed_pct: float,
              spindle_rpm: float, exact_stop: bool) -> Timed:
        if length <= EPSILON_MM:
            return Timed(0.0)
        factor = max(feed_pct, 0.0) / 100.0
        if feed_mode == "G95":
            speed_mm_s = feed * abs(spindle_rpm) / S_PER_MIN
        elif feed_mode == "G93":
            speed_mm_s = length * feed / S_PER_MIN  # F blocks per minute
        else:
            speed_mm_s = feed / S_PER_MIN
        speed_mm_s, accel = self._path_speed_mm_s(shares, length, speed_mm_s * factor)
        if speed_mm_s <= 0.0:
            return Timed(math.inf, 0.0, length)
        ramp_in, ramp_out = self._ramps(exact_stop)
        duration = ramp_time_s(length, speed_mm_s, accel, ramp_in + ramp_out)
        return Timed(duration, speed_mm_s * S_PER_MIN, length, Trapezoid(length, speed_mm_s, accel, ramp_in, ramp_out))

    def _css(self, shares: dict[str, float], length: float, motion: Move | Arc, overrides: Overrides,
             transverse_at: Callable[[float], float]) -> Timed:
        """G96: feed per revolution with the spindle at the cutting speed over the radius, which changes
        along the path; the time is the path integrated in CSS_STEPS pieces, each at its middle's speed
        (the axes' limits as for any path; the spindle taken to follow at once, ramps left out)."""
        if length <= EPSILON_MM:
            return Timed(0.0)
        css = motion.css
        assert css is not None and motion.feed is not None
        factor = max(overrides.feed_pct, 0.0) / 100.0 * overrides.spindle_pct / 100.0
        top_mm_s, _ = self._path_speed_mm_s(shares, length, math.inf)
        times, fractions, elapsed, fastest = [0.0], [0.0], 0.0, 0.0
        for step in range(CSS_STEPS):
            middle = (step + 0.5) / CSS_STEPS
            rpm = css_rpm(css, transverse_at(middle), self.limits.spindle_max_rpm)
            speed_mm_s = min(motion.feed * rpm / S_PER_MIN * factor, top_mm_s)
            if speed_mm_s <= 0.0:
                return Timed(math.inf, 0.0, length)
            fastest = max(fastest, speed_mm_s)
            elapsed += length / CSS_STEPS / speed_mm_s
            times.append(elapsed)
            fractions.append((step + 1) / CSS_STEPS)
        self._ramps(motion.exact_stop)
        return Timed(elapsed, fastest * S_PER_MIN, length, Tabulated(times, fractions))


def arc_path(start_mm: dict[str, float], arc: Arc) -> ArcPath:
    """The circle (or helix) ``arc`` describes from ``start_mm``: centre, radii, start angle, sweep."""
    first, second = _plane_axes(arc.plane)
    centre_a = arc.centre_mm.get(first, start_mm.get(first, 0.0))
    centre_b = arc.centre_mm.get(second, start_mm.get(second, 0.0))
    start_a, start_b = start_mm.get(first, 0.0) - centre_a, start_mm.get(second, 0.0) - centre_b
    end_a = arc.target_mm.get(first, start_mm.get(first, 0.0)) - centre_a
    end_b = arc.target_mm.get(second, start_mm.get(second, 0.0)) - centre_b
    start_angle = math.atan2(start_b, start_a)
    sweep = math.atan2(end_b, end_a) - start_angle
    if arc.clockwise:
        sweep = -sweep
    sweep %= 2.0 * math.pi
    if sweep <= 1.0e-12:
        sweep = 2.0 * math.pi  # start = end: a full circle
    sweep += 2.0 * math.pi * arc.turns
    linear = tuple((axis, start_mm.get(axis, 0.0), target) for axis, target in arc.target_mm.items()
                   if axis not in (first, second))
    return ArcPath(first, second, (centre_a, centre_b), math.hypot(start_a, start_b), math.hypot(end_a, end_b),
                   start_angle, -sweep if arc.clockwise else sweep, linear)


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
