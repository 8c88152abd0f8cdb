"""Part programs the NCK knows and the one selected for execution."""

from __future__ import annotations

from nckemu.errors import NckNoSuchFile, NckPiStateError

DEFAULT_PROGRAMS = ("/_N_MPF_DIR/_N_TEST_MPF", "/_N_MPF_DIR/_N_MAIN_MPF")


class Programs:
    def __init__(self) -> None:
        self.paths: set[str] = set(DEFAULT_PROGRAMS)
        self.selected = ""
        # Program texts by path, where a client stored one (OPC UA CopyFileToServer); others are names only.
        self.texts: dict[str, bytes] = {}

    def add(self, path: str) -> None:
        self.paths.add(path)

    def select(self, path: str) -> None:
        if path not in self.paths:
            raise NckNoSuchFile(f"no program {path}")
        self.selected = path

    def delete(self, path: str) -> None:
        if path not in self.paths:
            raise NckNoSuchFile(f"no file {path}")
        if path == self.selected:
            raise NckPiStateError(f"{path} is selected")
        self.paths.discard(path)
        self.texts.pop(path, None)
