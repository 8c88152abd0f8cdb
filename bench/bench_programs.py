"""Part programs through the interpreter (nckemu/emulator/machine/program/language), in one run:

- blocks per second executed for a program of straight G1 moves, and for a loop-heavy program
  (FOR, IF, arithmetic, R parameters), and (no target) for circles with I/J: the interpreter's events
  consumed as a channel would;
- pygcode (PyPI, a pure-Python G-code parser) only *parsing* the same straight-move program, as the
  anchor: printed as a ratio (skipped with a message when pygcode is not installed: `pip install
  -e .[bench]`);
- the peak memory (RSS) of a child process that loads and runs a 400 000-line CAM-style program
  (block numbers, decimals, comments, tool changes, cycles, feeds), against the same child's RSS
  before it reads the program.

Targets (issue 41): >= 50 000 blocks/s executed, faster than pygcode only parses, < 100 MB for the
400 000-line program. (The 600x live run with the web page open is the channel's figure.)

Usage: .venv/bin/python bench/bench_programs.py [--blocks 200000] [--cam-lines 400000] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from nckemu.emulator.machine.program.environment import ProgramEnvironment  # noqa: E402
from nckemu.emulator.machine.program.language import Interpreter  # noqa: E402
from nckemu.emulator.machine.program.motions import Block  # noqa: E402

PATH = "/_N_MPF_DIR/_N_BENCH_MPF"


def straight_program(blocks: int) -> str:
    lines = ["G90 G94 G17"]
    lines += [f"N{i + 10} G1 X{(i % 400) * 0.25:.3f} Y{(i * 7 % 300) * 0.125:.3f} Z-{i % 5}.{i % 10} F1200"
              for i in range(blocks)]
    lines.append("M30")
    return "\n".join(lines) + "\n"


def arc_program(blocks: int) -> str:
    lines = ["G90 G17 G0 X10 Y0 F1000"]
    lines += [f"N{i + 10} G3 X-10 Y0 I-10 J0" if i % 2 == 0 else f"N{i + 10} G3 X10 Y0 I10 J0"
              for i in range(blocks)]
    return "\n".join(lines) + "\nM30\n"


def loop_program(iterations: int) -> str:
    return f"""DEF INT IDX
DEF REAL TOTAL, PHASE
FOR IDX = 1 TO {iterations}
  PHASE = IDX * 3.6
  TOTAL = TOTAL + SIN(PHASE) * 2 + R1
  IF TOTAL > 100
    TOTAL = 0
  ENDIF
  R1 = IDX MOD 7
ENDFOR
M30
"""


def cam_program(lines: int) -> str:
    """A program as a CAM post writes it: mostly G1 X Y Z with decimals, block numbers, comments."""
    out = ["; CAM output (generated for the benchmark)", "G90 G94 G17 G71", "G54", 'T="END_MILL_10" D1 M6',
           "S8000 M3", "CYCLE832(0.01, 0, 1)", "G0 X0 Y0 Z50"]
    number = 10
    while len(out) < lines - 2:
        step = len(out)
        if step % 5000 == 0:
            out.append(f"N{number} ; pass {step // 5000}")
        elif step % 997 == 0:
            out.append(f"N{number} G0 Z{5 + step % 7}.000")
        else:
            out.append(f"N{number} G1 X{(step % 1200) * 0.0831:.4f} Y{(step * 13 % 900) * 0.0917:.4f} "
                       f"Z{-(step % 30) * 0.05:.4f} F{1500 + step % 500}")
        number += 2
    out += ["M5", "M30"]
    return "\n".join(out) + "\n"


def execute(text: str) -> tuple[int, float]:
    """Blocks executed and seconds, consuming every event."""
    env = ProgramEnvironment(axes=("X", "Y", "Z", "A", "C"))
    blocks = 0
    started = time.perf_counter()
    for event in Interpreter(env, PATH, text).events():
        if event.__class__ is Block:
            blocks += 1
    return blocks, time.perf_counter() - started


def pygcode_parse(text: str) -> float | None:
    try:
        from pygcode import Line  # type: ignore[import-not-found]
    except ImportError:
        return None
    lines = text.splitlines()
    started = time.perf_counter()
    for line in lines:
        Line(line)
    return time.perf_counter() - started


def rss_mb() -> float:
    with open("/proc/self/statm") as handle:
        return int(handle.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def peak_rss_mb() -> float:
    """VmHWM: this process image's peak RSS (ru_maxrss would include the parent's before exec)."""
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def memory_child(program: Path) -> dict[str, Any]:
    """Runs in a child: RSS before the program is read, then the peak RSS after loading and running it."""
    before = rss_mb()
    text = program.read_bytes().decode()  # as the program store hands it over: bytes, then one str
    blocks, seconds = execute(text)
    peak_mb = peak_rss_mb()
    return {"lines": text.count("\n"), "text_mb": round(len(text) / 2**20, 1), "blocks": blocks,
            "seconds": round(seconds, 2), "rss_before_mb": round(before, 1), "rss_after_mb": round(rss_mb(), 1),
            "peak_rss_mb": round(peak_mb, 1)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--blocks", type=int, default=200_000, help="straight G1 blocks (default 200000)")
    parser.add_argument("--loops", type=int, default=40_000, help="iterations of the loop program")
    parser.add_argument("--cam-lines", type=int, default=400_000, help="lines of the CAM-style program")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument("--memory-child", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.memory_child:
        print(json.dumps(memory_child(args.memory_child)))
        return 0

    straight = straight_program(args.blocks)
    blocks, seconds = execute(straight)
    results: dict[str, Any] = {"straight_blocks": blocks, "straight_blocks_per_s": round(blocks / seconds)}
    arc_blocks, arc_seconds = execute(arc_program(args.blocks // 4))
    results.update(arc_blocks=arc_blocks, arc_blocks_per_s=round(arc_blocks / arc_seconds))
    loop_blocks, loop_seconds = execute(loop_program(args.loops))
    results.update(loop_blocks=loop_blocks, loop_blocks_per_s=round(loop_blocks / loop_seconds))
    parse_seconds = pygcode_parse(straight)
    if parse_seconds is None:
        results["pygcode"] = "not installed (pip install -e .[bench]); no anchor figure"
    else:
        lines = straight.count("\n")
        results["pygcode_parse_lines_per_s"] = round(lines / parse_seconds)
        results["executed_over_pygcode_parsed"] = round((blocks / seconds) / (lines / parse_seconds), 2)
    with tempfile.TemporaryDirectory() as scratch:
        program = Path(scratch) / "CAM.MPF"
        program.write_text(cam_program(args.cam_lines))
        child = subprocess.run([sys.executable, __file__, "--memory-child", str(program)],
                               capture_output=True, text=True, check=True)
    results["cam_program"] = json.loads(child.stdout)

    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    print(f"straight G1: {results['straight_blocks']} blocks, {results['straight_blocks_per_s']} blocks/s executed "
          "(target >= 50000)")
    print(f"circles    : {results['arc_blocks']} blocks, {results['arc_blocks_per_s']} blocks/s executed")
    print(f"loop-heavy : {results['loop_blocks']} blocks, {results['loop_blocks_per_s']} blocks/s executed")
    if "pygcode_parse_lines_per_s" in results:
        print(f"pygcode    : {results['pygcode_parse_lines_per_s']} lines/s parsed only; executed/parsed = "
              f"{results['executed_over_pygcode_parsed']} (target > 1)")
    else:
        print(f"pygcode    : {results['pygcode']}")
    cam = results["cam_program"]
    print(f"CAM program: {cam['lines']} lines, {cam['text_mb']} MB of text, {cam['blocks']} blocks in "
          f"{cam['seconds']} s; peak RSS {cam['peak_rss_mb']} MB (before the program {cam['rss_before_mb']} MB, "
          f"after the run {cam['rss_after_mb']} MB; target < 100 MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
