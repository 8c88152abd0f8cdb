"""nckemu: a SINUMERIK NCK/PLC stand-in on the wire (S7comm over ISO-on-TCP)."""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    # pyproject.toml's version, as installed: `nckemu --version` and the package agree by construction
    __version__ = _version("nckemu")
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"
