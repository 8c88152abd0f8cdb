"""nckemu: a SINUMERIK NCK/PLC stand-in on the wire (S7comm over ISO-on-TCP)."""

from __future__ import annotations

from functools import cache


@cache
def _installed_version() -> str:
    # importlib.metadata costs a tenth of a second at start; only --version and the OPC UA face's build
    # information read it, so it is looked up when first asked for
    from importlib.metadata import PackageNotFoundError, version

    try:
        # pyproject.toml's version, as installed: `nckemu --version` and the package agree by construction
        return version("nckemu")
    except PackageNotFoundError:  # a source tree that was never installed
        return "0+unknown"


def __getattr__(name: str) -> str:
    if name == "__version__":
        return _installed_version()
    raise AttributeError(f"module 'nckemu' has no attribute {name!r}")
