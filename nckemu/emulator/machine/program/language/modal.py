"""The modal state of a program run: what its G groups and frames have set, as one record.

A subprogram inherits it from its caller; ``PROC ... SAVE`` copies it at the call and puts the copy
back on return (:meth:`ModalState.copy`). The interpreter keeps one (``Interpreter.modal``); the
tool, the feed value and the spindle speeds are not in it (SAVE does not restore them on a control).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from nckemu.emulator.machine.frame_math import IDENTITY_FRAME, Frame

from .feedrules import FeedRules
from .polar import Polar


@dataclass(slots=True)
class ModalState:
    motion: int = 0                    # group 1: 0 rapid, 1 straight, 2/3 circles, 33/331/332 threads
    plane: str = "G17"                 # group 6: G17, G18, G19
    absolute: bool = True              # group 14: G90 (False: G91)
    inch_geometry: bool = False        # group 13: G70/G700 (positions in inch)
    inch_feed: bool = False            # group 13: G700 (feeds in inch too)
    feed_mode: str = "G94"             # group 15: G93, G94, G95
    feed_rules: FeedRules = field(default_factory=FeedRules)  # FGROUP, G96, DIAMON, thread pitch
    polar: Polar = field(default_factory=Polar)  # group 3's pole (G110..G112) and AP=/RP=
    exact_stop: bool = True            # group 10: G60 (False: G64, G641...)
    frame_name: str = "G500"           # group 8: the settable frame
    settable: dict[str, float] = field(default_factory=dict)  # its offsets, mm
    pframe: Frame = IDENTITY_FRAME     # group 3: the programmable frame (TRANS, ROT, SCALE, MIRROR)
    chain: Frame | None = None         # settable + programmable frame when more than a translation
    shift: dict[str, float] = field(default_factory=dict)  # what the frames and the tool add, mm
    # the active G function of each modal group but 1 that a block has named (G64, G710, SOFT, CUT2D),
    # what $P_GG reads; groups not named hold their default (gfunctions.GROUP_DEFAULTS)
    g_groups: dict[int, str] = field(default_factory=dict)

    def copy(self) -> ModalState:
        """An independent copy (the dicts copied; the other fields are immutable)."""
        return replace(self, settable=dict(self.settable), shift=dict(self.shift), g_groups=dict(self.g_groups))
