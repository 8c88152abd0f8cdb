"""The NCK's own inputs and outputs and the data area it shares with the PLC, as part programs use them.

``$A_IN[n]``/``$A_OUT[n]`` are the NCK's digital inputs and outputs (n from 1), ``$A_INA[n]``/``$A_OUTA[n]``
its analog ones, and ``$A_DBB[i]``, ``$A_DBW[i]``, ``$A_DBD[i]``, ``$A_DBR[i]`` a byte, word, double
word and REAL at byte offset ``i`` of the PLC-NCK data area (the PLC writes it with FC21 on a control).
Multi-byte values are big-endian, as the PLC stores them (UNCONFIRMED for this area).

What drives the inputs is the machine's PLC. The machine file's ``[nck_io]`` says what it does
(io_points.py): points that read so from power on, and answers, each set a time after its trigger (the
channel outputs an M function, or a program sets ``$A_OUT[n]``). Without them the inputs read 0 until
a test or a tool sets them, so a program that waits for its PLC waits, as on a machine whose PLC never
answers. Answers fall due on the time of the program run that triggered them: :meth:`NckIo.settle`
applies those due before a program reads a point.
"""

from __future__ import annotations

import bisect
import struct

from nckemu.emulator.machine.io_points import (
    ANALOG_POINTS,
    DATA_BYTES,
    DATA_LAYOUT,
    DIGITAL_POINTS,
    NckIoSettings,
    PlcAnswer,
    point_range,
)

READABLE = frozenset({"$A_IN", "$A_OUT", "$A_INA", "$A_OUTA", *DATA_LAYOUT})
WRITABLE = frozenset({"$A_OUT", "$A_OUTA", *DATA_LAYOUT})


def _check_index(name: str, index: int) -> None:
    """IndexError unless ``name[index]`` is a point or a byte offset the NCK has (io_points.point_range)."""
    low, high = point_range(name)
    if not low <= index <= high:
        what = "byte offsets" if name in DATA_LAYOUT else "points"
        raise IndexError(f"{name}[{index}]: {what} {low}..{high}")


class NckIo:
    def __init__(self, settings: NckIoSettings | None = None) -> None:
        self.digital_in = [False] * DIGITAL_POINTS
        self.digital_out = [False] * DIGITAL_POINTS
        self.analog_in = [0.0] * ANALOG_POINTS
        self.analog_out = [0.0] * ANALOG_POINTS
        self.data = bytearray(DATA_BYTES)
        settings = settings or NckIoSettings()
        self._on_m: dict[int, list[PlcAnswer]] = {}
        self._on_out: dict[tuple[int, float], list[PlcAnswer]] = {}
        for answer in settings.answers:
            if answer.m is not None:
                self._on_m.setdefault(answer.m, []).append(answer)
            else:
                self._on_out.setdefault((answer.out, answer.value), []).append(answer)  # type: ignore[arg-type]
        # what the PLC will set, by the time it falls due: (due_s, order, name, index, value)
        self._pending: list[tuple[float, int, str, int, float]] = []
        self._order = 0
        for name, index, value in settings.initial:
            self.write(name, index, value)

    @property
    def answers_anything(self) -> bool:
        return bool(self._on_m or self._on_out)

    def _points(self, name: str) -> list:
        return {"$A_IN": self.digital_in, "$A_OUT": self.digital_out, "$A_INA": self.analog_in,
                "$A_OUTA": self.analog_out}[name]

    def read(self, name: str, index: int) -> bool | int | float:
        """The value of ``name[index]``; raises IndexError outside the points or the area."""
        layout = DATA_LAYOUT.get(name)
        if layout is None:
            points = self._points(name)
            _check_index(name, index)
            return points[index - 1]
        _check_index(name, index)
        return struct.unpack_from(layout, self.data, index)[0]

    def write(self, name: str, index: int, value: float, now_s: float | None = None) -> None:
        """Set ``name[index]``; a program's ``$A_OUT[n]`` at ``now_s`` triggers the PLC's answers to it."""
        layout = DATA_LAYOUT.get(name)
        if layout is None:
            points = self._points(name)
            _check_index(name, index)
            points[index - 1] = bool(value) if name in ("$A_OUT", "$A_IN") else float(value)
            if name == "$A_OUT" and now_s is not None:
                for answer in self._on_out.get((index, float(bool(value))), ()):
                    self._schedule(answer, now_s)
            return
        _check_index(name, index)
        if layout == ">f":
            struct.pack_into(layout, self.data, index, float(value))
        else:
            bits = 8 * struct.calcsize(layout)
            number = int(value) & ((1 << bits) - 1)
            if layout != ">B" and number >= 1 << (bits - 1):
                number -= 1 << bits
            struct.pack_into(layout, self.data, index, number)

    # --- the PLC's answers ----------------------------------------------------------------------
    def m_function(self, code: int, now_s: float) -> None:
        """The channel outputs M``code`` at ``now_s``: the PLC's answers to it fall due."""
        for answer in self._on_m.get(code, ()):
            self._schedule(answer, now_s)

    def _schedule(self, answer: PlcAnswer, now_s: float) -> None:
        for name, index, value in answer.sets:
            self._order += 1
            bisect.insort(self._pending, (now_s + answer.after_s, self._order, name, index, value))

    def settle(self, now_s: float) -> None:
        """Apply the answers due by ``now_s``, in the order they fall due."""
        pending = self._pending
        while pending and pending[0][0] <= now_s + 1e-9:
            _, _, name, index, value = pending.pop(0)
            self.write(name, index, value)
