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

import logging
import os
import shutil
import sys
import tempfile
from pathlib import Path

import asyncua

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


def shelf_dir(root: Path) -> Path:
    version = getattr(asyncua, "__version__", "unknown")
    return root / f"asyncua-{version}-py{sys.version_info[0]}.{sys.version_info[1]}"


def ready_shelf() -> Path | None:
    """The shelf to load, if one was built completely; None otherwise."""
    root = cache_root()
    if root is None:
        return None
    where = shelf_dir(root)
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


def new_shelf() -> Path | None:
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


def publish(built: Path) -> None:
    """Make a shelf built by ``new_shelf``'s caller the one later faces load. Two processes building at
    once: the first rename wins, the other's copy is removed."""
    building = built.parent
    root = cache_root()
    try:
        if root is None or not any(building.glob(f"{SHELF_NAME}*")):
            raise OSError("nothing was written")
        built.touch()
        (building / COMPLETE).write_text("asyncua standard address space\n", encoding="utf-8")
        building.rename(shelf_dir(root))
    except OSError:
        shutil.rmtree(building, ignore_errors=True)


def discard(shelf: Path) -> None:
    """A shelf that failed to load is removed, so that the next face builds a new one."""
    shutil.rmtree(shelf.parent, ignore_errors=True)
