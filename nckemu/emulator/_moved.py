"""Old module paths of the emulator (before the 0.2 layout) answer with the module that moved.

An import of ``nckemu.emulator.core`` gives ``nckemu.emulator.machine.core`` itself (the same module
object, so ``isinstance`` and monkeypatching see one thing). Only whole modules are redirected; names
that moved between modules (``Face``, now in ``nckemu.emulator.faces``) are not. The machine file's
old module ``nckemu.emulator.machine`` is now the machine package and cannot be redirected: import
``nckemu.emulator.machine.machine_file``.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
from types import ModuleType

MOVED: dict[str, str] = {
    "nckemu.emulator.core": "nckemu.emulator.machine.core",
    "nckemu.emulator.clock": "nckemu.emulator.machine.clock",
    "nckemu.emulator.state": "nckemu.emulator.machine.state",
    "nckemu.emulator.status": "nckemu.emulator.machine.status",
    "nckemu.emulator.live": "nckemu.emulator.machine.cycle",
    "nckemu.emulator.nck": "nckemu.emulator.machine.nck",
    "nckemu.emulator.plc": "nckemu.emulator.machine.plc",
    "nckemu.emulator.server": "nckemu.emulator.faces.s7.server",
    "nckemu.emulator.session": "nckemu.emulator.faces.s7.session",
    "nckemu.emulator.dispatch": "nckemu.emulator.faces.s7.dispatch",
    "nckemu.emulator.datastore": "nckemu.emulator.faces.s7.datastore",
    "nckemu.emulator.opcua": "nckemu.emulator.faces.opcua",
    "nckemu.emulator.web": "nckemu.emulator.faces.web",
    # moved to the catalogue before 0.2 (README "Layout")
    "nckemu.emulator.nck.table": "nckemu.catalogue.table",
    "nckemu.emulator.nck.leadscrew": "nckemu.catalogue.leadscrew",
}


def new_path(old: str) -> str | None:
    """The module an old path now names (a moved package's sub-modules included), or None."""
    if old in MOVED:
        return MOVED[old]
    head, _, tail = old.rpartition(".")
    while head:
        if head in MOVED:
            return MOVED[head] + old[len(head):]
        head, _, _ = head.rpartition(".")
    return None


class _Alias(importlib.abc.Loader):
    def __init__(self, target: str) -> None:
        self.target = target

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        return importlib.import_module(self.target)

    def exec_module(self, module: ModuleType) -> None:
        """The target module ran when it was imported."""


class _MovedFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname: str, path: object = None, target: object = None) \
            -> importlib.machinery.ModuleSpec | None:
        if not fullname.startswith("nckemu.emulator."):
            return None
        moved_to = new_path(fullname)
        if moved_to is None:
            return None
        module = importlib.import_module(moved_to)
        return importlib.machinery.ModuleSpec(fullname, _Alias(moved_to),
                                              is_package=hasattr(module, "__path__"))


def install() -> None:
    if not any(isinstance(finder, _MovedFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, _MovedFinder())
