"""Part programs the NCK knows: their texts, the one selected for execution and the one running.

Paths are the control's (``/_N_MPF_DIR/_N_TEST_MPF``); :func:`nckemu.catalogue.program_names.program_path` also takes the names
users write (``TEST.MPF``, ``WARMUP_CYCLE.SPF``, ``/MPF_DIR/TEST.MPF``). A program's text is replaced
whole or not at all (a transfer writes it only when it has ended); the program a channel is running,
and the subprograms it is in, cannot be replaced or deleted.
"""

from __future__ import annotations

import base64
from collections.abc import Callable, Collection
from typing import Any

from nckemu.catalogue.program_names import DIRECTORIES, directory_path, program_path
from nckemu.emulator.machine.program.language.definitions import GlobalDefinitions, is_definition_file
from nckemu.emulator.machine.program.language.gud_values import is_r_values_file, is_values_file
from nckemu.emulator.machine.program.language.source import decode_program
from nckemu.errors import NckNoSuchFile, NckPiStateError

DEFAULT_PROGRAMS = ("/_N_MPF_DIR/_N_TEST_MPF", "/_N_MPF_DIR/_N_MAIN_MPF")


def program_text(data: bytes) -> str:
    """A stored program as text: UTF-8 where it is (comments with a degree sign), else Latin-1 (any byte)."""
    return decode_program(data)


class Programs:
    def __init__(self) -> None:
        self.paths: set[str] = set(DEFAULT_PROGRAMS)
        self.selected = ""
        # The program a channel is executing (set by the channel): it cannot be replaced or deleted.
        self.running = ""
        # The subprograms it has called and not returned from (the channel sets the run's), likewise.
        self.called: Callable[[], Collection[str]] = tuple
        # Program texts by path; a path without a text is an empty program.
        self.texts: dict[str, bytes] = {}
        # The 16-character time stamps transfers carried (``yyMMddHHmmss`` + 4 spaces), by path.
        self.stamps: dict[str, str] = {}
        # Paths PI _N_F_XFER marked for upload, by their last part (an upload names only that).
        self.marked_for_transfer: dict[str, str] = {}
        # The activated definition files (GUD variables, macros): a file of those names is parsed
        # when it is written, and refused whole (its old definitions stay) when it has an error.
        self.definitions = GlobalDefinitions()
        # Channel 1's R parameters for an R value file (gud_values.py): how many, and how to write one
        # (the NCK model sets it; without it such a file is stored and assigns nothing).
        self.r_parameters: tuple[int, Callable[[int, float], None]] | None = None

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
        self._refuse_in_use(path)
        if is_definition_file(path):
            self.definitions.activate(path, bytes(text))  # raises DefinitionRefused
        elif is_values_file(path):
            self.definitions.assign_values(path, bytes(text))  # raises DefinitionRefused
        elif is_r_values_file(path) and self.r_parameters is not None:
            count, write_r = self.r_parameters
            self.definitions.assign_r_values(path, bytes(text), count, write_r)  # raises DefinitionRefused
        self.texts[path] = bytes(text)
        self.paths.add(path)
        self.stamps.pop(path, None)

    def _refuse_in_use(self, path: str) -> None:
        if path == self.running:
            raise NckPiStateError(f"{path} is running")
        if path in self.called():
            raise NckPiStateError(f"{path} is in use by the running program")

    def stored_bytes(self) -> int:
        """The bytes the program texts take (what the store's capacity limits)."""
        return sum(len(text) for text in self.texts.values())

    def mark_for_transfer(self, path: str) -> None:
        """PI _N_F_XFER: an upload naming ``path``'s last part fetches ``path`` (a file or a directory)."""
        if path not in self.paths and not self.is_directory(path):
            raise NckNoSuchFile(f"no file or directory {path}")
        self.marked_for_transfer[path.rsplit("/", 1)[-1]] = path

    def transfer_path(self, name: str) -> tuple[str, bool]:
        """The path an upload naming ``name`` fetches, and whether it is a directory: what _N_F_XFER
        marked under that name, else the directory or program the name gives (``_N_MPF_DIR``,
        ``_N_PART_WPD``, ``_N_TEST_MPF``, ``TEST.MPF``; case-insensitive). Raises NckPiBadArguments
        for a name that is neither."""
        text = name.strip().upper()
        marked = self.marked_for_transfer.get(text.rsplit("/", 1)[-1])
        if marked is not None and (not text.startswith("/") or text == marked):
            return marked, self.is_directory(marked)
        directory = directory_path(text)
        if directory is not None:
            return directory, True
        return program_path(text), False

    def is_directory(self, path: str) -> bool:
        """A main directory (``/_N_MPF_DIR``, ``/_N_SPF_DIR``, ``/_N_WKS_DIR``) or one holding a program."""
        path = path.rstrip("/")
        if path in DIRECTORIES:
            return True
        prefix = path + "/"
        return bool(path) and any(stored.startswith(prefix) for stored in self.paths)

    def children(self, directory: str) -> list[str]:
        """Paths of the files and directories directly in ``directory``, sorted."""
        prefix = directory.rstrip("/") + "/"
        found = {prefix + path[len(prefix):].split("/", 1)[0] for path in self.paths if path.startswith(prefix)}
        return sorted(found)

    def listing(self, directory: str = "") -> list[str]:
        """Paths in ``directory`` (``/_N_MPF_DIR``), or every path, sorted."""
        prefix = directory.rstrip("/") + "/" if directory else ""
        return sorted(path for path in self.paths if path.startswith(prefix))

    def snapshot(self) -> dict[str, Any]:
        """The program store as retained data: paths, and texts as base64."""
        return {"paths": sorted(self.paths),
                "texts": {path: base64.b64encode(text).decode("ascii") for path, text in sorted(self.texts.items())},
                "stamps": dict(sorted(self.stamps.items()))}

    def restore(self, snapshot: dict[str, Any]) -> None:
        """The store as ``snapshot`` left it (raises KeyError/TypeError/ValueError when it is damaged)."""
        paths = {str(path) for path in snapshot["paths"]}
        texts = {str(path): base64.b64decode(text, validate=True) for path, text in snapshot["texts"].items()}
        stamps = {str(path): str(stamp) for path, stamp in snapshot.get("stamps", {}).items()}
        self.paths = paths | set(texts)
        self.texts = texts
        self.stamps = stamps
        self.definitions.restore(texts)

    def select(self, path: str) -> None:
        if path not in self.paths:
            raise NckNoSuchFile(f"no program {path}")
        self.selected = path

    def delete(self, path: str) -> None:
        if path not in self.paths:
            raise NckNoSuchFile(f"no file {path}")
        if path == self.selected:
            raise NckPiStateError(f"{path} is selected")
        self._refuse_in_use(path)
        self.paths.discard(path)
        self.texts.pop(path, None)
        self.stamps.pop(path, None)
        self.definitions.remove(path)
