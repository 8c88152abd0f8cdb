"""Frames in a program: the programmable frame's instructions, the chain they make with the settable
frame, moves and circles through that chain, and the frame system variables.

The chain is the control's: the settable frame (G54...; translation only here, as the NCK stores it),
then the programmable frame on it. Within the programmable frame the components act in the
control's order, translation, rotation, scale, mirror (:class:`~nckemu.emulator.machine.nck.frames.Frame`).
``TRANS``, ``ROT``, ``SCALE`` and ``MIRROR`` replace the whole programmable frame with their one
component (without values: delete it); ``ATRANS``, ``AROT``, ``ASCALE`` and ``AMIRROR`` add theirs in
the system the frame has made so far (an ATRANS after a ROT goes along the rotated axes).
"""

from __future__ import annotations

import math
from typing import Any

from nckemu.emulator.machine.frame_math import GEOMETRY, IDENTITY_FRAME, Frame, rotation_rpy

from ..motions import ALARM_NAME_NOT_DEFINED, ALARM_SYNTAX, Arc, Move, ProgramAlarm
from .alarms import ALARM_FRAME

# The axis a plane rotation (RPL=) turns about: the plane's infeed axis.
PLANE_NORMAL = {"G17": "Z", "G18": "Y", "G19": "X"}
# The machine plane whose normal is a geometry axis, and the planes' axes (first, second).
_PLANE_OF_NORMAL = {"Z": "G17", "Y": "G18", "X": "G19"}
_PLANE_AXES = {"G17": ("X", "Y"), "G18": ("Z", "X"), "G19": ("Y", "Z")}
# $P_UIFR[n,X,TR] and friends: the component names the control reads.
COMPONENTS = frozenset({"TR", "FI", "RT", "SC", "MI"})
FRAME_VARIABLES = frozenset({"$P_PFRAME", "$P_UIFR", "$P_IFRAME", "$P_ACTFRAME", "$P_BFRAME"})


def _frame_pairs(word: str, args: tuple[Any, ...], valued: bool) -> list[tuple[str, Any]]:
    """``X, 10, Y, 5`` (``X, Y`` for CMIRROR) as (axis, value) pairs; an axis is a name (an AXIS value)."""
    step = 2 if valued else 1
    if len(args) % step:
        raise ProgramAlarm(ALARM_SYNTAX, f"{word}(axis, value, ...): an axis without its value")
    pairs = []
    for at in range(0, len(args), step):
        axis = args[at]
        if axis.__class__ is not str:
            raise ProgramAlarm(ALARM_SYNTAX, f"{word}: {axis!r} stands where an axis belongs")
        value = args[at + 1] if valued else 1
        if value.__class__ is bool or value.__class__ not in (int, float):
            raise ProgramAlarm(ALARM_SYNTAX, f"{word}: {value!r} is no value for axis {axis}")
        pairs.append((axis.upper(), float(value)))
    return pairs


def frame_function(word: str) -> Any:
    """CTRANS, CROT, CSCALE, CMIRROR: a FRAME value with that one component (``CTRANS()``: the empty
    frame), as TRANS, ROT, SCALE and MIRROR would set it from nothing (the plane's RPL is not one of
    their forms: CROT names its axes)."""
    instruction = word[1:]

    def build(*args: Any) -> Frame:
        pairs = _frame_pairs(word, args, valued=instruction != "MIRROR")
        return programmed_frame(IDENTITY_FRAME, instruction, pairs, "G17")
    return build


def chained(outer: Any, inner: Any) -> Frame:
    """``A : B``, the frame chain operator: ``B`` acting in the system ``A`` has made."""
    if outer.__class__ is not Frame or inner.__class__ is not Frame:
        from .alarms import ALARM_TYPE
        raise ProgramAlarm(ALARM_TYPE, "the chain operator ':' joins two FRAME values (CTRANS(..) : CROT(..))")
    return outer.after(inner)


FRAME_FUNCTIONS = {name: frame_function(name) for name in ("CTRANS", "CROT", "CSCALE", "CMIRROR")}


def settable_name(index: Any) -> str:
    """The G function of settable frame ``index`` ($P_UIFR[index]): 0 G500, 1..4 G54..G57, 5.. G505..."""
    position = int(index) if isinstance(index, int | float) and not isinstance(index, bool) else -1
    if not 0 <= position <= 99:
        raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"$P_UIFR[{index}]: no settable frame of that index (0..99)")
    return "G500" if position == 0 else (f"G{53 + position}" if position <= 4 else f"G{500 + position}")


def programmed_frame(current: Frame, word: str, values: list[tuple[str, float]], plane: str) -> Frame:
    """The programmable frame after ``word`` (TRANS, AROT, ...) with its values (axis or RPL, value)."""
    additive = word[0] == "A"
    kind = word[1:] if additive else word
    base = current if additive else IDENTITY_FRAME
    if not values:
        return base
    if kind != "ROT" and any(axis == "RPL" for axis, _ in values):
        raise ProgramAlarm(ALARM_SYNTAX, f"{word}: RPL= belongs to ROT and AROT")
    if kind == "TRANS":
        return base.then_translate(_summed(values))
    if kind == "ROT":
        angles: dict[str, float] = {}
        for axis, angle in values:
            name = PLANE_NORMAL.get(plane, "Z") if axis == "RPL" else axis
            if name not in GEOMETRY:
                raise ProgramAlarm(ALARM_FRAME, f"{word} {axis}: a rotation is about a geometry axis (X, Y, Z)")
            angles[name] = angles.get(name, 0.0) + angle
        return base.then_rotate(rotation_rpy(angles))
    if kind == "SCALE":
        for axis, factor in values:
            if factor == 0:
                raise ProgramAlarm(ALARM_FRAME, f"{word} {axis}0: a frame cannot scale an axis by 0")
        factors: dict[str, float] = {}
        for axis, factor in values:
            factors[axis] = factors.get(axis, 1.0) * factor
        return base.then_scale(factors)
    return base.then_mirror({axis for axis, _ in values})


def _summed(values: list[tuple[str, float]]) -> dict[str, float]:
    out: dict[str, float] = {}
    for axis, value in values:
        out[axis] = out.get(axis, 0.0) + value
    return out


def chain(settable: dict[str, float], programmable: Frame) -> Frame:
    """The settable frame (its translation) with the programmable frame on it."""
    if not settable:
        return programmable
    return Frame(dict(settable)).after(programmable)


def framed_arc(arc: Arc, start: dict[str, float], frame: Frame, tool: dict[str, float]) -> Arc | list[Move]:
    """A circle computed in the work system (targets and centre there, ``start`` its start point) brought
    below ``frame`` and the tool length ``tool`` (machine axis -> mm). Where the circle's plane comes
    out as a machine plane with its two axes scaled alike it stays a circle; otherwise (a plane the
    frame tilts, CYCLE800's swivel; an ellipse of an uneven scale) it becomes straight chords at
    continuous path within ``CHORD_TOLERANCE_MM``, points of the circle taken through the frame."""
    first, second = _PLANE_AXES[arc.plane]
    normal = PLANE_NORMAL[arc.plane]
    factors = (frame.scale.get(first, 1.0), frame.scale.get(second, 1.0))
    turned = Frame(rotation=frame.rotation).vector({normal: 1.0})
    axis = max(turned, key=lambda name: abs(turned[name]))
    if abs(abs(factors[0]) - abs(factors[1])) > 1e-12 or abs(abs(turned[axis]) - 1.0) > 1e-9:
        return _chords(arc, start, frame, tool)
    plane = _PLANE_OF_NORMAL[axis]
    # The sense of turning: flipped when the normal comes out reversed, and once more per mirrored
    # (or negatively scaled) axis of the plane.
    flips = (turned[axis] < 0) + sum(1 for name, factor in zip((first, second), factors, strict=True)
                                     if (name in frame.mirror) != (factor < 0))
    clockwise = arc.clockwise if flips % 2 == 0 else not arc.clockwise
    targets = frame.apply(arc.target_mm)
    centre_work = dict(arc.centre_mm)
    centre_work.setdefault(normal, 0.0)
    centre = frame.apply(centre_work)
    machine_first, machine_second = _PLANE_AXES[plane]
    for name, length in tool.items():
        if name in targets:
            targets[name] += length
        if name in centre:
            centre[name] += length
    return Arc(targets, {machine_first: centre.get(machine_first, 0.0), machine_second: centre.get(machine_second, 0.0)},
               clockwise, plane, arc.feed, arc.feed_mode, arc.turns, arc.exact_stop,  # type: ignore[arg-type]
               arc.programmed)


# The largest distance between a chord and its circle where a frame leaves no machine plane for it.
CHORD_TOLERANCE_MM = 0.01
MAX_CHORDS = 3600


def _chords(arc: Arc, start: dict[str, float], frame: Frame, tool: dict[str, float]) -> list[Move]:
    first, second = _PLANE_AXES[arc.plane]
    centre = (arc.centre_mm[first], arc.centre_mm[second])
    begin = (start.get(first, centre[0]) - centre[0], start.get(second, centre[1]) - centre[1])
    end = (arc.target_mm.get(first, start.get(first, 0.0)) - centre[0],
           arc.target_mm.get(second, start.get(second, 0.0)) - centre[1])
    radius = math.hypot(*begin)
    angle_from = math.atan2(begin[1], begin[0])
    sweep = math.atan2(end[1], end[0]) - angle_from
    if arc.clockwise:
        sweep = sweep - 2 * math.pi if sweep >= 0 else sweep
    else:
        sweep = sweep + 2 * math.pi if sweep <= 0 else sweep
    sweep += (-2 * math.pi if arc.clockwise else 2 * math.pi) * arc.turns
    scale = max(abs(frame.scale.get(first, 1.0)), abs(frame.scale.get(second, 1.0)))
    size = radius * scale
    step = 2 * math.acos(max(-1.0, 1 - CHORD_TOLERANCE_MM / size)) if size > CHORD_TOLERANCE_MM else math.pi
    count = min(MAX_CHORDS, max(1, math.ceil(abs(sweep) / step)))
    others = {axis: (start.get(axis, value), value) for axis, value in arc.target_mm.items() if axis not in (first, second)}
    moves: list[Move] = []
    for index in range(1, count + 1):
        share = index / count
        angle = angle_from + sweep * share
        point = {first: centre[0] + radius * math.cos(angle), second: centre[1] + radius * math.sin(angle)}
        point.update({axis: begin_value + (end_value - begin_value) * share
                      for axis, (begin_value, end_value) in others.items()})
        if index == count:
            point.update(arc.target_mm)
        target = frame.apply(point)
        for name, length in tool.items():
            if name in target:
                target[name] += length
        last = index == count
        moves.append(Move(target, arc.feed, arc.feed_mode, arc.exact_stop if last else False,
                          arc.programmed if last else {}))
    return moves


def read_component(frame: Frame, indices: tuple[Any, ...], name: str) -> float:
    """``$P_PFRAME[X,TR]``: one component of one axis of ``frame``."""
    if len(indices) != 2:
        raise ProgramAlarm(ALARM_SYNTAX, f"{name}[axis, component] (a whole FRAME value is not supported "
                                         f"by the emulator)")
    axis, kind = (str(index).upper() for index in indices)
    if kind not in COMPONENTS:
        raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name}: {kind} is no frame component (TR FI RT SC MI)")
    return frame.component(axis, kind)


def with_component(frame: Frame, indices: tuple[Any, ...], name: str, value: float) -> Frame:
    """``$P_PFRAME[X,TR]=5``: ``frame`` with one component of one axis set."""
    if len(indices) != 2:
        raise ProgramAlarm(ALARM_SYNTAX, f"{name}[axis, component]=value")
    axis, kind = (str(index).upper() for index in indices)
    if kind == "TR":
        translation = dict(frame.translation)
        translation[axis] = value
        return Frame(translation, frame.rotation, frame.scale, frame.mirror)
    if kind == "SC":
        if value == 0:
            raise ProgramAlarm(ALARM_FRAME, f"{name}[{axis},SC]=0: a frame cannot scale an axis by 0")
        scale = dict(frame.scale)
        scale[axis] = value
        return Frame(frame.translation, frame.rotation, scale, frame.mirror)
    if kind == "MI":
        mirror = frame.mirror | {axis} if value else frame.mirror - {axis}
        return Frame(frame.translation, frame.rotation, frame.scale, mirror)
    if kind == "RT" and axis in GEOMETRY:
        angles = {name: frame.component(name, "RT") for name in GEOMETRY}
        angles[axis] = value
        return Frame(frame.translation, rotation_rpy(angles), frame.scale, frame.mirror)
    if kind == "FI":
        return frame
    raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name}[{axis},{kind}] cannot be written")
