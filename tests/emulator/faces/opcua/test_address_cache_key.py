"""The address-space cache holds pickled asyncua objects, so it is kept per asyncua (and Python) version:
a shelf built by another asyncua (1.1 before the move to 2.x) is never loaded, the face builds its own."""

from __future__ import annotations

import sys
from pathlib import Path

import asyncua
import pytest

from nckemu.emulator.faces.opcua import shelf


def test_the_cache_directory_names_the_asyncua_and_python_versions(tmp_path: Path) -> None:
    python = f"py{sys.version_info[0]}.{sys.version_info[1]}"
    assert shelf.shelf_dir(tmp_path).name == f"asyncua-{asyncua.__version__}-{python}"
    assert shelf.shelf_dir(tmp_path, "models2-abc").name == f"asyncua-{asyncua.__version__}-{python}-models2-abc"


@pytest.mark.parametrize("kind", ["", "models2-abc"], ids=["standard", "models"])
def test_a_shelf_built_by_another_asyncua_is_not_loaded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        kind: str) -> None:
    monkeypatch.setenv("NCKEMU_CACHE", str(tmp_path))
    other = "1.1.8" if asyncua.__version__ != "1.1.8" else "2.1.0"
    built = Path(str(shelf.shelf_dir(tmp_path, kind)).replace(f"asyncua-{asyncua.__version__}-", f"asyncua-{other}-"))
    built.mkdir()
    (built / shelf.COMPLETE).write_text("asyncua address space\n", encoding="utf-8")
    (built / shelf.SHELF_NAME).write_bytes(b"pickled by another asyncua")
    assert shelf.ready_shelf(kind) is None
    mine = shelf.shelf_dir(tmp_path, kind)
    mine.mkdir()
    (mine / shelf.COMPLETE).write_text("asyncua address space\n", encoding="utf-8")
    assert shelf.ready_shelf(kind) == mine / shelf.SHELF_NAME
