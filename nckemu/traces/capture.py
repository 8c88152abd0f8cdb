"""Moved to ``nckemu.capture`` (0.2), below the server and the trace tools that both write captures;
kept so that imports of the old path keep working."""

from nckemu.capture import S7_PORT, CaptureWriter, write_capture  # noqa: F401
