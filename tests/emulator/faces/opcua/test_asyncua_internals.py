"""The face's reliance on asyncua internals is checked at import: the installed asyncua passes, and an
asyncua shaped otherwise fails with one clear error naming its version, not a silent misbehaviour."""

from __future__ import annotations

import pytest
from asyncua.server.address_space import AddressSpace
from asyncua.server.uaprocessor import UaProcessor

from nckemu.emulator.faces.opcua import asyncua_internals
from nckemu.errors import NckConfigError


def test_the_installed_asyncua_has_the_shape_the_face_relies_on() -> None:
    assert asyncua_internals.problems() == []
    asyncua_internals.check()


def test_a_moved_internal_is_named_with_the_asyncua_version(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delattr(AddressSpace, "load_aspace_shelf")

    async def renamed(self: object, typeid: object, header: object) -> None:  # another signature
        return None

    monkeypatch.setattr(UaProcessor, "_process_message", renamed)
    assert asyncua_internals.problems() == ["AddressSpace has no load_aspace_shelf",
                                            "UaProcessor._process_message takes other arguments"]
    with pytest.raises(NckConfigError) as raised:
        asyncua_internals.check()
    message = str(raised.value)
    assert isinstance(raised.value, asyncua_internals.AsyncuaShapeError)
    assert f"asyncua {asyncua_internals.VERSION} is installed" in message
    assert "load_aspace_shelf" in message and ">=2.1" in message


def test_no_other_module_of_the_face_names_an_asyncua_private() -> None:
    """Private asyncua names (``aspace._nodes``, ``_process_message`` ...) appear in asyncua_internals only."""
    import re
    from pathlib import Path

    package = Path(asyncua_internals.__file__).parent
    private = re.compile(r"\b(_nodes|_handle_to_attribute_map|_monitored_datachange|_process_message|"
                         r"_process_one_msg|_make_protocol|_publish_requests|_session_watchdog_task|"
                         r"_incoming_parts|_policies|_aspace|bserver\._server|_server_module)\b")
    found = {path.name: private.findall(path.read_text(encoding="utf-8"))
             for path in package.glob("*.py") if path.name != "asyncua_internals.py"}
    assert {name: hits for name, hits in found.items() if hits} == {}


def test_serve_on_an_asyncua_of_another_shape_says_so_in_one_line() -> None:
    """``nckemu serve --opcua`` on an asyncua whose internals moved: exit 1 and one line naming what moved."""
    import subprocess
    import sys

    script = ("import sys\n"
              "import asyncua.server.address_space as space\n"
              "del space.AddressSpace.load_aspace_shelf\n"
              "from nckemu.cli import main\n"
              "sys.exit(main(['serve', '--port', '0', '--opcua', '0']))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "AddressSpace has no load_aspace_shelf" in lines[0] and "asyncua" in lines[0]
