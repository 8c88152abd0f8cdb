"""`nckemu serve --opcua PORT` on a port another program holds: one line naming it, exit 1, no traceback."""

from __future__ import annotations

import socket
import subprocess
import sys


def test_opcua_port_in_use_is_one_line() -> None:
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        done = subprocess.run([sys.executable, "-m", "nckemu", "serve", "--port", "0", "--opcua", str(port)],
                              capture_output=True, text=True, timeout=60)
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    assert f"OPC UA: 127.0.0.1:{port} is already in use" in done.stderr
