"""One executed block as the block table shows it: what the channel tells its block listeners
(program run's ``--blocks``, the offline run's table). Its own module, imported by the channel and the
program run alike without either importing the other."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class BlockRecord:
    """One executed block as a block table shows it (``program run --blocks``)."""

    start_s: float
    program: str
    line: int
    number: str
    text: str
    depth: int
    end_s: float = 0.0
    positions_mm: dict[str, float] = field(default_factory=dict)
    feed_mm_min: float = 0.0
    spindle_rpm: float = 0.0
    m_codes: list[int] = field(default_factory=list)
    alarm: str = ""
    note: str = ""                # a standard cycle's word: "CYCLE62 not simulated", CYCLE832's tolerance

    def add_note(self, note: str) -> None:
        """``note`` after the notes the block already has ("; " between them)."""
        self.note = f"{self.note}; {note}" if self.note else note
