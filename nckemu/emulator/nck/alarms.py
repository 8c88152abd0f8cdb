"""The NCK's active alarms (texts for now; numbers and times arrive with the alarm list variables)."""

from __future__ import annotations


class Alarms:
    def __init__(self) -> None:
        self.active: list[str] = []

    def raise_alarm(self, text: str) -> None:
        if text not in self.active:
            self.active.append(text)

    def clear(self, text: str) -> None:
        if text in self.active:
            self.active.remove(text)

    @property
    def count(self) -> int:
        return len(self.active)
