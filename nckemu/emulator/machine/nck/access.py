"""Access levels of a connection (0 = Siemens, highest ... 7 = key switch position 0, lowest)."""

from __future__ import annotations

from dataclasses import dataclass

HIGHEST_LEVEL = 0
LOWEST_LEVEL = 7


@dataclass
class AccessContext:
    level: int = LOWEST_LEVEL
    client: str = ""

    def may(self, required_level: int) -> bool:
        """A smaller number is more privileged: level 2 may do what level 4 may."""
        return self.level <= required_level
