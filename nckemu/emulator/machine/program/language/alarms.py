"""Alarm numbers the language raises beyond those of :mod:`..motions` (programs.md §8).

Numbers marked UNCONFIRMED come from no source we hold; they are module constants so a lead or a
user with the Siemens diagnostics manual can correct them in one place.
"""

from __future__ import annotations

from ..motions import ProgramAlarm

# UNCONFIRMED (no source at hand; "arithmetic error in part program" as we remember the Siemens list):
# division by zero, and SQRT(-1), ASIN(2), an overflow to infinity under the same number.
ALARM_DIVISION_BY_ZERO = 14051
ALARM_ARITHMETIC = 14051
# UNCONFIRMED: a value of the wrong type (a STRING in arithmetic, a number into a STRING).
ALARM_TYPE = 12150
# UNCONFIRMED: IF without ENDIF, ENDFOR without FOR and the like ("invalid nesting of control structures").
ALARM_NESTING = 12640
# UNCONFIRMED: an array index outside the declared size.
ALARM_INDEX = 17020
# UNCONFIRMED: a G function the control does not know (no SINUMERIK has it: G43 of ISO controls, G999).
ALARM_UNKNOWN_G = 12470
# UNCONFIRMED: two G functions of one syntax-defining group (1 motion, 2 non-modal motion, 3 frames)
# in one block ("too many syntax-defining G functions": G0 G1 X10).
ALARM_SYNTAX_G_TWICE = 12070
# UNCONFIRMED ("same G group programmed repeatedly", as we remember the number): two G functions of one
# group that does not define the block's syntax (G90 G91), on a machine whose [program] repeated_g_group
# is "alarm"; by default the last one written is active.
ALARM_G_GROUP_TWICE = 12060
# UNCONFIRMED: subprogram calls nested deeper than the control allows.
ALARM_CALL_DEPTH = 14000
# Subprogram levels a program may open below the main program (840D sl: 16 levels in all; UNCONFIRMED).
MAX_CALL_DEPTH = 15
# UNCONFIRMED: more M functions in a block than allowed, or two of one group (M3 and M5 for one
# spindle) in the same block ("auxiliary function programmed incorrectly").
ALARM_AUXILIARY = 14770
MAX_M_PER_BLOCK = 5
# UNCONFIRMED ("frame instruction not permissible", as we remember the 18310 group): a frame that
# scales an axis by 0, a rotation about an axis that is no geometry axis.
ALARM_FRAME = 18311


# UNCONFIRMED ("value range exceeded", as we remember the number): a constant beyond the REAL range
# (1EX400), and an axis end point, a frame's value or a positioning axis' end point beyond the range an
# address takes (±999 999 999.9999, as we remember the programming manual's table; UNCONFIRMED).
ALARM_VALUE_RANGE = 12160
VALUE_LIMIT = 999_999_999.9999


def out_of_range(what: str, value: float) -> ProgramAlarm:
    """The alarm for ``value`` of ``what`` (``X``, ``SCALE X``) beyond :data:`VALUE_LIMIT` (the caller raises it)."""
    return ProgramAlarm(ALARM_VALUE_RANGE, f"value range exceeded: {what} = {value:g} (the control takes "
                                           f"at most ±{VALUE_LIMIT:,.4f})".replace(",", " "))


def located(alarm: ProgramAlarm, program: str, line: int, block: str) -> ProgramAlarm:
    """``alarm`` naming ``program``, ``line`` and ``block`` unless it names a program already (one
    raised inside a subprogram, located there)."""
    if alarm.program:
        return alarm
    return ProgramAlarm(alarm.number, alarm.args[0], program=program, line=line, block=block.strip())
