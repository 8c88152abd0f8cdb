"""asyncua's standard address space kept on disk, so that a face starts in tens of milliseconds.

Every asyncua server builds the standard OPC UA address space (5 820 nodes) when it starts: about 2 s
and 55 MB each, which a fleet pays once per machine. asyncua can instead read the nodes from a
``shelve`` file as they are first used (``Server.init(shelf_file)``), each server keeping its own copies
of the nodes it touches. The first face to start builds the shelf under the user's cache directory;
every later face, in this process or another, reads it.

Where: ``$NCKEMU_CACHE`` or ``$XDG_CACHE_HOME/nckemu`` or ``~/.cache/nckemu``; ``NCKEMU_CACHE=off`` turns
the shelf off (every face then builds its own address space as asyncua does by default). One shelf per
asyncua and Python version, since the shelf holds pickled asyncua objects. A cache that cannot be
written or read only costs the time: the face then builds the address space itself.
"""

from __future__ import annotations

import collections.abc
import logging
import os
import shelve
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

import asyncua

from nckemu.emulator.faces.opcua import asyncua_internals

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.opcua.shelf")

SHELF_NAME = "standard"
COMPLETE = "complete"


def cache_root() -> Path | None:
    """The cache directory, or None when turned off."""
    chosen = os.environ.get("NCKEMU_CACHE")
    if chosen is not None:
        return None if chosen.strip().lower() in ("", "off", "0", "no") else Path(chosen)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "nckemu"


def shelf_dir(root: Path, kind: str = "") -> Path:
    """Where a shelf lives: the standard address space's (``kind`` ""), or another kind beside it (the
    companion models', ``nodesets.py``)."""
    version = getattr(asyncua, "__version__", "unknown")
    return root / f"asyncua-{version}-py{sys.version_info[0]}.{sys.version_info[1]}{'-' + kind if kind else ''}"


def ready_shelf(kind: str = "") -> Path | None:
    """The shelf to load, if one was built completely; None otherwise."""
    root = cache_root()
    if root is None:
        return None
    where = shelf_dir(root, kind)
    if not (where / COMPLETE).is_file():
        return None
    shelf = where / SHELF_NAME
    # asyncua loads a shelf only where its path is a file; the "dumb" dbm keeps .dat/.dir files beside it.
    if not shelf.exists():
        try:
            shelf.touch()
        except OSError:
            return None
    return shelf


def new_shelf(kind: str = "") -> Path | None:
    """Where a face that finds no shelf builds one (a private directory; ``publish`` moves it in place)."""
    root = cache_root()
    if root is None:
        return None
    try:
        root.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(prefix=".building-", dir=root)) / SHELF_NAME
    except OSError as exc:
        log.info("OPC UA: no address-space cache in %s (%s); each face builds its own", root, exc.strerror)
        return None


def publish(built: Path, kind: str = "") -> None:
    """Make a shelf built by ``new_shelf``'s caller the one later faces load. Two processes building at
    once: the first rename wins, the other's copy is removed."""
    building = built.parent
    root = cache_root()
    try:
        if root is None or not any(building.glob(f"{SHELF_NAME}*")):
            raise OSError("nothing was written")
        built.touch()
        (building / COMPLETE).write_text(f"asyncua {kind or 'standard'} address space\n", encoding="utf-8")
        building.rename(shelf_dir(root, kind))
    except OSError:
        shutil.rmtree(building, ignore_errors=True)


def discard(shelf: Path) -> None:
    """A shelf that failed to load is removed, so that the next face builds a new one."""
    for key in [key for key in _OPEN if key[0] == str(shelf)]:
        _OPEN.pop(key).close()
    shutil.rmtree(shelf.parent, ignore_errors=True)


# Shelves opened by this process, by path and the files' change times: asyncua opens a shelf for every
# server, and the "dumb" dbm reads its whole index each time (0.1-1 s for the models' shelf); the faces of
# one process (a fleet, a test run) share one open shelf instead, each keeping its own copies of the nodes.
_OPEN: dict[tuple[str, float], shelve.Shelf[Any]] = {}


class ShelfNodes(collections.abc.MutableMapping):  # type: ignore[type-arg]
    """asyncua's ``LazyLoadingDict`` over a shared open shelf: a node is read from the shelf when first
    named and kept in this server's own dict; nodes made later live in that dict only."""

    def __init__(self, source: shelve.Shelf[Any]) -> None:
        self.source = source
        self.cache: dict[Any, Any] = {}

    def __getitem__(self, key: Any) -> Any:
        try:
            return self.cache[key]
        except KeyError:
            node = self.cache[key] = self.source[key.to_string()]
            return node

    def __setitem__(self, key: Any, value: Any) -> None:
        self.cache[key] = value

    def __contains__(self, key: object) -> bool:
        return key in self.cache or (hasattr(key, "to_string") and key.to_string() in self.source)

    def __delitem__(self, key: Any) -> None:
        del self.cache[key]

    def __iter__(self) -> Any:
        return iter(self.cache.keys())

    def __len__(self) -> int:
        return len(self.cache)


def share(server: Any) -> None:
    """Make ``server`` load its shelf (``Server.init(shelf)``) from the process's open copy."""
    aspace = server.iserver.aspace

    def load(path: Path) -> None:
        stamps = [p.stat().st_mtime for p in Path(path).parent.glob(f"{Path(path).name}*")]
        key = (str(path), max(stamps, default=0.0))
        source = _OPEN.get(key)
        if source is None:
            source = _OPEN[key] = shelve.open(str(path), "r")
        asyncua_internals.replace_nodes(aspace, ShelfNodes(source))

    asyncua_internals.load_shelves_with(aspace, load)
