"""Reading the project's text inputs (machine, fleet and model TOML, NC programs) with one refusal each."""

from __future__ import annotations

from pathlib import Path

from nckemu.errors import NckConfigError


def read_text(path: str | Path, kind: str) -> str:
    """The UTF-8 text of ``path``; a file that cannot be read, or is not text, is an NckConfigError
    naming the file (``kind`` says what the file should be, e.g. "a machine is TOML text")."""
    try:
        return Path(path).read_text("utf-8")
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=str(path)) from None
    except UnicodeDecodeError:
        raise NckConfigError(f"not a text file ({kind} in UTF-8)", path=str(path)) from None
