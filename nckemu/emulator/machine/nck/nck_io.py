"""The NCK's own inputs and outputs and the data area it shares with the PLC, as part programs use them.

``$A_IN[n]``/``$A_OUT[n]`` are the NCK's digital inputs and outputs (n from 1), ``$A_INA[n]``/``$A_OUTA[n]``
its analog ones, and ``$A_DBB[i]``, ``$A_DBW[i]``, ``$A_DBD[i]``, ``$A_DBR[i]`` a byte, word, double
word and REAL at byte offset ``i`` of the PLC-NCK data area (the PLC writes it with FC21 on a control).
Nothing drives the inputs here: they read 0 until a test or a tool sets them, so a program that waits
for its PLC waits, as it would on a machine whose PLC never answers. Multi-byte values are big-endian,
as the PLC stores them (UNCONFIRMED for this area).
"""

from __future__ import annotations

import struct

DIGITAL_POINTS = 64
ANALOG_POINTS = 8
DATA_BYTES = 1024
_LAYOUT = {"$A_DBB": ">B", "$A_DBW": ">h", "$A_DBD": ">i", "$A_DBR": ">f"}
READABLE = frozenset({"$A_IN", "$A_OUT", "$A_INA", "$A_OUTA", *_LAYOUT})
WRITABLE = frozenset({"$A_OUT", "$A_OUTA", *_LAYOUT})


class NckIo:
    def __init__(self) -> None:
        self.digital_in = [False] * DIGITAL_POINTS
        self.digital_out = [False] * DIGITAL_POINTS
        self.analog_in = [0.0] * ANALOG_POINTS
        self.analog_out = [0.0] * ANALOG_POINTS
        self.data = bytearray(DATA_BYTES)

    def _points(self, name: str) -> list:
        return {"$A_IN": self.digital_in, "$A_OUT": self.digital_out, "$A_INA": self.analog_in,
                "$A_OUTA": self.analog_out}[name]

    def read(self, name: str, index: int) -> bool | int | float:
        """The value of ``name[index]``; raises IndexError outside the points or the area."""
        layout = _LAYOUT.get(name)
        if layout is None:
            points = self._points(name)
            if not 1 <= index <= len(points):
                raise IndexError(f"{name}[{index}]: points 1..{len(points)}")
            return points[index - 1]
        if not 0 <= index <= DATA_BYTES - struct.calcsize(layout):
            raise IndexError(f"{name}[{index}]: byte offsets 0..{DATA_BYTES - struct.calcsize(layout)}")
        return struct.unpack_from(layout, self.data, index)[0]

    def write(self, name: str, index: int, value: float) -> None:
        layout = _LAYOUT.get(name)
        if layout is None:
            points = self._points(name)
            if not 1 <= index <= len(points):
                raise IndexError(f"{name}[{index}]: points 1..{len(points)}")
            points[index - 1] = bool(value) if name == "$A_OUT" else float(value)
            return
        if not 0 <= index <= DATA_BYTES - struct.calcsize(layout):
            raise IndexError(f"{name}[{index}]: byte offsets 0..{DATA_BYTES - struct.calcsize(layout)}")
        if layout == ">f":
            struct.pack_into(layout, self.data, index, float(value))
        else:
            bits = 8 * struct.calcsize(layout)
            number = int(value) & ((1 << bits) - 1)
            if layout != ">B" and number >= 1 << (bits - 1):
                number -= 1 << bits
            struct.pack_into(layout, self.data, index, number)
