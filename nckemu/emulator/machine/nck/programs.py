"""Part programs the NCK knows and the one selected for execution."""

from __future__ import annotations

import base64
from typing import Any

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

    def snapshot(self) -> dict[str, Any]:
        """The program store as retained data: paths, and texts as base64."""
        return {"paths": sorted(self.paths),
                "texts": {path: base64.b64encode(text).decode("ascii") for path, text in sorted(self.texts.items())}}

    def restore(self, snapshot: dict[str, Any]) -> None:
        """The store as ``snapshot`` left it (raises KeyError/TypeError/ValueError when it is damaged)."""
        paths = {str(path) for path in snapshot["paths"]}
        texts = {str(path): base64.b64decode(text, validate=True) for path, text in snapshot["texts"].items()}
        self.paths = paths | set(texts)
        self.texts = texts

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
