"""The words of a block as blocks.py reads them: one frozen record per kind of word.

A value is a constant or an expression closure (expressions.py, evaluated when the block runs);
a block compiled once is executed as often as it runs (loops, subprograms), so nothing here changes.
The interpreter executes a block's words in the order written, then what they add up to
(interpreter.py ``_words``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True, slots=True)
class AxisWord:
    """``X10``, ``X=R1+2``, ``X=IC(5)``: an axis and its value, ``mode`` "IC"/"AC" or None (G90/G91)."""

    axis: str
    value: Any
    mode: str | None = None


@dataclass(frozen=True, slots=True)
class IndirectAxisWord:
    """``AX[_AXVAR]=10``, ``AX[AXNAME("X")]=IC(5)``: an axis named by an expression (an AXIS value or
    the axis name), found when the block runs."""

    axis: Any
    value: Any
    mode: str | None = None


@dataclass(frozen=True, slots=True)
class GWord:
    """``G1``; a spline word (ASPLINE) runs as G1 and names itself in ``spline``."""

    code: int
    spline: str | None = None


@dataclass(frozen=True, slots=True)
class AddressWord:
    """``F500``, ``S=_RPM``, ``M1=3``, ``T="DRILL"``, ``CR=5``: a letter (or word address), its value and
    its extension (``M1=3``: 1; 0 without one)."""

    letter: str
    value: Any
    extension: int = 0


@dataclass(frozen=True, slots=True)
class CentreWord:
    """``I5``, ``J=AC(10)``: a circle centre coordinate, ``mode`` "AC" for an absolute one."""

    letter: str
    value: Any
    mode: str | None = None


@dataclass(frozen=True, slots=True)
class Assign:
    """``R1=5``, ``_X=_X+1``, ``$A_OUT[1]=1``: ``target`` ("R"/"VAR"/"SYS", name or index, indices)."""

    target: tuple
    value: Any


@dataclass(frozen=True, slots=True)
class Fill:
    """``TAB[1]=SET(4,5)`` / ``=REP(0)``: ``which`` "SET" or "REP"."""

    target: tuple
    which: str
    values: list


@dataclass(frozen=True, slots=True)
class Call:
    """A subprogram call: ``NAME(args)``, a bare ``NAME``, ``CALL "NAME"``, ``L123``; ``args`` None for
    a call without brackets, ``repeat`` the P count (an expression) or None."""

    name: Any
    args: list | None = None
    repeat: Any = None


@dataclass(frozen=True, slots=True)
class ModalCall:
    """``MCALL NAME(args)``; ``name`` None for MCALL alone (the modal call ends)."""

    name: Any
    args: list | None = None


@dataclass(frozen=True, slots=True)
class Jump:
    """``GOTOF LABEL`` and its kin at the end of a block (GOTOS: no target)."""

    kind: str
    target: str


@dataclass(frozen=True, slots=True)
class Msg:
    """``MSG("text" << VAR)``; ``MSG()`` clears the message (text "")."""

    text: Any


@dataclass(frozen=True, slots=True)
class Setal:
    """``SETAL(n)``."""

    number: Any


@dataclass(frozen=True, slots=True)
class FrameWord:
    """``TRANS X10``, ``AROT RPL=45``: a frame instruction and its (axis or RPL, value) pairs."""

    word: str
    pairs: list


@dataclass(frozen=True, slots=True)
class Suppress:
    """``SUPA``, ``G153`` written as a word: the frames suppressed for this block."""

    name: str


@dataclass(frozen=True, slots=True)
class Return:
    """``RET``."""


@dataclass(frozen=True, slots=True)
class AxisSetting:
    """``ACC[X]=50``: a per-axis setting, kept so the program can read it back."""

    name: str
    indices: list
    value: Any


@dataclass(frozen=True, slots=True)
class PositionWord:
    """``POS[U]=10``, ``POSA[U]=IC(5)``, ``POSP[U]=(100, 10, 0)``: a positioning axis (an expression
    naming it), its end point and dimension mode; ``kind`` "POS", "POSA" or "POSP"."""

    kind: str
    axis: Any
    value: Any
    mode: str | None = None


@dataclass(frozen=True, slots=True)
class WaitPosition:
    """``WAITP(U, V)``: the block waits until the positioning axes named have arrived."""

    axes: list


@dataclass(frozen=True, slots=True)
class Spos:
    """``SPOS=...``: the spindle stops (positioning is not modelled)."""

    spindle: int
    value: Any


@dataclass(frozen=True, slots=True)
class NoOp:
    """A word accepted without effect (BRISK, STOPRE, N as a word) or with its own small model
    (FGROUP, DIAMON): its name and the arguments written with it."""

    name: str
    args: Any = None


Word = (AxisWord | IndirectAxisWord | GWord | AddressWord | CentreWord | Assign | Fill | Call | ModalCall | Jump | Msg | Setal
        | FrameWord | Suppress | Return | AxisSetting | PositionWord | WaitPosition | Spos | NoOp)
