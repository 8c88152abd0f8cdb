"""tshark as an independent decoder: run it on a capture file and read fields back."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

TSHARK = shutil.which("tshark")
requires_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (make test installs "
                                     "Debian's tshark when run as root)")


def tshark_fields(path: Path, fields: list[str], *, port: int = 102, display_filter: str = "s7comm"
                  ) -> list[dict[str, str]]:
    """One dict per packet that passes the filter; multi-item values stay comma-joined as tshark prints."""
    assert TSHARK is not None
    command = [TSHARK, "-r", str(path), "-Y", display_filter, "-T", "fields", "-E", "separator=\t",
               "-E", "occurrence=a", "-E", "aggregator=,"]
    if port != 102:
        command += ["-d", f"tcp.port=={port},tpkt"]
    for field in fields:
        command += ["-e", field]
    # Times (S7 timestamps) printed in UTC whatever the machine's zone: they are compared as written.
    result = subprocess.run(command, capture_output=True, text=True, timeout=120, check=True,
                            env={**os.environ, "TZ": "UTC"})
    return [dict(zip(fields, line.split("\t"), strict=False)) for line in result.stdout.splitlines() if line]
