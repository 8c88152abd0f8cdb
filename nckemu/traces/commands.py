"""``nckemu trace show`` and ``nckemu trace replay``."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable

from nckemu.cliutil import progress_bar
from nckemu.errors import NckConfigError

from .decode import decode, format_exchange, format_gap
from .reader import read_capture
from .replay import replay, seed_values


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    raw = argparse.RawDescriptionHelpFormatter
    trace = subparsers.add_parser(
        "trace", help="decode and replay field captures (pcap, pcapng)", formatter_class=raw,
        epilog="examples:\n  nckemu trace show fixtures/traces/session.pcapng\n  nckemu trace replay fixtures/traces/session.pcapng\n")
    commands = trace.add_subparsers(dest="trace_command", metavar="COMMAND")
    show = commands.add_parser("show", help="one line per job/answer, items by variable name", formatter_class=raw,
                               epilog="example: nckemu trace show fixtures/traces/session.pcapng --var SD43900 --json")
    show.add_argument("capture", help="pcap or pcapng file (Wireshark, tshark, tcpdump, nckemu serve --record)")
    show.add_argument("--port", type=int, default=102, help="server port in the capture (102)")
    show.add_argument("--var", help="only exchanges with an item whose name contains this")
    show.add_argument("--connection", type=int, help="only this connection (1, 2, ... as listed)")
    show.add_argument("--json", action="store_true", help="records as JSON")
    show.set_defaults(func=run_show)
    again = commands.add_parser(
        "replay", help="send the recorded jobs to an emulator and diff the answers", formatter_class=raw,
        epilog="example: nckemu trace replay fixtures/traces/session.pcapng --spawn --seed-state\n"
               "         nckemu trace replay fixtures/traces/session.pcapng --emulator 127.0.0.1:1102")
    again.add_argument("capture", help="pcap or pcapng file whose client jobs are sent again")
    again.add_argument("--port", type=int, default=102, help="server port in the capture (102)")
    target = again.add_mutually_exclusive_group()
    target.add_argument("--emulator", metavar="HOST:PORT", help="a running emulator")
    target.add_argument("--spawn", action="store_true", help="start an emulator in this process (default)")
    again.add_argument("--machine", help="machine TOML for --spawn")
    again.add_argument("--realtime", action="store_true", help="keep the recorded timing")
    again.add_argument("--seed-state", action="store_true",
                       help="first set the values the trace's first reads show, to reproduce the field state")
    again.add_argument("--timeout", type=float, default=5.0, metavar="SECONDS",
                       help="seconds to wait for each answer (5, as get)")
    again.add_argument("--connect-timeout", type=float, default=2.0, metavar="SECONDS",
                       help="seconds to wait for the answer to each connection request (2): a port that "
                            "accepts TCP but stays silent is given up after it")
    again.add_argument("--json", action="store_true", help="print the report as JSON on stdout")
    again.add_argument("--quiet", action="store_true", help="no progress bar (there is none when not a terminal)")
    again.set_defaults(func=run_replay)
    trace.set_defaults(func=lambda args: trace.print_help() or 2)


def run_show(args: argparse.Namespace) -> int:
    capture = read_capture(args.capture, port=args.port)
    exchanges = decode(capture)
    if args.connection is not None:
        if args.connection not in capture.connections:
            known = ", ".join(str(n) for n in capture.connections) or "none"
            raise NckConfigError(f"--connection {args.connection}: the capture has no such connection "
                                 f"(it has: {known})", path=args.capture)
        exchanges = [e for e in exchanges if e.connection == args.connection]
    gaps = [g for g in capture.gaps if args.connection is None or g.connection == args.connection]
    if args.var:
        exchanges = [e for e in exchanges if any(args.var.upper() in i.name.upper() for i in e.items)]
    if args.json:
        print(json.dumps({"capture": args.capture, "frames": capture.frames, "connections": capture.connections,
                          "exchanges": [e.to_json() for e in exchanges], "problems": capture.problems,
                          "gaps": [g.to_json() for g in gaps]}))
    else:
        start = exchanges[0].job.time_s if exchanges else 0.0
        for number, label in capture.connections.items():
            print(f"connection c{number}: {label}")
        # A gap line stands where the capture lost bytes, among the exchanges in frame order.
        pending_gaps = sorted(gaps, key=lambda g: g.frame) if not args.var else []
        for exchange in exchanges:
            while pending_gaps and pending_gaps[0].frame <= exchange.job.frame:
                print(format_gap(pending_gaps.pop(0), start))
            print("\n".join(format_exchange(exchange, start)))
        for gap in pending_gaps:
            print(format_gap(gap, start))
    if gaps:
        missing = sum(g.missing_bytes for g in gaps)
        print(f"nckemu trace: {args.capture}: {len(gaps)} gap{'s' if len(gaps) != 1 else ''} in the TCP streams "
              f"({missing} bytes not captured); each resynced on the next TPKT header", file=sys.stderr)
    for problem in capture.problems:
        print(f"nckemu trace: {problem}", file=sys.stderr)
    if not capture.pdus:
        print(f"nckemu trace: {args.capture}: no S7 traffic on port {args.port} "
              f"({capture.frames} frames read)", file=sys.stderr)
        return 1
    return 0


def progress_printer(enabled: bool) -> Callable[[int, int], None] | None:
    """A progress bar on a terminal (tqdm on stderr), None when not enabled or not a terminal."""
    if not enabled or not sys.stderr.isatty():
        return None
    bar = progress_bar(None, description="replay", unit="job")

    def show(done: int, total: int) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()
        if done == total:
            bar.close()

    return show


def run_replay(args: argparse.Namespace) -> int:
    capture = read_capture(args.capture, port=args.port)
    if not capture.pdus:
        raise NckConfigError(f"no S7 traffic on port {args.port}", path=args.capture)
    if not args.timeout > 0:
        raise NckConfigError(f"--timeout {args.timeout}: expected a positive number of seconds")
    if not args.connect_timeout > 0:
        raise NckConfigError(f"--connect-timeout {args.connect_timeout}: expected a positive number of seconds")
    progress = progress_printer(not args.quiet)
    if args.emulator:
        host, _, port_text = args.emulator.rpartition(":")
        if not host or not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
            raise NckConfigError(f"--emulator {args.emulator!r}: expected HOST:PORT (port 1..65535)")
        if args.seed_state:
            _seed_remote(host, int(port_text), capture)
        report = replay(capture, host, int(port_text), realtime=args.realtime, timeout_s=args.timeout,
                        progress=progress, connect_timeout_s=args.connect_timeout)
    else:
        # The one place where a trace tool starts an emulator (``--spawn``): the command composes the
        # two; the trace library itself stays independent of the emulator (see .importlinter).
        from nckemu.emulator.runner import EmulatorThread

        with EmulatorThread(args.machine) as emulator:
            if args.seed_state:
                values = seed_values(decode(capture))
                emulator.call(lambda: emulator.emulator.seed_nck(values))
            report = replay(capture, "127.0.0.1", emulator.port, realtime=args.realtime, timeout_s=args.timeout,
                            progress=progress, connect_timeout_s=args.connect_timeout)
    if args.json:
        print(json.dumps(report.to_json()))
    else:
        for note in report.notes:
            print(f"note: {note}")
        print(f"{_count(report.jobs, 'job')} replayed: {_count(report.matching_items, 'item')} "
              f"{'matches' if report.matching_items == 1 else 'match'}, "
              f"{_count(report.differing_values, 'value')} {_differ(report.differing_values)}, "
              f"{_count(report.differing_return_codes, 'return code')} {_differ(report.differing_return_codes)}, "
              f"{_count(report.differing_errors, 'header error')} {_differ(report.differing_errors)}, "
              f"{_count(report.missing_answers, 'answer')} missing")
        skipped = ", ".join(f"{count} {what}" for what, count in report.skipped.items() if count)
        if skipped:
            print(f"not replayed: {skipped}")
        for difference in report.differences:
            print(f"  frame {difference['frame']} c{difference['connection']} {difference['function']} "
                  f"{difference['item']}: {difference['kind']}: recorded {difference['recorded']!r}, "
                  f"emulated {difference['emulated']!r}")
    return 0 if report.all_match else 1


def _count(number: int, noun: str) -> str:
    return f"{number} {noun}" if number == 1 else f"{number} {noun}s"


def _differ(number: int) -> str:
    return "differs" if number == 1 else "differ"


def _seed_remote(host: str, port: int, capture: object) -> None:
    from nckemu.catalogue.names import variable_for_address
    from nckemu.clients import NckClient
    from nckemu.errors import NckError
    from nckemu.protocol.values import decode_nck_values

    values = seed_values(decode(capture))  # type: ignore[arg-type]
    with NckClient(host, port) as client:
        try:
            client.login("SUNRISE")
        except NckError:
            pass
        for address, data in values.items():
            variable = variable_for_address(address)
            try:
                decoded = decode_nck_values(variable.nck_type, data, area=address.area,
                                            line_count=address.line_count, string_length=variable.length)
                client.put_items([(variable, decoded[0] if len(decoded) == 1 else decoded)])
            except NckError:
                continue
