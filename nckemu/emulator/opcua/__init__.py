"""The OPC UA face of the emulator (asyncua): SINUMERIK node ids over the same model as the S7 face."""

from .face import OpcUaFace
from .settings import OpcUaSettings

__all__ = ["OpcUaFace", "OpcUaSettings"]
