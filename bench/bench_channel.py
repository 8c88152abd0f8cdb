"""Part programs through the channel: blocks per second executed, and a 600x served run against its clock.

1. Blocks per second: a straight-move program (N G1 blocks, a CAM program's shape) and a loop-heavy one
   (a FOR loop of R-parameter arithmetic), each run offline through the whole channel (interpreter,
   planner, positions, block bookkeeping, the machine's cycle). The anchor, measured in the same run: the
   interpreter alone on the same text (events pulled, nothing timed), so the channel's own cost shows.
2. A 600x served run: a warm-up program (spindle steps, moves at feed, dwells) on a served machine with a
   LiveClock at 600x while a client polls BTSS values; printed: the pacer's cycles, its largest lag
   (simulated seconds behind the free-running clock at the start of a cycle), slips (it gave up
   catching up), the wall time per cycle, and the client's read latency.

Usage: .venv/bin/python bench/bench_channel.py [--moves 100000] [--loops 50000] [--wall 5] [--speed 600]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from nckemu.clients.sync import NckClient  # noqa: E402
from nckemu.emulator.machine.clock import LiveClock, SimulatedClock  # noqa: E402
from nckemu.emulator.machine.core import Emulator  # noqa: E402
from nckemu.emulator.machine.program.environment import ProgramEnvironment  # noqa: E402
from nckemu.emulator.machine.program.language import Interpreter  # noqa: E402
from nckemu.emulator.machine.program.offline import run_offline  # noqa: E402
from nckemu.emulator.runner import EmulatorThread  # noqa: E402

MAIN = "/_N_MPF_DIR/_N_BENCH_MPF"


def straight_moves(count: int) -> str:
    lines = ["G90 G71 G94 G64", "G0 X0 Y0 Z-10", "S6000 M3"]
    for n in range(count):
        lines.append(f"N{(n + 1) * 10} G1 X{(n * 7) % 1000 + 1:.3f} Y{(n * 13) % 700 + 1:.3f} F8000")
    lines += ["M5", "M30"]
    return "\n".join(lines) + "\n"


def loop_heavy(count: int) -> str:
    return (f"DEF INT CNT\nR1=0\nFOR CNT=1 TO {count}\nR1=R1+CNT*0.5\nR2=R1/CNT\nENDFOR\nG0 X=R2/R1\nM30\n")


def interpreter_alone(text: str) -> tuple[int, float]:
    env = ProgramEnvironment(axes=("X", "Y", "Z"))
    started = time.perf_counter()
    blocks = 0
    for event in Interpreter(env, MAIN, text).events():
        if type(event).__name__ == "Block":
            blocks += 1
    return blocks, time.perf_counter() - started


def through_channel(text: str) -> tuple[int, float, float]:
    emulator = Emulator(clock=SimulatedClock())
    emulator.nck.programs.write(MAIN, text.encode())
    started = time.perf_counter()
    result = run_offline(emulator, MAIN, max_time_s=30 * 24 * 3600.0)
    wall = time.perf_counter() - started
    if result.outcome != "ended":
        raise SystemExit(f"the bench program did not end: {result.outcome} {result.alarms}")
    return result.blocks, wall, result.net_time_s


WARM_UP = """; a 20 minute warm-up: spindle steps, moves at feed, dwells
DEF INT CYC
G90 G71 G94
G0 X100 Y100 Z-20
FOR CYC=1 TO 40
  S=1000+CYC*150 M3
  G1 X700 Y100 F6000
  G1 X700 Y600
  G1 X100 Y600
  G1 X100 Y100
  G4 F20
ENDFOR
M5
M30
"""


def served(speed: float, wall_s: float) -> dict[str, float]:
    emulator = Emulator(clock=LiveClock(speed))
    emulator.cycle_s = 1.0
    emulator.nck.programs.write(MAIN, WARM_UP.encode())
    latencies = []
    with EmulatorThread(emulator=emulator) as emu:
        channel = emulator.nck.channels[1]
        emu.call(lambda: (channel.select(MAIN), channel.start()))
        with NckClient("127.0.0.1", emu.port) as nck:
            deadline = time.monotonic() + wall_s
            while time.monotonic() < deadline:
                started = time.perf_counter()
                nck.get("progStatus[C1]", "actSpeed[C1]", "actBlock[C1]", "NCKEMU_ACTUAL_POS[AX1]")
                latencies.append(time.perf_counter() - started)
        pacer = emulator.pacer
        assert pacer is not None
        stats = pacer.stats
        result = {"cycles": stats.cycles, "max_lag_s": stats.max_lag_s, "slips": emulator.clock.slips,
                  "step_wall_ms": 1000.0 * stats.step_wall_s / max(1, stats.cycles),
                  "max_step_wall_ms": 1000.0 * stats.max_step_wall_s,
                  "simulated_s": emulator.clock.now_s(), "blocks": channel.run.blocks if channel.run else
                  channel.last_run_blocks, "reads": len(latencies),
                  "read_p50_ms": 1000.0 * statistics.median(latencies),
                  "read_p99_ms": 1000.0 * sorted(latencies)[int(0.99 * (len(latencies) - 1))]}
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--moves", type=int, default=100_000)
    parser.add_argument("--loops", type=int, default=50_000)
    parser.add_argument("--wall", type=float, default=5.0)
    parser.add_argument("--speed", type=float, default=600.0)
    args = parser.parse_args()

    for name, text in (("straight G1 moves", straight_moves(args.moves)), ("loop-heavy", loop_heavy(args.loops))):
        alone_blocks, alone_s = interpreter_alone(text)
        blocks, wall_s, simulated_s = through_channel(text)
        print(f"{name}: {blocks} blocks through the channel in {wall_s:.2f} s = {blocks / wall_s:,.0f} blocks/s "
              f"({simulated_s:,.0f} s simulated); anchor, the interpreter alone: {alone_blocks / alone_s:,.0f} "
              f"blocks/s; the channel costs {wall_s / alone_s:.2f}x the interpreter")
    figures = served(args.speed, args.wall)
    # The pacer holds the clock at each cycle until it has run: a lag is the wait of one cycle behind the
    # free-running clock; the run falls behind only when the pacer gives up and lets time slip.
    behind = "never fell behind its clock" if not figures["slips"] else "fell behind its clock"
    print(f"served at {args.speed:g}x for {args.wall:g} s wall: {figures['simulated_s']:.0f} s simulated, "
          f"{figures['cycles']} cycles, {figures['blocks']} blocks; pacer max lag {figures['max_lag_s']:.2f} s "
          f"simulated ({1000.0 * figures['max_lag_s'] / args.speed:.1f} ms wall), {figures['slips']} slips ({behind}); {figures['step_wall_ms']:.3f} ms per cycle (max "
          f"{figures['max_step_wall_ms']:.2f}); client reads {figures['reads']}, p50 {figures['read_p50_ms']:.2f} "
          f"ms, p99 {figures['read_p99_ms']:.2f} ms")


if __name__ == "__main__":
    main()
