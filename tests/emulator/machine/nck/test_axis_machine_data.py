"""Every axis machine datum the reference sheets name (and MD33120, which libsiemenscnc's own example
reads) answers over S7 with its type, unit and default, as a real NCK answers every MD it has (issue 44)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from nckemu.catalogue.table import load_table
from nckemu.clients import NckClient
from nckemu.emulator.runner import EmulatorThread
from nckemu.protocol.addresses import NckArea

# an MD number as the sheets write it: MD32000, "| 32300 `$MA_..", "35130 / 35140 `GEAR_..."
_AXIS_MD = re.compile(r"(?:MD ?|\| |/ )(3\d{4})\b")


@pytest.fixture(scope="module")
def client() -> Iterator[NckClient]:
    with EmulatorThread() as emu, NckClient("127.0.0.1", emu.port) as nck:
        yield nck


def _catalogue() -> dict[str, object]:
    return {spec.number: spec for spec in load_table()}


def test_md33120_answers_with_its_default(client: NckClient) -> None:
    spec = _catalogue()["MD33120"]
    assert spec.areas == {NckArea.A} and spec.unit == "mm"  # type: ignore[attr-defined]
    assert client.get("MD33120[AX1]", "$MA_PATH_TRANS_POS_TOL[AX4]") == [0.005, 0.005]


def test_every_axis_md_the_reference_names_answers(shared_dir: Path, client: NckClient) -> None:
    named = {f"MD{number}" for sheet in sorted(shared_dir.glob("reference/*.md"))
             for number in _AXIS_MD.findall(sheet.read_text(encoding="utf-8"))}
    catalogue = _catalogue()
    assert "MD32300" in named and "MD35200" in named
    missing = sorted(named - set(catalogue))
    assert not missing, f"axis machine data the reference names but the catalogue lacks: {missing}"
    for number in sorted(named):
        spec = catalogue[number]
        assert spec.areas == {NckArea.A}, number  # type: ignore[attr-defined]
        (value,) = client.get(f"{number}[AX1]")
        default = spec.default  # type: ignore[attr-defined]
        assert value == (default[0] if isinstance(default, list | tuple) else default), number
