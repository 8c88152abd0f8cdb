"""Recordings: a CSV with ``t_s``, ``temp_<name>_C``, optional ``spindle_rpm`` and ``pos_<axis>_mm``,
``err_<axis>_um`` (empty where the gauge was not read) and optional ``sim_<axis>_um``."""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nckemu.errors import NckConfigError


@dataclass
class Recording:
    source: str
    t_s: np.ndarray
    temperatures_C: dict[str, np.ndarray] = field(default_factory=dict)
    spindle_rpm: np.ndarray | None = None
    positions_mm: dict[str, np.ndarray] = field(default_factory=dict)
    errors_um: dict[str, np.ndarray] = field(default_factory=dict)
    simulated_um: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if len(self.t_s) > 1 else 0.0

    def sensor(self, name: str) -> np.ndarray:
        key = name if name.startswith("temp_") else f"temp_{name}_C"
        if key not in self.temperatures_C:
            raise NckConfigError(f"the recording has no column {key!r}", path=self.source, field=key)
        return self.temperatures_C[key]

    def axes(self) -> list[str]:
        return sorted(self.errors_um)

    def slice(self, mask: np.ndarray) -> Recording:
        return Recording(self.source, self.t_s[mask], {k: v[mask] for k, v in self.temperatures_C.items()},
                         None if self.spindle_rpm is None else self.spindle_rpm[mask],
                         {k: v[mask] for k, v in self.positions_mm.items()},
                         {k: v[mask] for k, v in self.errors_um.items()},
                         {k: v[mask] for k, v in self.simulated_um.items()})


def _column_kind(name: str) -> tuple[str, str] | None:
    if name == "t_s":
        return "t", ""
    if name == "spindle_rpm":
        return "rpm", ""
    for prefix, suffix, kind in (("temp_", "_C", "temp"), ("pos_", "_mm", "pos"), ("err_", "_um", "err"),
                                 ("sim_", "_um", "sim")):
        if name.startswith(prefix) and name.endswith(suffix) and len(name) > len(prefix) + len(suffix):
            return kind, name[len(prefix):-len(suffix)]
    return None


def load_recording(path: str | Path) -> Recording:
    """Read and check a recording; every refusal names the file, line and column."""
    path = Path(path)
    source = str(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=source) from None
    except UnicodeDecodeError:
        raise NckConfigError("not a text file (a recording is CSV text in UTF-8)", path=source) from None
    if "\x00" in text:
        raise NckConfigError("not a text file (it holds NUL bytes; a recording is CSV text)", path=source)
    handle = io.StringIO(text, newline="")
    with handle:
        reader = csv.reader(handle)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise NckConfigError("empty file, expected a header line", path=source, line=1) from None
        if "t_s" not in header:
            raise NckConfigError("no t_s column", path=source, line=1, field="t_s")
        kinds = {}
        for name in header:
            kind = _column_kind(name)
            if kind is None:
                raise NckConfigError("unknown column (expected t_s, temp_<name>_C, spindle_rpm, pos_<axis>_mm, "
                                     "err_<axis>_um or sim_<axis>_um)", path=source, line=1, field=name)
            kinds[name] = kind
        if not any(kind == "err" for kind, _ in kinds.values()):
            raise NckConfigError("no err_<axis>_um column", path=source, line=1)
        columns: dict[str, list[float]] = {name: [] for name in header}
        previous_t = -math.inf
        for line_number, row in enumerate(reader, start=2):
            if not row or all(not cell.strip() for cell in row):
                continue
            if len(row) != len(header):
                raise NckConfigError(f"{len(row)} cells, the header has {len(header)}", path=source,
                                     line=line_number)
            for name, cell in zip(header, row, strict=True):
                text = cell.strip()
                if not text:
                    if kinds[name][0] in ("t", "temp", "rpm", "pos"):
                        raise NckConfigError("empty cell (only err_ and sim_ cells may be empty)", path=source,
                                             line=line_number, field=name)
                    columns[name].append(math.nan)
                    continue
                try:
                    value = float(text)
                except ValueError:
                    raise NckConfigError(f"not a number: {text!r}", path=source, line=line_number,
                                         field=name) from None
                if not math.isfinite(value):
                    raise NckConfigError(f"not a finite number: {text!r}", path=source, line=line_number,
                                         field=name)
                columns[name].append(value)
            t = columns["t_s"][-1]
            if t <= previous_t:
                raise NckConfigError(f"time {t} does not increase (previous {previous_t})", path=source,
                                     line=line_number, field="t_s")
            previous_t = t
    if len(columns["t_s"]) < 3:
        raise NckConfigError("fewer than 3 data lines", path=source)
    recording = Recording(source, np.asarray(columns["t_s"]))
    for name, (kind, key) in kinds.items():
        values = np.asarray(columns[name], dtype=float)
        if kind == "temp":
            recording.temperatures_C[name] = values
        elif kind == "rpm":
            recording.spindle_rpm = values
        elif kind == "pos":
            recording.positions_mm[key] = values
        elif kind == "err":
            recording.errors_um[key] = values
        elif kind == "sim":
            recording.simulated_um[key] = values
    return recording


def write_recording(path: str | Path, recording: Recording) -> None:
    columns: dict[str, np.ndarray] = {"t_s": recording.t_s}
    columns.update(recording.temperatures_C)
    if recording.spindle_rpm is not None:
        columns["spindle_rpm"] = recording.spindle_rpm
    columns.update({f"pos_{k}_mm": v for k, v in recording.positions_mm.items()})
    columns.update({f"err_{k}_um": v for k, v in recording.errors_um.items()})
    columns.update({f"sim_{k}_um": v for k, v in recording.simulated_um.items()})
    with Path(path).open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        for row in zip(*columns.values(), strict=True):
            writer.writerow(["" if isinstance(v, float) and math.isnan(v) else f"{v:.6g}" for v in row])
