"""The standard cycles the emulator simulates, as the motions they make.

A Siemens standard cycle is a subprogram in the control's cycle directories; a program calls it with
its parameters (``CYCLE81(RTP, RFP, SDIS, DP, DPR)``). Here each simulated cycle is a function from
its parameters (positions in the work system, on the infeed axis of the active plane) to *steps*:
rapid and feed moves, dwells, spindle commands and a programmed stop, which the interpreter runs
through its own motion (frames, tool length, units) so that the planner times them like any block.
The parameter lists and sequences are those of the Siemens cycle descriptions (Programming Manual
Cycles, drilling cycles and drilling patterns); where a rule is ours it says so.

A program's own program of a cycle's name (a ``CYCLE81.SPF`` beside it) is called instead: the
interpreter asks the environment first. A cycle every control has but this emulator does not simulate
(``CYCLE62``, ``POCKET3``) takes no time and is counted apart; a ``CYCLE...`` name no control has is
14011 like any missing program.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from ..motions import ProgramAlarm

# The cycle's own alarms (UNCONFIRMED numbers, as we remember the 61000 range of the cycles):
ALARM_CYCLE_PARAMETER = 61000   # a parameter out of its range (no depth, a retraction plane below the hole)
ALARM_THREAD_PITCH = 61001      # tapping without a pitch (MPIT and PIT both 0, or a size without a pitch)

DRILLING = frozenset({"CYCLE81", "CYCLE82", "CYCLE83", "CYCLE84", "CYCLE840", "CYCLE85", "CYCLE86", "CYCLE87",
                      "CYCLE88", "CYCLE89"})
PATTERNS = frozenset({"HOLES1", "HOLES2", "CYCLE801"})
# Cycles that make no motion on a control either: accepted, what they set is recorded.
MOTIONLESS = frozenset({"CYCLE832", "WORKPIECE"})
# Standard cycles of the 840D sl / 828D cycle packages the emulator has no motion for (milling,
# turning, measuring, ShopMill/ShopTurn steps): they run in 0 s and are counted apart.
NOT_SIMULATED = frozenset({
    "CYCLE60", "CYCLE61", "CYCLE62", "CYCLE63", "CYCLE64", "CYCLE70", "CYCLE71", "CYCLE72", "CYCLE73", "CYCLE74",
    "CYCLE75", "CYCLE76", "CYCLE77", "CYCLE78", "CYCLE79", "CYCLE90", "CYCLE92", "CYCLE93", "CYCLE94", "CYCLE95",
    "CYCLE96", "CYCLE97", "CYCLE98", "CYCLE99", "CYCLE802", "CYCLE830", "CYCLE899", "CYCLE930", "CYCLE940",
    "CYCLE950", "CYCLE951", "CYCLE952", "CYCLE4071", "CYCLE4072", "CYCLE4073", "CYCLE4074", "CYCLE4075",
    "CYCLE4076", "CYCLE4077", "CYCLE4078", "CYCLE4079", "CYCLE961", "CYCLE971", "CYCLE973", "CYCLE974",
    "CYCLE976", "CYCLE977", "CYCLE978", "CYCLE979", "CYCLE982", "CYCLE994", "CYCLE995", "CYCLE996", "CYCLE997",
    "CYCLE998", "POCKET1", "POCKET2", "POCKET3", "POCKET4", "SLOT1", "SLOT2", "LONGHOLE",
})
SWIVEL = "CYCLE800"
KNOWN = DRILLING | PATTERNS | MOTIONLESS | NOT_SIMULATED | {SWIVEL}

# Metric coarse threads: MPIT (the size, M3..M48) -> pitch in mm (ISO 261), for CYCLE84/CYCLE840.
_METRIC_PITCH_MM = {3: 0.5, 4: 0.7, 5: 0.8, 6: 1.0, 8: 1.25, 10: 1.5, 12: 1.75, 14: 2.0, 16: 2.0, 18: 2.5, 20: 2.5,
                    22: 2.5, 24: 3.0, 27: 3.0, 30: 3.5, 33: 3.5, 36: 4.0, 39: 4.0, 42: 4.5, 45: 4.5, 48: 5.0}
MAX_STROKES = 10_000


def is_shop_step(name: str) -> bool:
    """ShopMill/ShopTurn steps (E_..., F_...): standard on a control, not simulated here."""
    return name.startswith(("E_", "F_"))


@dataclass(frozen=True, slots=True)
class Rapid:
    target: dict[str, float]          # work coordinates (mm; degrees for rotary axes), absolute


@dataclass(frozen=True, slots=True)
class Feed:
    target: dict[str, float]
    feed_mm_min: float | None = None   # None: the feed the caller programmed


@dataclass(frozen=True, slots=True)
class Wait:
    seconds: float | None = None
    revolutions: float | None = None


@dataclass(frozen=True, slots=True)
class Spindle:
    direction: str                     # M3, M4, M5
    speed_rpm: float | None = None


@dataclass(frozen=True, slots=True)
class Stop:
    """M0: the operator's NC start (CYCLE87, CYCLE88)."""


Step = Rapid | Feed | Wait | Spindle | Stop


@dataclass(frozen=True, slots=True)
class Context:
    """What a drilling cycle needs of the caller: the plane's axes and where the tool is (work system)."""

    first: str
    second: str
    infeed: str
    position: dict[str, float]
    feed_mm_min: float
    spindle_rpm: float
    spindle_direction: str | None


def _values(args: Sequence[float | None], count: int) -> list[float]:
    """The first ``count`` parameters, an empty or missing one 0 (as a cycle sees an unset parameter)."""
    return [float(args[index]) if index < len(args) and args[index] is not None else 0.0  # type: ignore[arg-type]
            for index in range(count)]


def _dwell(value: float) -> list[Step]:
    """DTB: seconds; negative: spindle revolutions (the sl cycles' convention)."""
    if value > 0:
        return [Wait(seconds=value)]
    if value < 0:
        return [Wait(revolutions=-value)]
    return []


def _planes(rtp: float, rfp: float, sdis: float, dp: float, dpr: float, name: str) -> tuple[float, float, float]:
    """(retraction plane, safety plane RFP+SDIS, final depth). DPR (depth below the reference plane,
    without sign) wins over DP when both are given."""
    depth = rfp - abs(dpr) if dpr else dp
    safety = rfp + abs(sdis)
    if depth >= safety:
        raise ProgramAlarm(ALARM_CYCLE_PARAMETER, f"{name}: the final depth {depth:g} does not lie below the "
                                                  f"reference plane plus the safety distance {safety:g}")
    return rtp, safety, depth


def drilling(name: str, args: Sequence[float | None], at: Context) -> list[Step]:
    """The steps of drilling cycle ``name`` at the tool's position in the plane."""
    z = at.infeed
    if name == "CYCLE83":
        return _deep_hole(args, at)
    if name in ("CYCLE84", "CYCLE840"):
        return _tapping(name, args, at)
    rtp, safety, depth = _planes(*_values(args, 5), name)
    params = _values(args, 11)
    steps: list[Step] = [Rapid({z: safety})]
    if name == "CYCLE85":  # boring 1: in and out at feed (FFR in, RFF out)
        feed_in = params[6] or None
        feed_out = params[7] or None
        steps += [Feed({z: depth}, feed_in), *_dwell(params[5]), Feed({z: safety}, feed_out), Rapid({z: rtp})]
        return steps
    steps.append(Feed({z: depth}))
    if name == "CYCLE81":
        return [*steps, Rapid({z: rtp})]
    if name in ("CYCLE82", "CYCLE89", "CYCLE86", "CYCLE88"):
        steps += _dwell(params[5])
    if name == "CYCLE89":  # boring 5: out at the same feed
        return [*steps, Feed({z: safety}), Rapid({z: rtp})]
    if name == "CYCLE86":  # boring 2: oriented stop, lift off the wall, out at rapid, spindle on again
        lift = {at.first: at.position.get(at.first, 0.0) + params[7],
                at.second: at.position.get(at.second, 0.0) + params[8], z: depth + params[9]}
        back = {at.first: at.position.get(at.first, 0.0), at.second: at.position.get(at.second, 0.0)}
        steps += [Spindle("M5"), Rapid(lift), Rapid({z: safety}), Rapid(back), Rapid({z: rtp})]
        return [*steps, *_spindle_again(params[6], at)]
    if name in ("CYCLE87", "CYCLE88"):  # boring 3/4: stop at depth, the operator's NC start, out at rapid
        direction = params[5] if name == "CYCLE87" else params[6]
        return [*steps, Spindle("M5"), Stop(), Rapid({z: rtp}), *_spindle_again(direction, at)]
    return [*steps, Rapid({z: rtp})]  # CYCLE82


def _spindle_again(direction: float, at: Context) -> list[Step]:
    code = {3: "M3", 4: "M4"}.get(int(direction)) or at.spindle_direction or "M3"
    return [Spindle(code, at.spindle_rpm or None)]


def anticipation_mm(depth_mm: float) -> float:
    """CYCLE83's automatic anticipation distance (_DIS1 = 0): 0.6 mm up to 30 mm depth, beyond that
    depth/50 up to 7 mm (as we read the cycle description; UNCONFIRMED)."""
    return 0.6 if depth_mm <= 30.0 else min(depth_mm / 50.0, 7.0)


def _strokes(start: float, first: float, final: float, degression: float) -> list[float]:
    """The depths each stroke reaches: the first depth, then strokes each shorter by DAM but never
    shorter than DAM (without DAM as long as the first), the last one ending at the final depth."""
    stroke = start - first if first > final else start - final
    stroke = max(stroke, 1e-3)
    depths: list[float] = []
    reached = start
    while reached > final + 1e-9:
        if len(depths) >= MAX_STROKES:
            raise ProgramAlarm(ALARM_CYCLE_PARAMETER, f"CYCLE83: more than {MAX_STROKES} strokes (DAM too small)")
        reached = max(reached - stroke, final)
        depths.append(reached)
        if degression > 0:
            stroke = max(stroke - degression, degression)
    return depths


def _deep_hole(args: Sequence[float | None], at: Context) -> list[Step]:
    """CYCLE83(RTP, RFP, SDIS, DP, DPR, FDEP, FDPR, DAM, DTB, DTS, FRF, VARI, _AXN, _MDEP, _VRT, _DTD,
    _DIS1): strokes deeper by a degression; VARI 0 breaks the chip (back by _VRT, 1 mm unless given,
    at feed), VARI 1 removes it (out to the safety plane at rapid, DTS dwell, back at rapid to the
    anticipation distance above the depth reached). The first stroke runs at F x FRF."""
    z = at.infeed
    rtp, safety, depth = _planes(*_values(args, 5), "CYCLE83")
    p = _values(args, 17)
    rfp = p[1]
    first = rfp - abs(p[6]) if p[6] else (p[5] if p[5] else depth)
    first = min(max(first, depth), safety)
    factor = p[10] if 0 < p[10] <= 1 else 1.0
    retract = abs(p[14]) or 1.0
    distance = abs(p[16]) or anticipation_mm(safety - depth)
    steps: list[Step] = [Rapid({z: safety})]
    previous = safety
    for index, reached in enumerate(_strokes(safety, first, depth, abs(p[7]))):
        feed = at.feed_mm_min * factor if index == 0 else None
        if index and p[11] == 1:  # chip removal: back in at rapid to just above the last depth
            steps.append(Rapid({z: previous + distance}))
        steps.append(Feed({z: reached}, feed))
        steps += _dwell(p[8])
        if reached > depth + 1e-9:
            if p[11] == 1:
                steps += [Rapid({z: safety}), *_dwell(p[9])]
            else:
                steps.append(Feed({z: reached + retract}))
        previous = reached
    return [*steps, Rapid({z: rtp})]


def thread_pitch_mm(size: float, pitch: float, name: str) -> float:
    """PIT (mm, its sign the thread's hand) or, without it, MPIT's metric coarse pitch."""
    if pitch:
        return abs(pitch)
    if size:
        found = _METRIC_PITCH_MM.get(int(abs(size)))
        if found is not None and abs(size) == int(abs(size)):
            return found
    raise ProgramAlarm(ALARM_THREAD_PITCH, f"{name}: no thread pitch (MPIT {size:g}, PIT {pitch:g})")


def _tapping(name: str, args: Sequence[float | None], at: Context) -> list[Step]:
    """CYCLE84(RTP, RFP, SDIS, DP, DPR, DTB, SDAC, MPIT, PIT, POSS, SST, SST1) rigid tapping: the
    spindle stops oriented (POSS), taps at SST (the spindle's speed when 0) times the pitch, dwells,
    comes out at SST1 (SST when 0), and turns again as SDAC says. CYCLE840(RTP, RFP, SDIS, DP, DPR,
    DTB, SDR, SDAC, ENC, MPIT, PIT) with a compensating chuck: in at the feed (the spindle speed times
    the pitch when a pitch is given), out again with the spindle reversed."""
    z = at.infeed
    rtp, safety, depth = _planes(*_values(args, 5), name)
    p = _values(args, 12)
    steps: list[Step] = [Rapid({z: safety})]
    if name == "CYCLE84":
        speed_in = p[10] or at.spindle_rpm
        speed_out = p[11] or speed_in
        pitch = thread_pitch_mm(p[7], p[8], name)
        if speed_in <= 0:
            raise ProgramAlarm(ALARM_CYCLE_PARAMETER, "CYCLE84: no spindle speed (SST 0 and the spindle stands)")
        steps += [Spindle("M5"), Feed({z: depth}, speed_in * pitch), *_dwell(p[5]),
                  Feed({z: safety}, speed_out * pitch), Rapid({z: rtp}), *_spindle_again(p[6], at)]
        return steps
    feed = at.spindle_rpm * thread_pitch_mm(p[9], p[10], name) if (p[9] or p[10]) and at.spindle_rpm else None
    reverse = "M3" if at.spindle_direction == "M4" else "M4"
    steps += [Feed({z: depth}, feed), *_dwell(p[5]), Spindle(reverse), Feed({z: safety}, feed), Rapid({z: rtp}),
              *_spindle_again(p[7], at)]
    return steps


def pattern(name: str, args: Sequence[float | None]) -> list[tuple[float, float]]:
    """The positions (abscissa, ordinate in the plane, work system) of a drilling pattern, in the
    order they are drilled."""
    if name == "HOLES1":  # SPCA, SPCO, STA1, FDIS, DBH, NUM: a row
        spca, spco, sta1, fdis, dbh, num = _values(args, 6)
        angle = math.radians(sta1)
        return [(spca + (fdis + index * dbh) * math.cos(angle), spco + (fdis + index * dbh) * math.sin(angle))
                for index in range(_count(num, name))]
    if name == "HOLES2":  # CPA, CPO, RAD, STA1, INDA, NUM: a circle; INDA 0 spaces them evenly
        cpa, cpo, rad, sta1, inda, num = _values(args, 6)
        count = _count(num, name)
        step = inda or 360.0 / count
        return [(cpa + rad * math.cos(math.radians(sta1 + index * step)),
                 cpo + rad * math.sin(math.radians(sta1 + index * step))) for index in range(count)]
    # CYCLE801(SPCA, SPCO, STA, DIS1, DIS2, NUM1, NUM2): a grid, row by row in a meander
    spca, spco, sta, dis1, dis2, num1, num2 = _values(args, 7)
    columns, rows = _count(num1, name), _count(num2, name)
    angle = math.radians(sta)
    points = []
    for row in range(rows):
        order = range(columns) if row % 2 == 0 else range(columns - 1, -1, -1)
        for column in order:
            u, v = column * dis1, row * dis2
            points.append((spca + u * math.cos(angle) - v * math.sin(angle),
                           spco + u * math.sin(angle) + v * math.cos(angle)))
    return points


def _count(value: float, name: str) -> int:
    if value != int(value) or not 1 <= value <= 10_000:
        raise ProgramAlarm(ALARM_CYCLE_PARAMETER, f"{name}: the number of holes must be 1..10000 (not {value:g})")
    return int(value)


def swivel_rotations(args: Sequence[float | None]) -> list[tuple[str, float]]:
    """CYCLE800(_FR, _TC, _ST, _MODE, _X0, _Y0, _Z0, _A, _B, _C, _X1, _Y1, _Z1, _DIR, _FR_I): the
    rotations (geometry axis, degrees) in the order they apply. _MODE bits 0-5 give the axis order of
    an axis-by-axis swivel (2 bits each: 1 X, 2 Y, 3 Z, the first in bits 0-1); the other modes
    (solid angle, projection angle, direct rotary axes) are taken as X, Y, Z (our simplification)."""
    values = [float(arg) if isinstance(arg, int | float) else 0.0 for arg in list(args)[:13]]
    values += [0.0] * (13 - len(values))
    mode = int(values[3])
    order = ["X", "Y", "Z"]
    if mode & 0xC0 == 0 and mode & 0x3F:
        decoded = [{1: "X", 2: "Y", 3: "Z"}.get((mode >> shift) & 3) for shift in (0, 2, 4)]
        if all(decoded) and len(set(decoded)) == 3:
            order = decoded  # type: ignore[assignment]
    return [(axis, angle) for axis, angle in zip(order, values[7:10], strict=True)]


def swivel_offsets(args: Sequence[float | None]) -> tuple[dict[str, float], dict[str, float]]:
    """CYCLE800's reference point before the rotation (_X0, _Y0, _Z0) and zero point after it (_X1...)."""
    values = [float(arg) if isinstance(arg, int | float) else 0.0 for arg in list(args)[:13]]
    values += [0.0] * (13 - len(values))
    return dict(zip("XYZ", values[4:7], strict=True)), dict(zip("XYZ", values[10:13], strict=True))


ROTARY_FOR = {"X": "A", "Y": "B", "Z": "C"}
