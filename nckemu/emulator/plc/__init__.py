"""The PLC side of the emulated NCU: memory for S7ANY clients, SZL, the 840C command channel."""

from .memory import PlcModel

__all__ = ["PlcModel"]
