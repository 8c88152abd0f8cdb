"""Start time and memory of the OPC UA face with the umati and CNC models, beside the face without them.

Each case runs in a fresh Python process (so that memory and caches are the process's own):
- ``first``: an empty cache directory: the standard shelf and the models' shelf are built (the NodeSets
  imported), then the face starts;
- ``cached``: the same directory again: the face starts from the models' shelf;
- ``cached, 2nd face``: a second face in that process (what each machine of a fleet pays);
- ``without models``: ``[opcua] models = []`` from the same cache.

Prints one line per case: wall seconds to ``start()``, the process's peak RSS after it, nodes the models
added. ``python bench/bench_umati.py`` (needs the NodeSets: ``make nodesets``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

CHILD = r"""
import asyncio, dataclasses, json, resource, sys, time
from nckemu.emulator.faces.opcua import OpcUaFace
from nckemu.emulator.faces.opcua.settings import OpcUaSettings
from nckemu.emulator.machine.core import Emulator

async def main(models, faces):
    out = []
    for _ in range(faces):
        emulator = Emulator()
        settings = OpcUaSettings.from_machine(emulator.machine.opcua, emulator.machine.source)
        if not models:
            settings = dataclasses.replace(settings, models=())
        rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        started = time.perf_counter()
        face = await OpcUaFace(emulator, "127.0.0.1", 0, settings=settings).start()
        took = time.perf_counter() - started
        out.append({"start_s": took, "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                    "rss_before_mb": rss0, "nodes": face.models.nodes_made})
    print(json.dumps(out))

asyncio.run(main(sys.argv[1] == "models", int(sys.argv[2])))
"""


def run(cache: str, models: bool, faces: int) -> list[dict[str, float]]:
    env = dict(os.environ, NCKEMU_CACHE=cache)
    done = subprocess.run([sys.executable, "-c", CHILD, "models" if models else "none", str(faces)], env=env,
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def main() -> int:
    from nckemu.emulator.faces.opcua import nodesets

    if nodesets.find() is None:
        print(nodesets.how_to_get())
        return 0
    with tempfile.TemporaryDirectory() as cache:
        first = run(cache, True, 1)[0]
        cached = run(cache, True, 2)
        plain = run(cache, False, 2)
    rows = [("first (models imported)", first), ("cached", cached[0]), ("cached, 2nd face", cached[1]),
            ("without models", plain[0]), ("without models, 2nd face", plain[1])]
    for label, row in rows:
        print(f"{label:28s} start {row['start_s']:6.2f} s   peak RSS {row['rss_mb']:6.1f} MB "
              f"(+{row['rss_mb'] - row['rss_before_mb']:5.1f})   model nodes {row['nodes']:.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
