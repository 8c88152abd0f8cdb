"""Canonical events the interpreter emits, in execution order, and the alarm it raises.

Positions are machine coordinates in mm (degrees for rotary axes) after every frame, inch
conversion and tool offset the interpreter applies; feeds are mm/min (G94) or mm/rev (G95), already
converted from inch where G700 asked for it. ``programmed`` keeps the values as the block wrote them
after modal resolution (work coordinates, the program's unit), for block tables.

The events are records nobody changes once made. :class:`Block`, :class:`Move` and :class:`Arc`, made
for every block a CAM program runs, are plain slotted dataclasses: a frozen one's ``__init__`` sets
each field through ``object.__setattr__``, three to four times the cost (bench/bench_programs.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from nckemu.errors import NckError

FeedMode = Literal["G93", "G94", "G95"]
Plane = Literal["G17", "G18", "G19"]


@dataclass(slots=True)
class Block:
    """A block begins executing (every executed block, motion or not, so a channel can bound work)."""

    program: str                  # NC path, e.g. /_N_MPF_DIR/_N_DAILY_MPF
    line: int                     # 1-based line in that program
    number: str = ""              # block number as written ("N40"), or ""
    text: str = ""                # the block as written, without its comment
    depth: int = 0                # subprogram level: 0 main program


@dataclass(frozen=True, slots=True)
class ConstantCuttingSpeed:
    """G96: the spindle turns at ``speed_m_min`` (the S under G96) over the radius of the transverse axis
    ``axis`` about ``centre_mm`` (its machine position where the work's X is 0), at most ``limit_rpm``
    (LIMS; 0: the spindle's own limit)."""

    speed_m_min: float
    limit_rpm: float = 0.0
    axis: str = "X"
    centre_mm: float = 0.0
    spindle: int = 1


@dataclass(slots=True)
class Move:
    """A straight move: rapid (G0, ``feed`` None) or at feed (G1)."""

    target_mm: dict[str, float]   # every axis the block moves, machine coordinates
    feed: float | None = None     # None: rapid traverse
    feed_mode: FeedMode = "G94"
    exact_stop: bool = True       # G60/G9; False under G64 path control
    programmed: dict[str, float] = field(default_factory=dict)
    fgroup: frozenset[str] | None = None   # the axes F applies to (FGROUP); None: the geometry axes
    css: ConstantCuttingSpeed | None = None  # G96 (with feed per revolution)
    thread: bool = False          # G33/G331/G332: the feed override does not act


@dataclass(slots=True)
class Arc:
    """A circular move (G2 clockwise, G3 counter-clockwise) in ``plane``, helical where the third axis moves."""

    target_mm: dict[str, float]
    centre_mm: dict[str, float]   # the two plane axes of the centre, machine coordinates
    clockwise: bool
    plane: Plane = "G17"
    feed: float = 0.0
    feed_mode: FeedMode = "G94"
    turns: int = 0                # full turns beyond the first (TURN=)
    exact_stop: bool = True
    programmed: dict[str, float] = field(default_factory=dict)
    fgroup: frozenset[str] | None = None
    css: ConstantCuttingSpeed | None = None


@dataclass(frozen=True, slots=True)
class Dwell:
    """G4: ``seconds`` (G4 F) or ``spindle_revolutions`` (G4 S) of the master spindle."""

    seconds: float | None = None
    spindle_revolutions: float | None = None


@dataclass(frozen=True, slots=True)
class SpindleCommand:
    """S and M3/M4/M5 of one spindle; ``speed_rpm`` None keeps the speed, ``direction`` None keeps it."""

    spindle: int = 1
    speed_rpm: float | None = None
    direction: Literal["M3", "M4", "M5"] | None = None
    css: ConstantCuttingSpeed | None = None  # G96: the speed follows the transverse axis (speed_rpm None)


@dataclass(frozen=True, slots=True)
class MFunction:
    """An M function the channel reacts to or hands to the PLC (M0, M1, M2, M17, M30, M6, others)."""

    code: int
    extension: int = 0            # address extension (M1=3 -> extension 1, code 3)


@dataclass(frozen=True, slots=True)
class ToolSelect:
    """T (tool number or name) and D (edge); ``change`` True for M6 or a T that changes directly."""

    tool: int | str | None = None
    edge: int | None = None
    change: bool = False


@dataclass(frozen=True, slots=True)
class Message:
    """MSG("...") (an empty text clears the message)."""

    text: str


@dataclass(frozen=True, slots=True)
class ProgramEnd:
    """The main program ended (M2, M30, or its last block); ``code`` 2, 30, or 0 for the last block
    (17 for M17 and 0 for RET written in a main program)."""

    code: int


@dataclass(frozen=True, slots=True)
class CycleCall:
    """A standard cycle the block calls: ``simulated`` False for one the emulator has no motion for (it
    takes 0 s and is counted apart); ``note`` what it set (CYCLE832's tolerance) for the block table."""

    name: str
    simulated: bool = True
    note: str = ""


@dataclass(frozen=True, slots=True)
class Positioning:
    """``POS[U]=10`` / ``POSA[U]=10``: a positioning axis starts for ``target_mm`` (machine coordinates) on
    its own, beside the path, at ``feed_mm_min`` (FA; degrees/min on a rotary axis), or, None, at the
    axis' MD32060 POS_AX_VELO. It does not hold the block by itself: a POS block is followed by an
    :class:`AxesWait` for its axes, a POSA axis runs on past the block's end."""

    axis: str
    target_mm: float
    feed_mm_min: float | None = None
    programmed: float = 0.0


@dataclass(frozen=True, slots=True)
class AxesWait:
    """The block does not change until the positioning axes ``axes`` have arrived (POS at its block's
    end, ``WAITP(U)``); ``axes`` empty: every positioning axis (the program's end)."""

    axes: tuple[str, ...] = ()


Event = (Block | Move | Arc | Dwell | SpindleCommand | MFunction | ToolSelect | Message | ProgramEnd | CycleCall
         | Positioning | AxesWait)


# Alarm numbers the interpreter raises (programs.md §8; texts are ours).
ALARM_SYNTAX = 12080
ALARM_NAME_NOT_DEFINED = 12550
ALARM_PROGRAM_NOT_FOUND = 14011
ALARM_JUMP_TARGET = 14080
ALARM_FEED_ZERO = 14800
ALARM_CIRCLE_END_POINT = 14040


class ProgramAlarm(NckError):
    """An NCK alarm raised while a program runs: the channel stops, the alarm list shows it."""

    def __init__(self, number: int, message: str, *, program: str = "", line: int = 0,
                 block: str = "") -> None:
        super().__init__(message)
        self.number = number
        self.program = program
        self.line = line
        self.block = block

    def __str__(self) -> str:
        block = f": {self.block}" if self.block else ""  # the block's N number, where it has one
        where = f" ({self.program} line {self.line}{block})" if self.program else ""
        return f"alarm {self.number}: {self.args[0]}{where}"
