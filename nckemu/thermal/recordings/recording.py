"""Recordings: a table with ``t_s``, ``temp_<name>_C``, optional ``spindle_rpm`` and ``pos_<axis>_mm``,
``err_<axis>_um`` (empty where the gauge was not read) and optional ``sim_<axis>_um``, as CSV text or
as a Parquet file with the same columns and the same checks.

Field recordings are logged at irregular intervals and with gaps (the logger was off): the only rule
on time is that it increases. Many recordings of one machine are *runs* (``load_runs``): each carries a
unique name, its file name without the extension.
"""

from __future__ import annotations

import csv
import glob
import io
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nckemu.errors import NckConfigError

PARQUET_SUFFIXES = (".parquet", ".pq")
RECORDING_SUFFIXES = (".csv", *PARQUET_SUFFIXES)
_PARQUET_MAGIC = b"PAR1"
# A run is fitted and judged on its own samples: fewer than this many rows cannot be a run.
MIN_ROWS = 3
_COLUMN_HELP = "expected t_s, temp_<name>_C, spindle_rpm, pos_<axis>_mm, err_<axis>_um or sim_<axis>_um"


def default_run_name(source: str) -> str:
    """A file's name without its extension; a generated recording's ``<label>`` without the brackets."""
    if source.startswith("<") and source.endswith(">"):
        return source[1:-1]
    return Path(source).stem


@dataclass
class Recording:
    source: str
    t_s: np.ndarray
    temperatures_C: dict[str, np.ndarray] = field(default_factory=dict)
    spindle_rpm: np.ndarray | None = None
    positions_mm: dict[str, np.ndarray] = field(default_factory=dict)
    errors_um: dict[str, np.ndarray] = field(default_factory=dict)
    simulated_um: dict[str, np.ndarray] = field(default_factory=dict)
    # The run's name among the runs of a machine (last, with a default: positional callers keep working).
    name: str = ""

    def __post_init__(self) -> None:
        if not self.name:
            self.name = default_run_name(self.source)

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

    def slice(self, mask: np.ndarray, name: str | None = None) -> Recording:
        return Recording(self.source, self.t_s[mask], {k: v[mask] for k, v in self.temperatures_C.items()},
                         None if self.spindle_rpm is None else self.spindle_rpm[mask],
                         {k: v[mask] for k, v in self.positions_mm.items()},
                         {k: v[mask] for k, v in self.errors_um.items()},
                         {k: v[mask] for k, v in self.simulated_um.items()}, name or self.name)


def column_kind(name: str) -> tuple[str, str] | None:
    """(kind, key) of a project column name: ("t", ""), ("temp", "spindle"), ("err", "Z"), ...; None if it
    is not one."""
    if name == "t_s":
        return "t", ""
    if name == "spindle_rpm":
        return "rpm", ""
    for prefix, suffix, kind in (("temp_", "_C", "temp"), ("pos_", "_mm", "pos"), ("err_", "_um", "err"),
                                 ("sim_", "_um", "sim")):
        if name.startswith(prefix) and name.endswith(suffix) and len(name) > len(prefix) + len(suffix):
            return kind, name[len(prefix):-len(suffix)]
    return None


def _column_kinds(header: Sequence[str], source: str, line: int | None,
                  need_errors: bool = True) -> dict[str, tuple[str, str]]:
    """The kind of every column; the header must hold t_s and (unless ``need_errors`` is false) an err_
    column, each name once."""
    kinds: dict[str, tuple[str, str]] = {}
    for name in header:
        kind = column_kind(name)
        if kind is None:
            if "t_s" not in header:  # not the project's format at all: say what is there and the way in
                raise NckConfigError(foreign_header_message(header), path=source, line=line)
            raise NckConfigError(f"unknown column ({_COLUMN_HELP})", path=source, line=line, field=name)
        if name in kinds:
            raise NckConfigError("the column appears twice", path=source, line=line, field=name)
        kinds[name] = kind
    if "t_s" not in kinds:
        raise NckConfigError("no t_s column", path=source, line=line, field="t_s")
    if need_errors and not any(kind == "err" for kind, _ in kinds.values()):
        raise NckConfigError("no err_<axis>_um column", path=source, line=line)
    return kinds


def _assemble(source: str, kinds: dict[str, tuple[str, str]], columns: dict[str, np.ndarray],
              where: np.ndarray | None) -> Recording:
    """The checks every format shares, on whole columns (NaN is an empty cell, allowed only in err_ and
    sim_). ``where`` maps a data row to its line in the file (CSV); without it rows are counted from 1."""
    def place(row: int) -> dict[str, int | None]:
        return {"line": int(where[row])} if where is not None else {"line": None}

    def row_text(row: int) -> str:
        return "" if where is not None else f"row {row + 1}: "

    rows = len(columns["t_s"])
    if rows == 0:
        raise NckConfigError("no data rows (an empty run)", path=source)
    if rows < MIN_ROWS:
        raise NckConfigError(f"{rows} data row{'s' if rows > 1 else ''}; a run needs at least {MIN_ROWS}",
                             path=source)
    for name, (kind, _key) in kinds.items():
        values = columns[name]
        infinite = np.flatnonzero(np.isinf(values))
        if len(infinite):
            raise NckConfigError(f"{row_text(infinite[0])}not a finite number: {values[infinite[0]]}",
                                 path=source, field=name, **place(infinite[0]))
        if kind in ("t", "temp", "rpm", "pos"):
            empty = np.flatnonzero(np.isnan(values))
            if len(empty):
                raise NckConfigError(f"{row_text(empty[0])}empty cell (only err_ and sim_ cells may be empty)",
                                     path=source, field=name, **place(empty[0]))
    t = columns["t_s"]
    backwards = np.flatnonzero(np.diff(t) <= 0)
    if len(backwards):
        row = int(backwards[0]) + 1
        raise NckConfigError(f"{row_text(row)}time {t[row]:g} does not increase (previous {t[row - 1]:g})",
                             path=source, field="t_s", **place(row))
    recording = Recording(source, np.asarray(t, dtype=float))
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


def foreign_header_message(header: Sequence[str]) -> str:
    shown = ", ".join(repr(name) for name in header[:8]) + (f", ... ({len(header)} columns)" if len(header) > 8 else "")
    return (f"not the project's recording format (its columns: {shown}); a map file says how to read it: "
            "--map MAP.toml (docs/recordings.md), or `nckemu recording import FILE --map MAP.toml --out DIR`")


@dataclass(frozen=True)
class CsvDialect:
    separator: str              # ",", ";" or "\t"
    decimal: str | None         # "." or ","; None when no fraction was seen in the lines looked at


_SNIFF_LINES = 200
_SNIFF_CHARS = 1 << 16
_COMMA_DECIMAL = re.compile(r"^[+-]?\d*,\d+(?:[eE][+-]?\d+)?$")
_POINT_DECIMAL = re.compile(r"^[+-]?\d*\.\d+(?:[eE][+-]?\d+)?$")


def sniff_csv(text: str) -> CsvDialect:
    """The separator (``,`` ``;`` or tab) and decimal mark (``.`` or ``,``) of CSV text, from its first
    lines: the separator that splits the header into most fields and the data lines as the header is
    split; the decimal mark that the number cells show (``,`` only where no ``.`` fraction appears)."""
    head = text[:_SNIFF_CHARS]
    if len(text) > _SNIFF_CHARS and "\n" in head:  # a line cut at the end would count its fields wrong
        head = head[:head.rindex("\n")]
    lines = [line for line in head.splitlines()[:_SNIFF_LINES] if line.strip()]
    if not lines:
        return CsvDialect(",", ".")
    best: tuple[tuple[bool, int, int], str] | None = None
    for separator in (",", ";", "\t"):
        try:
            rows = list(csv.reader(lines, delimiter=separator))
        except csv.Error:
            continue
        fields = len(rows[0])
        same = sum(1 for row in rows[1:] if len(row) == fields)
        score = (fields > 1, same, fields)
        if best is None or score > best[0]:
            best = (score, separator)
    separator = best[1] if best is not None else ","
    comma = point = 0
    for row in csv.reader(lines[1:], delimiter=separator):
        for cell in row:
            cell = cell.strip()
            if _COMMA_DECIMAL.match(cell):
                comma += 1
            elif _POINT_DECIMAL.match(cell):
                point += 1
    # the mark most number cells show: one cell written the other way must not flip the file (it is the
    # one a reader then names, decimal_mark_breaks)
    decimal = "," if comma > point else "." if point else None
    return CsvDialect(separator, decimal)


def decimal_mark_breaks(text: str, decimal: str | None) -> str | None:
    """The decimal mark a number cell writes where the file's sniffed mark is the other one (``.`` in
    a ``,`` file or the reverse); None when the cell keeps the convention or shows no fraction."""
    if decimal == "," and _POINT_DECIMAL.match(text):
        return "."
    if decimal == "." and _COMMA_DECIMAL.match(text):
        return ","
    return None


def decimal_mark_refusal(text: str, decimal: str | None) -> str | None:
    """Why a number cell breaks the file's decimal mark (``decimal_mark_breaks``), in words; None when it
    does not. The caller names the file, line and field."""
    mark = decimal_mark_breaks(text, decimal)
    if mark is None:
        return None
    return (f"{text[:40]!r} writes {mark!r} as the decimal mark, where the file's numbers write {decimal!r} "
            "(the first cell that breaks the file's convention)")


def parse_number(text: str, decimal: str | None) -> float | None:
    """A number cell's value (``decimal``: the file's mark, None when unknown); None when it is not a
    number. A ``,`` mark with a ``.`` in the same cell (a thousands separator) is not read."""
    if decimal != "." and "," in text:
        if "." in text or text.count(",") > 1:
            return None
        text = text.replace(",", ".")
    try:
        return float(text)
    except ValueError:
        return None


def _parse_csv(data: bytes, source: str, need_errors: bool = True) -> Recording:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise NckConfigError("not a text file (a recording is CSV text in UTF-8 or Parquet)", path=source) from None
    if "\x00" in text:
        raise NckConfigError("not a text file (it holds NUL bytes; a recording is CSV text or Parquet)", path=source)
    dialect = sniff_csv(text)
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=dialect.separator)
    try:
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise NckConfigError("empty file, expected a header line", path=source, line=1) from None
        kinds = _column_kinds(header, source, 1, need_errors)
        cells: list[list[float]] = [[] for _ in header]
        lines: list[int] = []
        nullable = [kinds[name][0] in ("err", "sim") for name in header]
        comma_decimal = dialect.separator != "," and dialect.decimal != "."
        for row in reader:
            line_number = reader.line_num
            if not row or all(not cell.strip() for cell in row):
                continue
            if len(row) != len(header):
                raise NckConfigError(f"{len(row)} cells, the header has {len(header)}", path=source,
                                     line=line_number)
            for index, cell in enumerate(row):
                value_text = cell.strip()
                if not value_text:
                    if not nullable[index]:
                        raise NckConfigError("empty cell (only err_ and sim_ cells may be empty)", path=source,
                                             line=line_number, field=header[index])
                    cells[index].append(math.nan)
                    continue
                if (refusal := decimal_mark_refusal(value_text, dialect.decimal)) is not None:
                    raise NckConfigError(refusal, path=source, line=line_number, field=header[index])
                if comma_decimal and "," in value_text:
                    value = parse_number(value_text, ",")
                else:
                    try:
                        value = float(value_text)
                    except ValueError:
                        value = None
                if value is None:
                    raise NckConfigError(f"not a number: {value_text[:40]!r}", path=source, line=line_number,
                                         field=header[index])
                if not math.isfinite(value):  # "nan" or "inf" written out is not a reading
                    raise NckConfigError(f"not a finite number: {value_text[:40]!r}", path=source,
                                         line=line_number, field=header[index])
                cells[index].append(value)
            lines.append(line_number)
    except csv.Error as exc:
        raise NckConfigError(f"not CSV: {exc}", path=source, line=reader.line_num) from None
    columns = {name: np.asarray(values, dtype=float) for name, values in zip(header, cells, strict=True)}
    return _assemble(source, kinds, columns, np.asarray(lines))


def _parquet_column(column: object, name: str, source: str) -> np.ndarray:
    """One Parquet column as float64 with NaN where it is null; numbers (and time stamps for t_s) only."""
    import pyarrow as pa

    assert isinstance(column, pa.ChunkedArray)
    kind = column.type
    if name == "t_s" and pa.types.is_timestamp(kind):
        seconds = column.cast(pa.timestamp("ns")).cast(pa.int64()).to_numpy(zero_copy_only=False)
        values = np.asarray(seconds, dtype=float) / 1e9
    elif pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_decimal(kind):
        values = column.cast(pa.float64()).to_numpy(zero_copy_only=False)
    elif pa.types.is_null(kind):
        values = np.full(len(column), math.nan)
    else:
        raise NckConfigError(f"not numbers (Parquet type {kind})", path=source, field=name)
    values = np.array(values, dtype=float)  # writable, NaN where the column is null
    if column.null_count:
        values[np.asarray(column.is_null().to_numpy(zero_copy_only=False), dtype=bool)] = math.nan
    return values


def _parse_parquet(data: bytes, source: str, need_errors: bool = True) -> Recording:
    import pyarrow as pa
    import pyarrow.parquet as pq

    # A damaged file fails in pyarrow in many ways (bad magic, metadata, pages, names that are not UTF-8).
    damaged = (pa.ArrowException, OSError, ValueError, TypeError, IndexError, KeyError, OverflowError, MemoryError)

    def refusal(exc: BaseException) -> NckConfigError:
        reason = str(exc).splitlines()[0][:160] if str(exc).strip() else type(exc).__name__
        return NckConfigError(f"not a readable Parquet file ({reason})", path=source)

    try:
        table = pq.read_table(pa.BufferReader(data))
        header = [str(name) for name in table.column_names]
    except damaged as exc:
        raise refusal(exc) from None
    kinds = _column_kinds(header, source, None, need_errors)
    try:
        columns = {name: _parquet_column(table.column(index), name, source) for index, name in enumerate(header)}
    except NckConfigError:
        raise
    except damaged as exc:
        raise refusal(exc) from None
    return _assemble(source, kinds, columns, None)


def is_parquet(path: str | Path) -> bool:
    """By the file name: ``.parquet`` or ``.pq`` among its suffixes (``x.parquet.partial`` counts)."""
    return any(suffix.lower() in PARQUET_SUFFIXES for suffix in Path(path).suffixes)


def load_recording(path: str | Path, *, need_errors: bool = True) -> Recording:
    """Read and check a recording (CSV, or Parquet by its name or its magic bytes); every refusal names
    the file, and the line (CSV) or row (Parquet) and the column. ``need_errors=False`` accepts a
    recording without ``err_`` columns (inputs to play back: sensors, positions, spindle speed). A
    foreign file is read through a map: ``recording_map.load_recording``."""
    path = Path(path)
    source = str(path)
    try:
        data = path.read_bytes()
    except IsADirectoryError:
        raise NckConfigError("a directory, not a recording", path=source) from None
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=source) from None
    if is_parquet(path) or data[:4] == _PARQUET_MAGIC:
        return _parse_parquet(data, source, need_errors)
    if data[:4] == b"PK\x03\x04":  # a zip: an .xlsx workbook, most likely
        raise NckConfigError("a workbook (or another zip file), not a recording: read a workbook through a map, "
                             "--map MAP.toml (docs/recordings.md)", path=source)
    return _parse_csv(data, source, need_errors)


def _columns(recording: Recording) -> dict[str, np.ndarray]:
    columns: dict[str, np.ndarray] = {"t_s": recording.t_s}
    columns.update(recording.temperatures_C)
    if recording.spindle_rpm is not None:
        columns["spindle_rpm"] = recording.spindle_rpm
    columns.update({f"pos_{k}_mm": v for k, v in recording.positions_mm.items()})
    columns.update({f"err_{k}_um": v for k, v in recording.errors_um.items()})
    columns.update({f"sim_{k}_um": v for k, v in recording.simulated_um.items()})
    return columns


def write_recording(path: str | Path, recording: Recording) -> None:
    """Write ``recording`` as Parquet when the name says so (``.parquet``/``.pq``), else as CSV. Values are
    written exactly (the shortest text that reads back as the same float), empty cells (nulls) where a
    value is NaN: reading the file back gives the same recording."""
    columns = _columns(recording)
    if is_parquet(path):
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.table({name: pa.array(np.asarray(values, dtype=float), from_pandas=True)
                          for name, values in columns.items()})
        pq.write_table(table, str(path))
        return
    texts = [[("" if v != v else repr(v)) for v in np.asarray(values, dtype=float).tolist()]
             for values in columns.values()]
    with Path(path).open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        writer.writerows(zip(*texts, strict=True))



# ---------------------------------------------------------------------------------------- many runs
def _has_magic(spec: str) -> bool:
    return any(char in spec for char in "*?[")


def find_recordings(specs: Sequence[str | Path], suffixes: Sequence[str] = RECORDING_SUFFIXES) -> list[Path]:
    """Files named by ``specs``: a file as given, a directory's ``*.csv``/``*.parquet``/``*.pq`` files and a
    glob's matches (recordings only; ``suffixes`` says which), in name order within each spec."""
    if not specs:
        raise NckConfigError("no recordings given")
    found: list[Path] = []
    for spec in specs:
        path = Path(spec)
        if path.is_dir():
            files = sorted(f for f in path.iterdir() if f.is_file() and f.suffix.lower() in suffixes)
            if not files:
                raise NckConfigError(f"no recordings ({', '.join('*' + s for s in suffixes)}) in this "
                                     "directory", path=str(spec))
            found += files
        elif path.exists():
            found.append(path)
        elif _has_magic(str(spec)):
            files = sorted(Path(m) for m in glob.glob(str(spec), recursive=True)
                           if Path(m).is_file() and Path(m).suffix.lower() in suffixes)
            if not files:
                raise NckConfigError("no recordings match this pattern", path=str(spec))
            found += files
        else:
            raise NckConfigError("no such file or directory", path=str(spec))
    return found


def load_runs(specs: Sequence[str | Path], axis: str | None = None) -> list[Recording]:
    """The runs of one machine: files, directories and globs (``find_recordings``), each run named by its
    file name without the extension. Refused, each with one line naming the file: two runs of one name,
    a run that does not load (``load_recording``), runs with different ``err_`` columns (or, with
    ``axis``, a run without ``err_<axis>_um`` or with fewer than 2 readings of it). Foreign files are
    read through a map: ``recording_map.load_runs``."""
    paths = find_recordings(specs)
    seen: dict[str, Path] = {}
    for path in paths:
        name = default_run_name(str(path))
        if name in seen:
            same = seen[name].resolve() == path.resolve()
            raise NckConfigError(f"the run {name!r} is given twice" if same else
                                 f"a second run named {name!r} (the first is {seen[name]}); runs are named by "
                                 "their file names, which must differ", path=str(path))
        seen[name] = path
    return check_runs([load_recording(path) for path in paths], axis)


def check_runs(runs: list[Recording], axis: str | None) -> list[Recording]:
    """Runs of one machine record the same axes (or, with ``axis``, each has 2 readings of it)."""
    first = runs[0]
    for run in runs:
        if axis is not None:
            key = f"err_{axis}_um"
            if axis not in run.errors_um:
                raise NckConfigError(f"no {key} column (the runs' axis is {axis})", path=run.source, field=key)
            readings = int(np.count_nonzero(~np.isnan(run.errors_um[axis])))
            if readings < 2:
                raise NckConfigError(f"{readings} gauge reading{'' if readings == 1 else 's'} in {key}; a run "
                                     "needs at least 2", path=run.source, field=key)
        elif set(run.errors_um) != set(first.errors_um):
            raise NckConfigError(f"its axes ({_err_list(run)}) differ from those of {first.source} "
                                 f"({_err_list(first)}); runs of one machine record the same axes, or choose "
                                 "one axis", path=run.source)
    return runs


def _err_list(recording: Recording) -> str:
    return ", ".join(f"err_{axis}_um" for axis in recording.axes()) or "none"


# ------------------------------------------------------------------------------- one recording, runs
def _speed_label(rpm: np.ndarray, idle_rpm: float) -> str:
    running = np.unique(np.round(rpm[rpm > idle_rpm]).astype(np.int64))
    if len(running) == 0:
        return "0rpm"
    if len(running) == 1:
        return f"{running[0]}rpm"
    return f"{running[0]}-{running[-1]}rpm"


def split_runs(recording: Recording, *, speed_blocks: bool | None = None, max_gap_s: float | None = 3600.0,
               idle_rpm: float = 0.0, min_rows: int = MIN_ROWS) -> list[Recording]:
    """Cut one long recording into runs.

    - At speed blocks (``speed_blocks``; by default when the recording has ``spindle_rpm``): a block
      starts where the spindle starts after standing (speed above ``idle_rpm`` after a row at or below
      it) and holds the running part and the standstill after it, a heating and a cooling phase. The
      rows before the first start belong to the first block. Named ``<name>_block<NN>_<speed>rpm``
      (``<low>-<high>rpm`` when the block ran at several speeds).
    - At gaps in time longer than ``max_gap_s`` (the logger was off: the thermal state across the gap
      is unknown, so a lag filter must start afresh). A cut block is named ``..._part<N>``; a recording
      cut only at gaps ``<name>_part<N>``.

    Pieces with fewer than ``min_rows`` rows cannot be runs and are left out. Nothing to cut: the
    recording itself, as the one run."""
    t = recording.t_s
    rpm = recording.spindle_rpm
    if speed_blocks is None:
        speed_blocks = rpm is not None
    if speed_blocks and rpm is None:
        raise NckConfigError("cannot cut at speed blocks: no spindle_rpm column", path=recording.source,
                             field="spindle_rpm")
    if max_gap_s is not None and not max_gap_s > 0:
        raise ValueError(f"max_gap_s must be positive, not {max_gap_s}")
    rows = len(t)
    block_starts = [0]
    if speed_blocks and rpm is not None and rows:
        running = rpm > idle_rpm
        starts = np.flatnonzero(running[1:] & ~running[:-1]) + 1
        first_run = np.flatnonzero(running)
        block_starts += [int(s) for s in starts if not len(first_run) or s > first_run[0]]
    gap_cuts = set() if max_gap_s is None else {int(i) + 1 for i in np.flatnonzero(np.diff(t) > max_gap_s)}
    if len(block_starts) == 1 and not gap_cuts:
        return [recording]
    bounds = block_starts + [rows]
    runs: list[Recording] = []
    for number, (start, end) in enumerate(zip(bounds[:-1], bounds[1:], strict=True), start=1):
        label = recording.name
        if speed_blocks and rpm is not None:
            label += f"_block{number:02d}_{_speed_label(rpm[start:end], idle_rpm)}"
        cuts = [start, *sorted(c for c in gap_cuts if start < c < end), end]
        pieces = list(zip(cuts[:-1], cuts[1:], strict=True))
        for part, (a, b) in enumerate(pieces, start=1):
            if b - a < min_rows:
                continue
            mask = np.zeros(rows, dtype=bool)
            mask[a:b] = True
            runs.append(recording.slice(mask, f"{label}_part{part}" if len(pieces) > 1 else label))
    return runs
