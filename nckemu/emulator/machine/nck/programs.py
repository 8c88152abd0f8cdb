"""Part programs the NCK knows: their texts, the one selected for execution and the one running.

Paths are the control's (``/_N_MPF_DIR/_N_TEST_MPF``); :func:`program_path` also takes the names
users write (``TEST.MPF``, ``WARMUP_CYCLE.SPF``, ``/MPF_DIR/TEST.MPF``). A program's text is replaced
whole or not at all (a transfer writes it only when it has ended); the program a channel is running
cannot be replaced or deleted.
"""

from __future__ import annotations

import base64
import re
from typing import Any

from nckemu.errors import NckNoSuchFile, NckPiBadArguments, NckPiStateError

DEFAULT_PROGRAMS = ("/_N_MPF_DIR/_N_TEST_MPF", "/_N_MPF_DIR/_N_MAIN_MPF")

# File types and the directory a bare name of that type lives in.
TYPE_DIRECTORIES = {"MPF": "_N_MPF_DIR", "SPF": "_N_SPF_DIR"}
_CONTROL_NAME = re.compile(r"_N_([A-Z0-9_]+)_(MPF|SPF|DEF|INI|WPD)")
_USER_NAME = re.compile(r"([A-Z0-9_]+)\.(MPF|SPF|DEF|INI)")
_DIRECTORY = re.compile(r"_N_[A-Z0-9_]+_(DIR|WPD)")
MAX_NAME_CHARS = 24


def program_path(name: str, *, default_type: str = "MPF") -> str:
    """The control's path of a program named as a user or the control writes it.

    ``TEST.MPF`` and ``_N_TEST_MPF`` give ``/_N_MPF_DIR/_N_TEST_MPF``; ``/_N_SPF_DIR/_N_X_SPF`` stays
    as it is; a bare ``TEST`` is of ``default_type``. Names are case-insensitive (kept in upper case).
    Raises NckPiBadArguments for anything that is not an NC file name (``..``, empty parts, spaces).
    """
    text = name.strip().upper()
    parts = [part for part in text.split("/") if part]
    if not parts or any(part in (".", "..") for part in parts) or "\\" in text:
        raise NckPiBadArguments(f"{name!r} is not an NC file name")
    *directories, leaf = parts
    control = _CONTROL_NAME.fullmatch(leaf)
    user = _USER_NAME.fullmatch(leaf)
    if control:
        stem, kind = control.group(1), control.group(2)
    elif user:
        stem, kind = user.group(1), user.group(2)
    elif re.fullmatch(r"[A-Z_][A-Z0-9_]*", leaf):
        stem, kind = leaf, default_type
    else:
        raise NckPiBadArguments(f"{name!r} is not an NC file name (letters, digits and _ only)")
    if len(stem) > MAX_NAME_CHARS:
        raise NckPiBadArguments(f"{name!r}: a program name has at most {MAX_NAME_CHARS} characters")
    control_dirs = []
    for directory in directories:
        if not directory.startswith("_N_"):
            directory = "_N_" + directory.replace(".", "_")
        if not _DIRECTORY.fullmatch(directory):
            raise NckPiBadArguments(f"{name!r}: {directory} is not an NC directory")
        control_dirs.append(directory)
    if not control_dirs:
        control_dirs = [TYPE_DIRECTORIES.get(kind, "_N_MPF_DIR")]
    return "/" + "/".join([*control_dirs, f"_N_{stem}_{kind}"])


def user_name(path: str) -> str:
    """``/_N_MPF_DIR/_N_TEST_MPF`` -> ``TEST.MPF`` (the name an HMI shows)."""
    leaf = path.rsplit("/", 1)[-1]
    match = _CONTROL_NAME.fullmatch(leaf)
    return f"{match.group(1)}.{match.group(2)}" if match else leaf


class Programs:
    def __init__(self) -> None:
        self.paths: set[str] = set(DEFAULT_PROGRAMS)
        self.selected = ""
        # The program a channel is executing (set by the channel): it cannot be replaced or deleted.
        self.running = ""
        # Program texts by path; a path without a text is an empty program.
        self.texts: dict[str, bytes] = {}

    def add(self, path: str) -> None:
        self.paths.add(path)

    def exists(self, path: str) -> bool:
        return path in self.paths

    def read(self, path: str) -> bytes:
        """The program's text (raises NckNoSuchFile)."""
        if path not in self.paths:
            raise NckNoSuchFile(f"no program {path}")
        return self.texts.get(path, b"")

    def write(self, path: str, text: bytes) -> None:
        """Store ``text`` as the program at ``path``, whole (refused while it runs)."""
        if path == self.running:
            raise NckPiStateError(f"{path} is running")
        self.texts[path] = bytes(text)
        self.paths.add(path)

    def listing(self, directory: str = "") -> list[str]:
        """Paths in ``directory`` (``/_N_MPF_DIR``), or every path, sorted."""
        prefix = directory.rstrip("/") + "/" if directory else ""
        return sorted(path for path in self.paths if path.startswith(prefix))

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
        if path in (self.selected, self.running):
            raise NckPiStateError(f"{path} is {'running' if path == self.running else 'selected'}")
        self.paths.discard(path)
        self.texts.pop(path, None)
