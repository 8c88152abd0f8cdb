"""``nckemu program run``: a part program on the emulated channel, offline (a simulated clock).

Other areas add their commands to the same ``program`` group (put, get, list, select, start, ...).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from nckemu.catalogue.program_names import program_path
from nckemu.cliutil import check_output, command_group
from nckemu.errors import NckConfigError, NckError

if TYPE_CHECKING:
    from nckemu.emulator.machine.core import Emulator
    from nckemu.emulator.machine.program.block_record import BlockRecord

# The emulator (the interpreter, numpy) is imported by the functions that run it: the program group's
# other commands (put, select, start ... over the wire) register here too and start without it.

RUN_EXAMPLE = """\
examples:
  nckemu program run fixtures/programs/SHORT.MPF
  nckemu program run fixtures/programs/SHORT.MPF --blocks /tmp/blocks.csv --out /tmp/sim.csv --json
A main program calling a subprogram kept elsewhere (the SYIL 828D warm-up, for instance):
  program run DAILY.MPF --with ../subroutines/WARMUP_CYCLE.SPF --machine fixtures/machines/syil_x7.toml
  program run MPF/GRIND.MPF --with DEF/MGUD.DEF     (GUD arrays the program uses: INI[53]=1500)
  program run MPF/GRIND.MPF --with DEF/MGUD.DEF --with WHEEL.GUD  (the values an operator entered)
The program is stored under its name (DAILY.MPF -> /_N_MPF_DIR/_N_DAILY_MPF), with the .MPF/.SPF/.DEF
files next to it and every --with file (MGUD.DEF -> /_N_DEF_DIR/_N_MGUD_DEF, activated; WHEEL.GUD: GUD values,
INI[5]=3 a block, assigned); it runs on channel 1 until M2/M30, an alarm or --max-time.
--out writes what the run would have recorded (t_s, temp_<sensor>_C, spindle_rpm, pos_<axis>_mm: the
columns `plc run --inputs` and `discover` read); --blocks the executed blocks.
"""


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    group = command_group(subparsers, "program", "part programs: run one offline, and more")
    group_parser = subparsers.choices["program"]
    if not group_parser.epilog:
        group_parser.epilog = "example:\n  nckemu program run fixtures/programs/SHORT.MPF\n"
        group_parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser = group.add_parser(
        "run", help="run a part program offline on the emulated channel (simulated clock)", epilog=RUN_EXAMPLE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run a SINUMERIK part program on the emulated channel without a server: the blocks it "
                    "executes, with their simulated time, positions, feed, spindle speed and M codes, and any "
                    "alarm. The time model is the served channel's (docs/programs.md).")
    parser.add_argument("file", help="the main program (e.g. DAILY.MPF)")
    parser.add_argument("--machine", help="machine TOML (default: the built-in default machine)")
    parser.add_argument("--with", dest="extra", action="append", default=[], metavar="FILE",
                        help="another program to store first (a subprogram in another folder, a .DEF definition file, a .GUD "
                             "file of GUD values, a .RPA file of R parameters); repeatable, stored in the order given")
    parser.add_argument("--blocks", metavar="BLOCKS.csv", help="write the executed blocks to this CSV file")
    parser.add_argument("--out", metavar="SIM.csv", help="write the recording the run would have made")
    parser.add_argument("--sample", type=float, default=1.0, metavar="S",
                        help="seconds between the rows of --out (1.0)")
    parser.add_argument("--max-time", type=float, default=24 * 3600.0, metavar="S",
                        help="stop after this much simulated time (an endless program; 86400)")
    parser.add_argument("--json", action="store_true", help="print a JSON summary on stdout (no block lines)")
    parser.set_defaults(func=run_program_command)


def _program_name(path: Path) -> str:
    try:
        return program_path(path.name)
    except NckError:
        raise NckConfigError("not an NC program name (NAME.MPF or NAME.SPF: letters, digits, _)",
                             path=str(path)) from None


def _read(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=str(path)) from None


def store_programs(emulator: Emulator, files: list[str]) -> str:
    """Store ``files`` (the first is the main program; the .MPF/.SPF files beside it come too) and
    return the main program's NC path (``serve --program``, ``program run``)."""
    main = Path(files[0])
    if not main.is_file():
        raise NckConfigError("no such program file", path=str(main))
    return _store(emulator, main, list(files[1:]))


def _store(emulator: Emulator, main: Path, extra: list[str]) -> str:
    from nckemu.emulator.machine.program.language.definitions import DefinitionRefused

    programs = emulator.nck.programs
    siblings = sorted(main.parent.glob("*")) if main.parent.is_dir() else []
    # definitions first, GUD values last: the values go into the variables the definitions make
    order = {".DEF": 0, ".MPF": 1, ".SPF": 1, ".GUD": 2, ".RPA": 2}
    for sibling in sorted(siblings, key=lambda path: order.get(path.suffix.upper(), 3)):
        if sibling != main and sibling.suffix.upper() in order and sibling.is_file():
            try:
                programs.write(program_path(sibling.name), _read(sibling))
            except DefinitionRefused as exc:  # MGUD.DEF beside the program: its error is the user's
                raise NckConfigError(f"definition file refused: {exc}", path=str(sibling)) from None
            except NckError:
                continue  # a file that is no NC program name next to it: not ours to refuse
    for name in extra:
        path = Path(name)
        try:
            programs.write(_program_name(path), _read(path))
        except DefinitionRefused as exc:
            raise NckConfigError(f"definition file refused: {exc}", path=str(path)) from None
    target = _program_name(main)
    programs.write(target, _read(main))
    return target


def _block_row(record: BlockRecord, axes: list[str]) -> list[Any]:
    return [f"{record.start_s:.3f}", f"{record.end_s:.3f}", record.program, record.line, record.number,
            record.text, *(f"{record.positions_mm.get(axis, 0.0):.4f}" for axis in axes),
            f"{record.feed_mm_min:g}", f"{record.spindle_rpm:.1f}", " ".join(f"M{m}" for m in record.m_codes),
            record.note]


def run_program_command(args: argparse.Namespace) -> int:
    from nckemu.emulator.machine.clock import SimulatedClock
    from nckemu.emulator.machine.core import Emulator
    from nckemu.emulator.machine.nck.run_geometry import path_axis_names
    from nckemu.emulator.machine.offline import recording_columns, run_offline

    check_output(args.blocks, "--blocks")
    check_output(args.out, "--out")
    if not args.sample > 0 or not args.max_time > 0:
        raise NckConfigError("--sample and --max-time must be positive")
    main = Path(args.file)
    if not main.is_file():
        raise NckConfigError("no such program file", path=str(main))
    emulator = Emulator(args.machine, clock=SimulatedClock())
    target = _store(emulator, main, args.extra)
    axes = path_axis_names(emulator.nck)
    block_file: TextIO | None = open(args.blocks, "w", newline="", encoding="utf-8") if args.blocks else None  # noqa: SIM115
    out_file: TextIO | None = open(args.out, "w", newline="", encoding="utf-8") if args.out else None  # noqa: SIM115
    header = ["t_s", "end_s", "program", "line", "N", "block", *(f"{axis}_mm" for axis in axes), "feed",
              "spindle_rpm", "M", "note"]
    blocks_out = csv.writer(block_file) if block_file is not None else None
    stdout_blocks = block_file is None and not args.json
    if blocks_out is not None:
        blocks_out.writerow(header)
    elif stdout_blocks:
        print("\t".join(header), flush=False)
    samples = csv.writer(out_file) if out_file is not None else None
    if samples is not None:
        samples.writerow(recording_columns(emulator))
    progress = sys.stderr.isatty() and not args.json
    started = time.monotonic()

    def block(record: BlockRecord) -> None:
        row = _block_row(record, axes)
        if blocks_out is not None:
            blocks_out.writerow(row)
        elif stdout_blocks:
            print("\t".join(str(value) for value in row))

    def show(t_s: float, record: BlockRecord | None) -> None:
        where = f"{record.program.rsplit('/', 1)[-1]} line {record.line}" if record is not None else ""
        print(f"\r  {t_s:10.1f} s simulated  {where:40s}", end="", file=sys.stderr, flush=True)

    try:
        result = run_offline(emulator, target, sample_s=args.sample, max_time_s=args.max_time,
                             on_block=block if blocks_out is not None or stdout_blocks else None,
                             on_sample=(lambda row: samples.writerow([repr(v) for v in row]))
                             if samples is not None else None,
                             on_progress=show if progress else None)
    finally:
        for handle in (block_file, out_file):
            if handle is not None:
                handle.close()
        if progress:
            print(file=sys.stderr)
    summary = {"program": target, "outcome": result.outcome, "simulated_s": round(result.t_s, 3),
               "net_time_s": round(result.net_time_s, 3), "blocks": result.blocks, "parts": result.parts,
               "alarms": result.alarms, "not_simulated": result.not_simulated, "notes": result.notes,
               "wall_s": round(time.monotonic() - started, 3)}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"{target}: {result.outcome} after {result.net_time_s:.1f} s simulated ({result.blocks} blocks, "
              f"{result.parts:g} parts)" + "".join(f"\n  {line}" for line in result.not_simulated_lines())
              + "".join(f"\n  alarm: {text}" for text in result.alarms)
              + "".join(f"\n  note: {text}" for text in result.notes))
    return 0 if result.outcome == "ended" else 1


