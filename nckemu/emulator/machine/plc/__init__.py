"""The PLC side of the emulated NCU: memory for S7ANY clients, SZL, the 840C command channel."""

from nckemu.emulator.machine.plc.memory import PlcModel

__all__ = ["PlcModel"]
