"""Frames as the control computes them: translation, rotation, scale and mirror, and their chain.

A pure value module (nothing of the machine imported), so the interpreter and the NCK's frame store
share one piece of arithmetic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

GEOMETRY = ("X", "Y", "Z")
_IDENTITY = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
Matrix = tuple[float, float, float, float, float, float, float, float, float]


def _product(a: Matrix, b: Matrix) -> Matrix:
    return tuple(sum(a[3 * row + k] * b[3 * k + column] for k in range(3))  # type: ignore[return-value]
                 for row in range(3) for column in range(3))


def _about(axis: int, degrees: float) -> Matrix:
    """The rotation by ``degrees`` about geometry axis ``axis`` (0 X, 1 Y, 2 Z), counter-clockwise
    looking from the positive axis towards the origin (the right-hand rule the control uses)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    if abs(c) < 1e-15:
        c = 0.0
    if abs(s) < 1e-15:
        s = 0.0
    if axis == 0:
        return (1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
    if axis == 1:
        return (c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
    return (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)


def rotation_rpy(angles: dict[str, float]) -> Matrix:
    """ROT X.. Y.. Z..: MD10600 FRAME_ANGLE_INPUT_MODE = 1 (RPY), the rotations applied Z first,
    then about the new Y, then about the new X."""
    matrix: Matrix = _IDENTITY
    for index in (2, 1, 0):
        angle = angles.get(GEOMETRY[index], 0.0)
        if angle:
            matrix = _product(matrix, _about(index, angle))
    return matrix


def rpy_angles(matrix: Matrix) -> dict[str, float]:
    """The RPY angles (X, Y, Z in degrees) of a rotation: what $P_PFRAME[X,RT] reads back."""
    r = matrix
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, -r[6]))))
    if abs(r[6]) < 1.0 - 1e-12:
        roll = math.degrees(math.atan2(r[7], r[8]))
        yaw = math.degrees(math.atan2(r[3], r[0]))
    else:  # gimbal lock: all of the rotation about Z
        roll = 0.0
        yaw = math.degrees(math.atan2(-r[1], r[4]))
    return {"X": roll, "Y": pitch, "Z": yaw}


@dataclass(frozen=True)
class Frame:
    """One frame as the control keeps it: translation (TR), rotation (RT, over the geometry axes X Y
    Z), scale (SC) and mirror (MI). A point programmed in the frame's system is, in the system below
    it, ``translation + rotation(scale(mirror(point)))``: the programmable frame's components in the
    control's order (translation, rotation, scale, mirror). Axes other than X, Y, Z take translation,
    scale and mirror on their own."""

    translation: dict[str, float] = field(default_factory=dict)
    rotation: Matrix = _IDENTITY
    scale: dict[str, float] = field(default_factory=dict)
    mirror: frozenset[str] = frozenset()

    @property
    def rotated(self) -> bool:
        return self.rotation != _IDENTITY

    @property
    def is_translation(self) -> bool:
        return not self.rotated and not self.mirror and all(value == 1.0 for value in self.scale.values())

    def linear(self, axis: str, value: float) -> float:
        """Scale and mirror of one axis (no rotation, no translation)."""
        value *= self.scale.get(axis, 1.0)
        return -value if axis in self.mirror else value

    def vector(self, values: dict[str, float]) -> dict[str, float]:
        """A direction (an ATRANS, a centre offset) from this frame's system into the one below."""
        out = {axis: self.linear(axis, value) for axis, value in values.items()}
        if self.rotated and any(axis in out for axis in GEOMETRY):
            point = [out.get(axis, 0.0) for axis in GEOMETRY]
            r = self.rotation
            for row, axis in enumerate(GEOMETRY):
                turned = r[3 * row] * point[0] + r[3 * row + 1] * point[1] + r[3 * row + 2] * point[2]
                if axis in out or abs(turned) > 1e-12:
                    out[axis] = turned
        return out

    def apply(self, point: dict[str, float]) -> dict[str, float]:
        """A point from this frame's system into the one below."""
        out = self.vector(point)
        for axis, offset in self.translation.items():
            if axis in out:
                out[axis] += offset
        return out

    def inverse_apply(self, point: dict[str, float]) -> dict[str, float]:
        """A point of the system below into this frame's system (every geometry axis of ``point``)."""
        shifted = {axis: value - self.translation.get(axis, 0.0) for axis, value in point.items()}
        if self.rotated:
            vector = [shifted.get(axis, 0.0) for axis in GEOMETRY]
            r = self.rotation  # the transpose undoes a rotation
            for column, axis in enumerate(GEOMETRY):
                if axis in shifted:
                    shifted[axis] = r[column] * vector[0] + r[3 + column] * vector[1] + r[6 + column] * vector[2]
        out = {}
        for axis, value in shifted.items():
            if axis in self.mirror:
                value = -value
            factor = self.scale.get(axis, 1.0)
            out[axis] = value / factor if factor else value
        return out

    def coupled(self, axes: set[str] | frozenset[str]) -> set[str]:
        """The geometry axes a move of ``axes`` changes below this frame (a rotation couples them)."""
        if not self.rotated or not axes & set(GEOMETRY):
            return set(axes)
        out = set(axes)
        r = self.rotation
        for row, axis in enumerate(GEOMETRY):
            if any(abs(r[3 * row + column]) > 1e-12 for column, name in enumerate(GEOMETRY) if name in axes):
                out.add(axis)
        return out

    # --- the programmable frame's instructions -------------------------------------------------------
    def then_translate(self, values: dict[str, float]) -> Frame:
        """ATRANS: a translation in this frame's system (rotated, scaled, mirrored with it)."""
        moved = dict(self.translation)
        for axis, offset in self.vector(values).items():
            moved[axis] = moved.get(axis, 0.0) + offset
        return Frame(moved, self.rotation, self.scale, self.mirror)

    def then_rotate(self, rotation: Matrix) -> Frame:
        """AROT: a rotation about this frame's axes."""
        return Frame(self.translation, _product(self.rotation, rotation), self.scale, self.mirror)

    def then_scale(self, factors: dict[str, float]) -> Frame:
        """ASCALE: the factors multiply those in place."""
        scale = dict(self.scale)
        for axis, factor in factors.items():
            scale[axis] = scale.get(axis, 1.0) * factor
        return Frame(self.translation, self.rotation, scale, self.mirror)

    def then_mirror(self, axes: set[str]) -> Frame:
        """AMIRROR: each named axis changes its direction once more."""
        return Frame(self.translation, self.rotation, self.scale, self.mirror ^ frozenset(axes))

    def after(self, inner: Frame) -> Frame:
        """The chain ``self`` below ``inner`` (settable frame, then the programmable frame on it), as
        one frame where ``inner`` has no scale or mirror that a rotation of ``self`` would skew."""
        combined = self.then_translate(inner.translation)
        combined = combined.then_rotate(inner.rotation) if inner.rotated else combined
        combined = combined.then_scale(inner.scale) if inner.scale else combined
        return combined.then_mirror(set(inner.mirror)) if inner.mirror else combined

    def component(self, axis: str, kind: str) -> float:
        """$P_PFRAME[X,TR] and friends: TR translation, FI fine (0), RT rotation angle (RPY),
        SC scale factor, MI mirrored (1) or not (0)."""
        if kind == "TR":
            return self.translation.get(axis, 0.0)
        if kind == "FI":
            return 0.0
        if kind == "RT":
            return rpy_angles(self.rotation).get(axis, 0.0) if self.rotated else 0.0
        if kind == "SC":
            return self.scale.get(axis, 1.0)
        if kind == "MI":
            return 1.0 if axis in self.mirror else 0.0
        raise KeyError(kind)


IDENTITY_FRAME = Frame()
