"""The OPC UA face of the emulator (asyncua): SINUMERIK node ids over the same model as the S7 face."""

from nckemu.emulator.faces.opcua.face import OpcUaFace
from nckemu.emulator.faces.opcua.settings import OpcUaSettings

__all__ = ["OpcUaFace", "OpcUaSettings"]
