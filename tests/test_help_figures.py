"""A figure a help text quotes is a measured one (issue 37: `fleet --help` said an OPC UA face takes
about 55 MB; measured, about 4 MB): the OPC UA faces of a fleet, started in a fresh process, measured.

A fresh process: in a test worker that ran other tests first, the faces fill memory those tests freed and
the resident size hardly grows (0.08 MB a face was measured so, in a full run)."""

from __future__ import annotations

import gc
import re
import subprocess
import sys
from pathlib import Path

import pytest

from nckemu.cli import _walk, build_parser
from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.machine.core import Emulator

pytestmark = pytest.mark.timeout(240)
FACES = 8


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise AssertionError("no VmRSS")


async def _mb_per_face() -> float:
    faces = [await OpcUaFace(Emulator(), "127.0.0.1", 0).start()]  # the first reads the shared cache
    try:
        gc.collect()
        before = _rss_mb()
        for _ in range(FACES):
            faces.append(await OpcUaFace(Emulator(), "127.0.0.1", 0).start())
        gc.collect()
        return (_rss_mb() - before) / FACES
    finally:
        for face in faces:
            await face.stop()


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="RSS read from /proc")
def test_the_fleet_help_quotes_the_measured_memory_of_an_opcua_face() -> None:
    fleet = next(p for p in _walk(build_parser()) if p.prog == "nckemu fleet")
    (quoted,) = (float(f) for f in re.findall(r"OPC UA face \(about (\d+) MB", fleet.format_help()))
    done = subprocess.run([sys.executable, "-c", "import asyncio; from tests.test_help_figures import "
                           "_mb_per_face; print(asyncio.run(_mb_per_face()))"],
                          cwd=Path(__file__).resolve().parents[1], capture_output=True, text=True, timeout=200)
    assert done.returncode == 0, done.stderr[-2000:]
    measured = float(done.stdout.split()[-1])
    assert measured < 2 * quoted, f"an OPC UA face takes {measured:.1f} MB, the help says about {quoted:g} MB"
    assert measured > quoted / 4, f"an OPC UA face takes {measured:.1f} MB, the help says about {quoted:g} MB"
