"""Retained data on disk: one JSON file, replaced atomically (write temp, fsync, rename, fsync dir).

A write job that changes retained data is acknowledged only after the file holding it was written,
so an acknowledged value survives a kill -9. A damaged file is refused with a message, never
replaced. Writes may come from the event loop and from a saving thread (``saves.py``): they take
turns, and a snapshot older than the one on disk is not written over it.
"""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path
from typing import Any

from nckemu.errors import NckConfigError


class RetainedStore:
    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._turn = threading.Lock()
        self._written_sequence = -1

    def load(self) -> dict[str, Any] | None:
        try:
            text = self.path.read_text("utf-8")
        except FileNotFoundError:
            return None
        except (OSError, UnicodeDecodeError) as exc:
            raise NckConfigError(f"cannot read the retained state: {exc}", path=str(self.path)) from None
        try:
            snapshot = json.loads(text)
        except json.JSONDecodeError as exc:
            raise NckConfigError(f"damaged retained state ({exc.msg}); it is left as it is: move it "
                                 f"away to start without it", path=str(self.path), line=exc.lineno) from None
        if not isinstance(snapshot, dict):
            raise NckConfigError("damaged retained state (not a JSON object)", path=str(self.path))
        return snapshot

    def save(self, snapshot: dict[str, Any]) -> None:
        self.write(self.encode(snapshot))

    @staticmethod
    def encode(snapshot: dict[str, Any]) -> bytes:
        """The file's bytes (taken where the snapshot cannot change meanwhile: on the event loop)."""
        try:
            return json.dumps(snapshot, separators=(",", ":"), allow_nan=False).encode("utf-8")
        except ValueError as exc:  # NaN or infinity: JSON has no spelling for them
            raise NckConfigError(f"retained data cannot be written as JSON: {exc}") from None

    def write(self, data: bytes, sequence: int | None = None) -> None:
        """Replace the file with ``data``; with ``sequence``, only if no later snapshot was written."""
        with self._turn:
            if sequence is not None:
                if sequence < self._written_sequence:
                    return
                self._written_sequence = sequence
            self._replace(data)

    def _replace(self, data: bytes) -> None:
        directory = self.path.parent
        temporary = directory / f".{self.path.name}.tmp"
        fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            # os.write may write part of it (a disk that fills up writes what fits and says how much):
            # the rest is written until done or the next write raises (ENOSPC). Once, a single write
            # left a truncated file that replaced the good one, with no error (a full tmpfs).
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
            os.fsync(fd)
        except BaseException:
            os.close(fd)
            try:
                os.unlink(temporary)  # on a full disk, a half-written temporary file keeps it full
            except OSError:
                pass
            raise
        os.close(fd)
        os.replace(temporary, self.path)
        dir_fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
