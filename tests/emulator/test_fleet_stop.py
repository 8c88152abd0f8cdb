"""A fleet stops its machines at once, not one after another (issue 44: 20 OPC UA faces at ~0.7 s each
took 10-15 s after SIGTERM); the figure `fleet --help` quotes is the one bench_fleet.py prints."""

from __future__ import annotations

import asyncio
import re
from types import SimpleNamespace

from nckemu.cli import _walk, build_parser
from nckemu.emulator.fleet import Fleet


class _Part:
    def __init__(self, events: list[str], name: str) -> None:
        self.events, self.name = events, name

    async def stop(self) -> None:
        self.events.append(f"start {self.name}")
        await asyncio.sleep(0.05)
        self.events.append(f"end {self.name}")


class _Broken:
    async def stop(self) -> None:
        raise RuntimeError("a face that fails to stop")


def test_the_machines_stop_at_once_and_a_failing_one_keeps_none_running() -> None:
    events: list[str] = []
    machines = [SimpleNamespace(entry=SimpleNamespace(name=f"m{i}"), opcua=_Part(events, f"ua{i}"), face=None,
                                server=_Part(events, f"s7{i}")) for i in range(5)]
    machines.append(SimpleNamespace(entry=SimpleNamespace(name="broken"), opcua=_Broken(), face=None,
                                    server=_Part(events, "s7broken")))
    asyncio.run(Fleet._stop(machines))  # type: ignore[arg-type]
    first_end = next(i for i, event in enumerate(events) if event.startswith("end"))
    assert all(f"start ua{i}" in events[:first_end] for i in range(5))  # every face stopping before one ends
    assert sum(event.startswith("end s7") for event in events) == 5     # the broken one's S7 face stays up


def test_fleet_help_cites_the_measured_figure_and_its_bench() -> None:
    fleet = next(p for p in _walk(build_parser()) if p.prog == "nckemu fleet")
    text = fleet.format_help()
    assert "measured by bench/bench_fleet.py" in text
    (per_machine,) = re.findall(r"(\d+(?:\.\d+)?) MB with an\s+OPC UA face", text)
    (quoted,) = re.findall(r"OPC UA face \(about (\d+) MB", text)
    assert round(float(per_machine)) == int(quoted)
    from bench import bench_fleet  # the bench prints the figure it quotes
    assert "MB per extra machine" in open(bench_fleet.__file__, encoding="utf-8").read()
