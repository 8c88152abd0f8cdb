"""What every ``nckemu`` command shares: the --json convention, ports, output paths, progress.

The --json convention (one for all commands): ``--json`` prints the machine-readable result to
stdout instead of the text; ``--json-out FILE`` writes it to FILE (``-`` is stdout), for commands
whose text output is worth keeping beside it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from nckemu.errors import NckConfigError

T = TypeVar("T")

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 102


def port_number(text: str) -> int:
    """argparse type: a TCP port 1..65535 (a wrapped 99999 would serve on 34463)."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number (1..65535)") from None
    if not 1 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{port} is outside 1..65535")
    return port


def listen_port(text: str) -> int:
    """argparse type for ``serve --port``: 1..65535, or 0 for any free port."""
    return 0 if text.strip() == "0" else port_number(text)


def default_host() -> str:
    """NCKEMU_HOST, else 127.0.0.1."""
    return os.environ.get("NCKEMU_HOST", "").strip() or DEFAULT_HOST


def default_port() -> int:
    """NCKEMU_PORT, else 102; a bad value is refused in one line by main()."""
    text = os.environ.get("NCKEMU_PORT", "").strip()
    if not text:
        return DEFAULT_PORT
    try:
        return port_number(text)
    except argparse.ArgumentTypeError as exc:
        raise NckConfigError(f"NCKEMU_PORT={text}: {exc}") from None


def check_output(path: str | None, what: str) -> None:
    """Refuse an output path that cannot be written *before* the work is done (nothing half-written)."""
    if path is None or path == "-":
        return
    target = Path(path)
    if target.is_dir():
        raise NckConfigError(f"{what} {path}: is a directory, expected a file name")
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise NckConfigError(f"{what} {path}: the directory {parent} does not exist")
    if not os.access(parent, os.W_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise NckConfigError(f"{what} {path}: not writable (permission denied)")


def add_json_options(parser: argparse.ArgumentParser, *, out: bool = False) -> None:
    parser.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    if out:
        parser.add_argument("--json-out", metavar="FILE",
                            help="also write the result as JSON to FILE (- for stdout)")


def write_json(document: Any, path: str | None) -> None:
    """``--json-out FILE``: FILE, or stdout for ``-``."""
    if path is None:
        return
    text = json.dumps(document, indent=2) + "\n"
    if path == "-":
        sys.stdout.write(text)
        return
    write_atomically(path, lambda temporary: temporary.write_text(text, encoding="utf-8"))


def write_atomically(path: str | Path, write: Callable[[Path], object]) -> None:
    """A file written whole or not at all: ``write`` fills a temporary file beside ``path``, which
    replaces ``path`` once it is complete (a failure or an interruption leaves the old file, or none)."""
    target = Path(path)
    if str(target) in ("-", "/dev/stdout") or (target.exists() and not target.is_file()):
        write(target)  # a stream or a device: nothing to rename
        return
    temporary = target.with_name(f".{target.name}.partial")
    try:
        write(temporary)
        temporary.replace(target)
    except OSError as exc:
        raise NckConfigError(f"cannot write: {exc.strerror}", path=str(path)) from None
    finally:
        temporary.unlink(missing_ok=True)


def progress(items: Iterable[T], *, total: int | None = None, description: str = "",
             enabled: bool = True, unit: str = "it") -> Iterator[T]:
    """A tqdm bar on a terminal (stderr), nothing when piped or not ``enabled``."""
    from tqdm import tqdm

    yield from tqdm(items, total=total, desc=description, unit=unit, disable=None if enabled else True,
                    leave=False, file=sys.stderr)


def progress_bar(total: float | None, *, description: str = "", enabled: bool = True, unit: str = "it") -> Any:
    """A tqdm bar to ``update()`` by hand (same rules as ``progress``)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=description, unit=unit, disable=None if enabled else True, leave=False,
                file=sys.stderr)


class working:  # noqa: N801 (used as `with working("discover"):`, like a function)
    """An elapsed-time bar on a terminal while work without its own progress runs (quiet when piped)."""

    def __init__(self, description: str, *, enabled: bool = True) -> None:
        self.description = description
        self.enabled = enabled
        self._stop: Any = None
        self._thread: Any = None

    def __enter__(self) -> working:
        if not self.enabled or not sys.stderr.isatty():
            return self
        import threading

        bar = progress_bar(None, description=self.description, unit="s")
        self._stop = threading.Event()

        def tick() -> None:
            while not self._stop.wait(1.0):
                bar.update(1)
            bar.close()

        self._thread = threading.Thread(target=tick, name="nckemu-progress", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()


async def until_signalled() -> None:
    """Wait on the running loop until SIGINT or SIGTERM (a server's Ctrl-C or kill), then return."""
    import asyncio
    import signal

    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            loop.add_signal_handler(sig, stop.set)
        except (NotImplementedError, RuntimeError):
            pass
    await stop.wait()


def command_group(subparsers: argparse._SubParsersAction, name: str, help_text: str) -> argparse._SubParsersAction:
    """The subcommands of the group ``name`` (``nckemu program ...``), made by whichever area's
    ``register`` asks first, so that several areas can add commands to one group."""
    group = subparsers.choices.get(name)
    if group is None:
        group = subparsers.add_parser(name, help=help_text, description=help_text)
        group.set_defaults(func=lambda _args, _group=group: (_group.print_help(), 1)[1])
    for action in group._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action
    return group.add_subparsers(dest=f"{name}_command", metavar="COMMAND")
