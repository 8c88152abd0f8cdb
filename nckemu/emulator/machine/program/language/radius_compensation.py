"""Tool radius compensation (G41 tool left of the contour, G42 right, G40 off) in the working plane.

The control offsets the programmed contour by the active edge's radius: a straight line moves parallel to
itself, a circle keeps its centre and grows or shrinks by the radius. Where two offset elements meet:

- on the outside of a corner the tool goes round the corner point on a circle of the edge radius (G450,
  the control's default: a transition circle, emitted as an arc of its own);
- on the inside the two offset elements are cut back to where they intersect;
- where they do not intersect, or the tool would have to go back along an element, the contour cannot be
  built: alarm 10751 (collision danger; UNCONFIRMED number); a circle whose offset radius is not positive
  is alarm 10758 (curvature radius too small; UNCONFIRMED number).

This needs the next element's direction, so a contour element is held until the next one is known (the
control's look-ahead does the same), with the blocks and events that come between it and the next, which
are then passed on in their order. The approach (the first motion after G41/G42) ends offset along the
normal of the next element's start (NORM); the retract (the motion of or after G40) starts at the last
element's offset end and goes to its programmed point. A motion that does not move in the plane (an
infeed) is passed on in its place without ending the contour. Positions are machine coordinates; the
programmed ones (``Move.programmed``, ``$P_EP``) stay as written.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..motions import Arc, Event, MFunction, Move, ProgramAlarm, ProgramEnd

ALARM_COLLISION = 10751        # UNCONFIRMED: "danger of collision due to tool radius compensation"
ALARM_CURVATURE = 10758        # UNCONFIRMED: "curvature radius with compensation value too small"
EPSILON = 1.0e-9
_END_CODES = frozenset({2, 17, 30})

Point = tuple[float, float]


@dataclass(frozen=True, slots=True)
class _Element:
    """A contour element in the plane: a line, or a circle about ``centre`` (``clockwise``)."""

    event: Move | Arc
    start: Point
    end: Point
    centre: Point | None = None
    clockwise: bool = False

    def tangent(self, at: Point) -> Point:
        if self.centre is None:
            return _unit((self.end[0] - self.start[0], self.end[1] - self.start[1]))
        radial = _unit((at[0] - self.centre[0], at[1] - self.centre[1]))
        return (radial[1], -radial[0]) if self.clockwise else (-radial[1], radial[0])


class RadiusCompensation:
    """One activation of G41/G42 in ``plane`` (its two axes) with the edge radius ``radius_mm``, from the
    programmed point ``start`` (machine coordinates) on."""

    def __init__(self, side: int, radius_mm: float, plane: tuple[str, str], start: Point) -> None:
        self.side = 1.0 if side == 41 else -1.0     # the tool's side: +1 left of the path
        self.radius_mm = radius_mm
        self.plane = plane
        self.point = start                           # the programmed (uncompensated) point reached
        self.ending = False                          # G40 programmed: the next plane motion retracts
        self.done = False
        self._held: _Element | None = None
        self._held_start: Point | None = None        # where the held element starts, compensated
        self._queue: list[Event] = []

    @property
    def holding(self) -> bool:
        return self._held is not None

    def take(self, block: Event | None, events: list[Event]) -> list[Event]:
        """A block's Block event (when held back) and its events: what may be passed on now."""
        out: list[Event] = []
        if block is not None:
            self._pass(block, out)
        for event in events:
            kind = event.__class__
            if (kind is Move or kind is Arc) and self._in_plane(event):  # type: ignore[arg-type]
                self._contour(event, out)  # type: ignore[arg-type]
            elif kind is ProgramEnd or (kind is MFunction and event.code in _END_CODES):  # type: ignore[attr-defined]
                self._flush(out)
                out.append(event)
            else:
                self._pass(event, out)
        return out

    # ------------------------------------------------------------------ internals
    def _pass(self, event: Event, out: list[Event]) -> None:
        (self._queue if self._held is not None else out).append(event)

    def _in_plane(self, motion: Move | Arc) -> bool:
        first, second = self.plane
        targets = motion.target_mm
        return motion.__class__ is Arc or abs(targets.get(first, self.point[0]) - self.point[0]) > EPSILON \
            or abs(targets.get(second, self.point[1]) - self.point[1]) > EPSILON

    def _element(self, motion: Move | Arc) -> _Element:
        first, second = self.plane
        end = (motion.target_mm.get(first, self.point[0]), motion.target_mm.get(second, self.point[1]))
        if motion.__class__ is Arc:
            centre = (motion.centre_mm.get(first, self.point[0]),  # type: ignore[union-attr]
                      motion.centre_mm.get(second, self.point[1]))  # type: ignore[union-attr]
            element = _Element(motion, self.point, end, centre, motion.clockwise)  # type: ignore[union-attr]
            if self._offset_radius(element) <= EPSILON:
                raise ProgramAlarm(ALARM_CURVATURE, f"tool radius compensation: the circle of radius "
                                   f"{_distance(end, centre):.3f} mm cannot be offset by {self.radius_mm:g} mm "
                                   "on its inside (curvature radius too small)")
            return element
        return _Element(motion, self.point, end)

    def _offset(self, element: _Element, at: Point) -> Point:
        tangent = element.tangent(at)
        return (at[0] - self.side * self.radius_mm * tangent[1], at[1] + self.side * self.radius_mm * tangent[0])

    def _offset_radius(self, element: _Element) -> float:
        assert element.centre is not None
        radius = _distance(element.end, element.centre)
        towards_centre = (self.side > 0) != element.clockwise   # G41 on a counter-clockwise circle: inside
        return radius - self.radius_mm if towards_centre else radius + self.radius_mm

    def _contour(self, motion: Move | Arc, out: list[Event]) -> None:
        if self.ending:
            self._retract(motion, out)
            return
        element = self._element(motion)
        held, held_start = self._held, self._held_start
        if held is None:  # the approach: held until the first contour element says where it ends
            self._held, self._held_start = element, None
        elif held_start is None:  # the approach ends offset along the normal of the element's start
            corner = self._offset(element, element.start)
            out.append(self._moved(held, corner))
            self._release(out)
            self._held, self._held_start = element, corner
        else:
            self._corner(held, held_start, element, out)
        self.point = element.end

    def _corner(self, held: _Element, held_start: Point, element: _Element, out: list[Event]) -> None:
        corner = held.end
        before, after = held.tangent(corner), element.tangent(corner)
        turn = before[0] * after[1] - before[1] * after[0]
        held_end, next_start = self._offset(held, corner), self._offset(element, corner)
        if self.side * turn < -EPSILON or (abs(turn) <= EPSILON and before[0] * after[0] + before[1] * after[1] < 0):
            # outside: round the corner on the edge radius (from the held end to the next start)
            out.append(self._moved(held, held_end))
            out.append(Arc({self.plane[0]: next_start[0], self.plane[1]: next_start[1]},
                           {self.plane[0]: corner[0], self.plane[1]: corner[1]}, self.side > 0, _plane_of(self.plane),
                           held.event.feed or 0.0, held.event.feed_mode, exact_stop=held.event.exact_stop))
        elif abs(turn) > EPSILON:
            # inside: both offset elements end where they cross
            next_start = self._intersection(held, held_start, element, held_end)
            held_end = next_start
            out.append(self._moved(held, held_end))
        else:
            out.append(self._moved(held, held_end))
        self._release(out)
        self._held, self._held_start = element, next_start

    def _intersection(self, held: _Element, held_start: Point, element: _Element, near: Point) -> Point:
        candidates = _crossings(self._curve(held), self._curve(element))
        if not candidates:
            raise self._collision("the offset elements do not meet")
        point = min(candidates, key=lambda candidate: _distance(candidate, near))
        if held.centre is None:
            direction = held.tangent(held.end)
            if (point[0] - held_start[0]) * direction[0] + (point[1] - held_start[1]) * direction[1] < -EPSILON:
                raise self._collision("the tool would go back along the element before the corner")
        if element.centre is None:
            direction = element.tangent(element.start)
            length = _distance(element.start, element.end)
            start = self._offset(element, element.start)
            along = (point[0] - start[0]) * direction[0] + (point[1] - start[1]) * direction[1]
            if along > length + EPSILON:
                raise self._collision("the element after the corner is shorter than the tool radius")
        return point

    def _curve(self, element: _Element) -> tuple[Point, Point | float]:
        """The offset element as (point, direction) of a line or (centre, radius) of a circle."""
        if element.centre is None:
            return self._offset(element, element.start), element.tangent(element.start)
        return element.centre, self._offset_radius(element)

    def _collision(self, why: str) -> ProgramAlarm:
        return ProgramAlarm(ALARM_COLLISION, f"tool radius compensation: the contour cannot be offset by "
                                             f"{self.radius_mm:g} mm ({why}: danger of collision)")

    def _retract(self, motion: Move | Arc, out: list[Event]) -> None:
        """G40: the last element ends at its offset end; the retract goes from there as programmed."""
        self._flush(out)
        out.append(motion)
        self.done = True

    def _flush(self, out: list[Event]) -> None:
        held = self._held
        if held is not None:
            out.append(self._moved(held, self._offset(held, held.end)) if self._held_start is not None
                       else held.event)
            self._held = None
        self._release(out)
        self.done = self.done or self.ending

    def _release(self, out: list[Event]) -> None:
        out += self._queue
        self._queue = []

    def _moved(self, element: _Element, end: Point) -> Move | Arc:
        first, second = self.plane
        return replace(element.event, target_mm={**element.event.target_mm, first: end[0], second: end[1]})


def _plane_of(plane: tuple[str, str]) -> str:
    return {("X", "Y"): "G17", ("Z", "X"): "G18", ("Y", "Z"): "G19"}.get(plane, "G17")


def _unit(vector: Point) -> Point:
    length = math.hypot(*vector)
    return (vector[0] / length, vector[1] / length) if length > EPSILON else (1.0, 0.0)


def _distance(a: Point, b: Point) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def _crossings(one: tuple[Point, Point | float], other: tuple[Point, Point | float]) -> list[Point]:
    """Where two offset elements (lines as point and direction, circles as centre and radius) cross."""
    if isinstance(one[1], float) and not isinstance(other[1], float):
        one, other = other, one
    if not isinstance(one[1], float) and not isinstance(other[1], float):
        (p, d), (q, e) = one, other
        denominator = d[0] * e[1] - d[1] * e[0]
        if abs(denominator) <= EPSILON:
            return []
        t = ((q[0] - p[0]) * e[1] - (q[1] - p[1]) * e[0]) / denominator
        return [(p[0] + t * d[0], p[1] + t * d[1])]
    if not isinstance(one[1], float):  # a line and a circle
        (p, d), (c, r) = one, other
        fx, fy = p[0] - c[0], p[1] - c[1]
        b = fx * d[0] + fy * d[1]
        disc = b * b - (fx * fx + fy * fy - r * r)  # type: ignore[operator]
        if disc < 0:
            return []
        root = math.sqrt(disc)
        return [(p[0] + t * d[0], p[1] + t * d[1]) for t in (-b - root, -b + root)]
    (c1, r1), (c2, r2) = one, other
    dist = _distance(c1, c2)
    if dist <= EPSILON or dist > r1 + r2 or dist < abs(r1 - r2):  # type: ignore[operator]
        return []
    a = (r1 * r1 - r2 * r2 + dist * dist) / (2 * dist)  # type: ignore[operator]
    h = math.sqrt(max(r1 * r1 - a * a, 0.0))  # type: ignore[operator]
    mx, my = c1[0] + a * (c2[0] - c1[0]) / dist, c1[1] + a * (c2[1] - c1[1]) / dist
    ox, oy = h * (c2[1] - c1[1]) / dist, h * (c2[0] - c1[0]) / dist
    return [(mx + ox, my - oy), (mx - ox, my + oy)]
