"""Recordings as they come: a map file (TOML) says how a foreign table becomes recordings.

A source is a workbook (.xlsx: each sheet a table), a CSV file (separator and decimal mark sniffed) or a
Parquet file. The map names the time column and its unit, the project's name of every column it keeps
(``err_x_um = "X disp"``, or ``{ column = "X disp", unit = "mm" }`` to convert) and how the source is cut
into runs (``[runs] sheets = "*"``: every sheet that has the time column, named after the sheet; or
``[runs] column = "Run"``: rows grouped by that column's value). Every run's time starts at 0.

Every refusal is one line naming the file, the sheet, the row (line of a CSV) and the column, or the map
file, its line and its field. docs/recordings.md is the user's guide.
"""

from __future__ import annotations

import csv
import datetime as dt
import fnmatch
import io
import math
import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np

from nckemu.errors import NckConfigError
from nckemu.textfile import read_text

from . import recording as project
from .recording import (
    MIN_ROWS,
    Recording,
    check_runs,
    column_kind,
    decimal_mark_refusal,
    find_recordings,
    parse_number,
    sniff_csv,
)

WORKBOOK_SUFFIXES = (".xlsx", ".xlsm")
MAPPED_SUFFIXES = (*WORKBOOK_SUFFIXES, ".csv", ".txt", ".tsv", ".parquet", ".pq")

# Seconds per unit of a numeric time column; "datetime" is a date and time (ISO text, an Excel serial
# number or a workbook's date cell).
TIME_UNITS: dict[str, float] = {"ms": 0.001, "s": 1.0, "min": 60.0, "h": 3600.0, "d": 86400.0}
DATETIME = "datetime"
_EXCEL_EPOCH = dt.datetime(1899, 12, 30, tzinfo=dt.UTC)  # serial 0 (Excel's 1900 system, after Feb 1900)
_UNIX_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)

_MICRO = {"um": 1.0, "µm": 1.0, "μm": 1.0, "nm": 0.001, "mm": 1000.0, "m": 1e6, "in": 25400.0}
# A column's unit -> (scale, offset) to the project's unit: project = value * scale + offset.
VALUE_UNITS: dict[str, dict[str, tuple[float, float]]] = {
    "err": {unit: (scale, 0.0) for unit, scale in _MICRO.items()},
    "sim": {unit: (scale, 0.0) for unit, scale in _MICRO.items()},
    "pos": {unit: (scale / 1000.0, 0.0) for unit, scale in _MICRO.items()},
    "temp": {"C": (1.0, 0.0), "°C": (1.0, 0.0), "degC": (1.0, 0.0), "K": (1.0, -273.15),
             "F": (5.0 / 9.0, -32.0 * 5.0 / 9.0), "°F": (5.0 / 9.0, -32.0 * 5.0 / 9.0)},
    "rpm": {"rpm": (1.0, 0.0), "1/min": (1.0, 0.0), "rps": (60.0, 0.0), "Hz": (60.0, 0.0)},
}
PROJECT_UNITS = {"err": "um", "sim": "um", "pos": "mm", "temp": "C", "rpm": "rpm"}
ROLES = {"t": "time", "temp": "temperature", "rpm": "spindle speed", "pos": "axis position",
         "err": "measured error", "sim": "simulated compensation"}

_TABLES = {"time": {"column", "unit", "format"}, "columns": None, "runs": {"sheets", "column"}}


def convert_value(values: np.ndarray, kind: str, unit: str) -> np.ndarray:
    """``values`` in ``unit`` as the project's unit of a column of ``kind`` (err, sim, pos, temp, rpm)."""
    scale, offset = VALUE_UNITS[kind][unit]
    return values * scale + offset if offset else values * scale


def convert_decimal(values: np.ndarray, scale: float, offset: float = 0.0) -> np.ndarray:
    """``values * scale + offset`` worked in decimal from each value's shortest text, as a person would:
    -9 um is -0.009 mm, not -0.009000000000000001 (the binary product, which the files would then carry
    as its ``repr``); 16.66667 h is 60000.012 s, not 60000.012000000004. A value's own digits are kept."""
    if scale == 1.0 and not offset:
        return values
    exact_scale, exact_offset = Decimal(repr(scale)), Decimal(repr(offset))

    def one(value: float) -> float:
        if value != value or (value and abs(value) < _SMALLEST_NORMAL):  # NaN; a subnormal's text is short
            return value * scale + offset
        return float(Decimal(repr(value)) * exact_scale + exact_offset)

    return np.array([one(value) for value in values.tolist()], dtype=float)


_SMALLEST_NORMAL = 2.2250738585072014e-308


def excel_serial(moment: dt.datetime) -> float:
    """A date and time as Excel's serial number (days since 1899-12-30; naive means UTC)."""
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=dt.UTC)
    return (moment - _EXCEL_EPOCH) / dt.timedelta(days=1)


def excel_serial_seconds(serial: float) -> float:
    """Seconds since 1970 of an Excel serial number."""
    return serial * 86400.0 + (_EXCEL_EPOCH - _UNIX_EPOCH).total_seconds()


# ----------------------------------------------------------------------------------------- the map
@dataclass(frozen=True)
class ColumnMap:
    name: str            # the project's column name, e.g. err_x_um
    column: str          # the source column (compared with whitespace trimmed)
    unit: str            # the source's unit
    line: int | None     # where the map says so
    kind: str = ""       # t, temp, rpm, pos, err, sim
    key: str = ""        # the sensor's or axis's name within the project's name

    @property
    def field(self) -> str:
        return "time.column" if self.kind == "t" else f"columns.{self.name}"


@dataclass(frozen=True)
class RecordingMap:
    source: str
    time: ColumnMap
    columns: tuple[ColumnMap, ...]
    time_format: str | None = None
    run_sheets: tuple[str, ...] | None = None   # sheet names or glob patterns ("*": every sheet)
    run_sheets_line: int | None = None
    run_column: str | None = None
    run_column_line: int | None = None

    def where(self, column: ColumnMap) -> str:
        """The map's place of a column, for a refusal about the source."""
        line = f", line {column.line}" if column.line else ""
        return f"{self.source}{line}, {column.field}"


def _key_lines(text: str, source: str) -> dict[tuple[str, str], int]:
    """The line of every ``key =`` in every ``[table]``; two of one key in a table are refused here, so
    the refusal names both lines (tomllib names one)."""
    lines: dict[tuple[str, str], int] = {}
    table = ""
    key_pattern = re.compile(r"""^\s*("([^"]*)"|'([^']*)'|[A-Za-z0-9_\-]+)\s*=""")
    for number, raw in enumerate(text.splitlines(), 1):
        stripped = raw.strip()
        header = re.match(r"^\[\s*([^\[\]]+?)\s*\]\s*(#.*)?$", stripped)
        if header:
            table = header.group(1).strip().strip('"')
            lines.setdefault((table, "[]"), number)
            continue
        match = key_pattern.match(raw)
        if not match:
            continue
        key = match.group(2) if match.group(2) is not None else match.group(3) if match.group(3) is not None \
            else match.group(1)
        if (table, key) in lines:
            what = "two sources for one name" if table == "columns" else "the key appears twice"
            raise NckConfigError(f"{what} (the first on line {lines[(table, key)]})", path=source, line=number,
                                 field=f"{table}.{key}" if table else key)
        lines[(table, key)] = number
    return lines


def _text_value(value: Any, source: str, line: int | None, name: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise NckConfigError("expected a non-empty string", path=source, line=line, field=name)
    return value.strip()


def load_map(path: str | Path) -> RecordingMap:
    """Read and check a map file; every refusal names the map file, its line and the field."""
    source = str(path)
    text = read_text(path, "a recording map is TOML text")
    lines = _key_lines(text, source)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise NckConfigError(f"not valid TOML: {exc}", path=source) from None

    def line_of(table: str, key: str) -> int | None:
        return lines.get((table, key))

    for table, value in data.items():
        if table not in _TABLES:
            raise NckConfigError("unknown table (a map has [time], [columns] and [runs])", path=source,
                                 line=line_of(table, "[]"), field=table)
        if not isinstance(value, dict):
            raise NckConfigError("expected a table, e.g. [time]", path=source, line=line_of("", table), field=table)
        allowed = _TABLES[table]
        for key in value:
            if allowed is not None and key not in allowed:
                raise NckConfigError(f"unknown key (expected {', '.join(sorted(allowed))})", path=source,
                                     line=line_of(table, key), field=f"{table}.{key}")
    time = data.get("time")
    if time is None:
        raise NckConfigError('no [time] table: say which column is the time, e.g. [time] column = "Time", '
                             'unit = "s"', path=source, field="time")
    time_column = _text_value(time.get("column"), source, line_of("time", "column"), "time.column")
    time_unit = _text_value(time.get("unit", "s"), source, line_of("time", "unit"), "time.unit")
    if time_unit not in TIME_UNITS and time_unit != DATETIME:
        raise NckConfigError(f"unknown time unit {time_unit!r} (expected {', '.join(TIME_UNITS)} or {DATETIME})",
                             path=source, line=line_of("time", "unit"), field="time.unit")
    time_format = None
    if "format" in time:
        time_format = _text_value(time["format"], source, line_of("time", "format"), "time.format")
        if time_unit != DATETIME:
            raise NckConfigError(f"a format is for unit = \"{DATETIME}\"", path=source,
                                 line=line_of("time", "format"), field="time.format")
    time_map = ColumnMap("t_s", time_column, time_unit, line_of("time", "column"), "t")
    columns: list[ColumnMap] = []
    for name, spec in (data.get("columns") or {}).items():
        line = line_of("columns", name)
        where = f"columns.{name}"
        kind = column_kind(name)
        if kind is None:
            raise NckConfigError("not a project column name (expected temp_<name>_C, spindle_rpm, pos_<axis>_mm, "
                                 "err_<axis>_um or sim_<axis>_um)", path=source, line=line, field=where)
        if kind[0] == "t":
            raise NckConfigError(f"two sources for one name: the time comes from [time] (column "
                                 f"{time_column!r})", path=source, line=line, field=where)
        unit = PROJECT_UNITS[kind[0]]
        if isinstance(spec, dict):
            for key in spec:
                if key not in ("column", "unit"):
                    raise NckConfigError("unknown key (expected column and unit)", path=source, line=line,
                                         field=f"{where}.{key}")
            column = _text_value(spec.get("column"), source, line, f"{where}.column")
            if "unit" in spec:
                unit = _text_value(spec["unit"], source, line, f"{where}.unit")
        else:
            column = _text_value(spec, source, line, where)
        if unit not in VALUE_UNITS[kind[0]]:
            raise NckConfigError(f"unknown unit {unit!r} for a {ROLES[kind[0]]} column (expected "
                                 f"{', '.join(VALUE_UNITS[kind[0]])})", path=source, line=line, field=where)
        columns.append(ColumnMap(name, column, unit, line, kind[0], kind[1]))
    runs = data.get("runs") or {}
    sheets: tuple[str, ...] | None = None
    if "sheets" in runs:
        value = runs["sheets"]
        names = [value] if isinstance(value, str) else value
        if not isinstance(names, list) or not names or not all(isinstance(n, str) and n.strip() for n in names):
            raise NckConfigError('expected "*", a pattern or a list of sheet names', path=source,
                                 line=line_of("runs", "sheets"), field="runs.sheets")
        sheets = tuple(n.strip() for n in names)
    run_column = None
    if "column" in runs:
        run_column = _text_value(runs["column"], source, line_of("runs", "column"), "runs.column")
    return RecordingMap(source, time_map, tuple(columns), time_format, sheets, line_of("runs", "sheets"),
                        run_column, line_of("runs", "column"))


# --------------------------------------------------------------------------------------- sources
@dataclass
class Table:
    """One table of a source: a sheet, a CSV file or a Parquet file, cells as read."""

    file: str
    sheet: str | None
    header: list[str]                  # as in the file
    cells: list[list[Any]]             # per column
    rows: list[int]                    # each data row's row (sheet), line (CSV) or row (Parquet) number
    row_word: str = "row"
    decimal: str | None = None         # a CSV's decimal mark (None: not seen)
    separator: str | None = None
    header_row: int | None = None      # the header's row (sheet) or line (CSV)

    def place(self, row: int | None = None, column: str | None = None) -> str:
        parts = [self.file]
        if self.sheet is not None:
            parts.append(f"sheet {self.sheet!r}")
        if row is not None:
            parts.append(f"{self.row_word} {row}")
        if column is not None:
            parts.append(f"column {column!r}")
        return ", ".join(parts)

    def refuse(self, message: str, row: int | None = None, column: str | None = None) -> NckConfigError:
        exc = NckConfigError(message, path=self.file, line=row, field=column)
        exc.args = (f"{self.place(row, column)}: {message}",)
        return exc


def read_tables(path: str | Path) -> list[Table]:
    """Every table of a source: a workbook's sheets in order, or the one table of a CSV or Parquet file."""
    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise NckConfigError("no such file" if not path.exists() else "not a file", path=source)
    suffix = path.suffix.lower()
    if suffix in WORKBOOK_SUFFIXES:
        return _read_workbook(path)
    data = _read_bytes(path)
    if suffix in (".parquet", ".pq") or data[:4] == b"PAR1":
        return [_read_parquet(data, source)]
    if data[:4] == b"PK\x03\x04":
        raise NckConfigError("a zip file (a workbook?): workbooks are read by their name, *.xlsx", path=source)
    return [_read_csv(data, source)]


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise NckConfigError(f"cannot read: {exc.strerror}", path=str(path)) from None


def _read_workbook(path: Path) -> list[Table]:
    import zipfile

    import openpyxl

    source = str(path)
    try:
        workbook = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except (zipfile.BadZipFile, OSError, KeyError, ValueError) as exc:
        raise NckConfigError(f"not a readable workbook ({str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__})",
                             path=source) from None
    tables = []
    try:
        for sheet in workbook.worksheets:
            header: list[str] | None = None
            header_row = None
            cells: list[list[Any]] = []
            rows: list[int] = []
            for number, values in enumerate(sheet.iter_rows(values_only=True), 1):
                if all(v is None or (isinstance(v, str) and not v.strip()) for v in values):
                    continue
                if header is None:
                    header = ["" if v is None else str(v) for v in values]
                    header_row = number
                    cells = [[] for _ in header]
                    continue
                for index in range(len(header)):
                    cells[index].append(values[index] if index < len(values) else None)
                rows.append(number)
            tables.append(Table(source, str(sheet.title), header or [], cells, rows, header_row=header_row))
    finally:
        workbook.close()
    return tables


def _read_csv(data: bytes, source: str) -> Table:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        try:  # an old Excel writes its code page; Latin-1 reads any byte, and the header will tell
            text = data.decode("cp1252")
        except UnicodeDecodeError:
            text = data.decode("latin-1")
    if "\x00" in text:
        raise NckConfigError("not a text file (it holds NUL bytes)", path=source)
    dialect = sniff_csv(text)
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=dialect.separator)
    header: list[str] | None = None
    header_row = None
    cells: list[list[Any]] = []
    rows: list[int] = []
    try:
        for row in reader:
            if not row or all(not cell.strip() for cell in row):
                continue
            if header is None:
                header = row
                header_row = reader.line_num
                cells = [[] for _ in header]
                continue
            if len(row) != len(header):
                raise NckConfigError(f"{len(row)} cells, the header has {len(header)} (separator "
                                     f"{_separator_name(dialect.separator)})", path=source, line=reader.line_num)
            for index, cell in enumerate(row):
                cells[index].append(cell)
            rows.append(reader.line_num)
    except csv.Error as exc:
        raise NckConfigError(f"not CSV: {exc}", path=source, line=reader.line_num) from None
    return Table(source, None, header or [], cells, rows, "line", dialect.decimal, dialect.separator, header_row)


def _separator_name(separator: str) -> str:
    return {"\t": "tab", ",": "','", ";": "';'"}.get(separator, repr(separator))


def _read_parquet(data: bytes, source: str) -> Table:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(pa.BufferReader(data))
        cells = [table.column(index).to_pylist() for index in range(table.num_columns)]
    except (pa.ArrowException, OSError, ValueError, TypeError, IndexError, KeyError) as exc:
        raise NckConfigError(f"not a readable Parquet file ({str(exc).splitlines()[0][:120]})", path=source) from None
    return Table(source, None, [str(n) for n in table.column_names], cells, list(range(1, table.num_rows + 1)))


# ------------------------------------------------------------------------------------ applying it
@dataclass
class ColumnUse:
    """What became of one source column."""

    column: str
    name: str          # the project's name, or "" when ignored
    role: str
    unit: str
    project_unit: str


@dataclass
class Run:
    """One run of a source: its recording, or why it failed."""

    name: str
    file: str
    sheet: str | None
    recording: Recording | None = None
    error: NckConfigError | None = None
    columns: list[ColumnUse] = field(default_factory=list)


def _column_index(table: Table, column: ColumnMap | str, recording_map: RecordingMap) -> int:
    wanted = column.column if isinstance(column, ColumnMap) else column
    found = [index for index, name in enumerate(table.header) if name.strip() == wanted.strip()]
    if len(found) > 1:
        raise table.refuse(f"two columns are named {wanted!r} (columns {found[0] + 1} and {found[1] + 1}): "
                           "rename one in the source", row=_header_row(table), column=wanted)
    if not found:
        said = recording_map.where(column) if isinstance(column, ColumnMap) else f"{recording_map.source}, runs.column"
        listing = ", ".join(repr(h.strip()) for h in table.header[:12]) + (", ..." if len(table.header) > 12 else "")
        raise table.refuse(f"no column {wanted!r} ({said}); the header has {listing or 'nothing'}",
                           row=_header_row(table))
    return found[0]


def _header_row(table: Table) -> int | None:
    return table.header_row


def _numbers(table: Table, index: int, rows: Sequence[int], nullable: bool) -> np.ndarray:
    column = table.header[index].strip()
    cells = table.cells[index]
    values = np.empty(len(rows))
    for out, row in enumerate(rows):
        cell = cells[row]
        if cell is None or (isinstance(cell, str) and not cell.strip()):
            if not nullable:
                raise table.refuse("empty cell (only err_ and sim_ cells may be empty)", table.rows[row], column)
            values[out] = math.nan
            continue
        if isinstance(cell, bool) or not isinstance(cell, int | float | str):
            raise table.refuse(f"not a number: {cell!r}", table.rows[row], column)
        value = float(cell) if not isinstance(cell, str) else parse_number(cell.strip(), table.decimal)
        if value is None:
            raise table.refuse(f"text in a number column: {str(cell).strip()[:40]!r}", table.rows[row], column)
        if not math.isfinite(value):
            raise table.refuse(f"not a finite number: {str(cell).strip()[:40]!r}", table.rows[row], column)
        values[out] = value
    return values


def _moment_seconds(cell: Any, time_format: str | None, decimal: str | None) -> float | None:
    """Seconds since 1970 of a date and time cell: a datetime, ISO text (or ``time_format``), or an Excel
    serial number; None when it is none of these."""
    if isinstance(cell, dt.datetime):
        moment = cell
    elif isinstance(cell, dt.date):
        moment = dt.datetime(cell.year, cell.month, cell.day)
    elif isinstance(cell, bool):
        return None
    elif isinstance(cell, int | float):
        return excel_serial_seconds(float(cell))
    elif isinstance(cell, str):
        text = cell.strip()
        number = parse_number(text, decimal)
        if number is not None:
            return excel_serial_seconds(number)
        try:
            moment = dt.datetime.strptime(text, time_format) if time_format else dt.datetime.fromisoformat(text)
        except ValueError:
            return None
    else:
        return None
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=dt.UTC)
    return (moment - _UNIX_EPOCH).total_seconds()


def _time_column(table: Table, index: int, rows: Sequence[int], recording_map: RecordingMap) -> np.ndarray:
    unit = recording_map.time.unit
    if unit != DATETIME:
        return convert_decimal(_numbers(table, index, rows, nullable=False), TIME_UNITS[unit])
    column = table.header[index].strip()
    values = np.empty(len(rows))
    for out, row in enumerate(rows):
        cell = table.cells[index][row]
        if cell is None or (isinstance(cell, str) and not cell.strip()):
            raise table.refuse("empty time cell", table.rows[row], column)
        seconds = _moment_seconds(cell, recording_map.time_format, table.decimal)
        if seconds is None:
            expected = f"format {recording_map.time_format!r}" if recording_map.time_format else \
                "ISO date and time or an Excel serial number"
            raise table.refuse(f"not a date and time ({expected}): {str(cell).strip()[:40]!r}", table.rows[row],
                               column)
        values[out] = seconds
    return values


def _check_time(table: Table, t_s: np.ndarray, rows: Sequence[int], column: str) -> None:
    steps = np.diff(t_s)
    bad = np.flatnonzero(~(steps > 0))
    if len(bad):
        at = int(bad[0]) + 1
        what = "repeats" if t_s[at] == t_s[at - 1] else "goes backwards"
        raise table.refuse(f"the time {what} ({t_s[at] - t_s[0]:g} s after {t_s[at - 1] - t_s[0]:g} s, "
                           f"counted from the run's start; the {table.row_word} before is "
                           f"{table.rows[rows[at - 1]]})", table.rows[rows[at]], column)


def _run_name(value: Any) -> str:
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value).strip()


def apply_map(table: Table, recording_map: RecordingMap, *, name: str) -> list[Run]:
    """The runs of one table under the map; a refusal that concerns the whole table is raised, one that
    concerns a run is kept in its Run (the other runs are still read)."""
    if not table.header:
        raise table.refuse("empty sheet (no header, no rows)" if table.sheet is not None else
                           "empty file (no header, no rows)")
    time_index = _column_index(table, recording_map.time, recording_map)
    indices = [(column, _column_index(table, column, recording_map)) for column in recording_map.columns]
    run_index = None
    if recording_map.run_column is not None:
        run_index = _column_index(table, recording_map.run_column, recording_map)
    used = {time_index, *(i for _, i in indices)} | ({run_index} if run_index is not None else set())
    uses = [ColumnUse(table.header[time_index].strip(), "t_s", "time", recording_map.time.unit, "s")]
    uses += [ColumnUse(table.header[i].strip(), c.name, ROLES[c.kind], c.unit, PROJECT_UNITS[c.kind])
             for c, i in indices]
    if run_index is not None:
        uses.append(ColumnUse(table.header[run_index].strip(), "", "run name", "", ""))
    uses += [ColumnUse(h.strip(), "", "ignored", "", "") for i, h in enumerate(table.header) if i not in used]
    if not table.rows:
        raise table.refuse(f"no data rows under the header ({'an empty sheet' if table.sheet else 'an empty file'})")
    groups: dict[str, list[int]] = {}
    if run_index is None:
        groups[name] = list(range(len(table.rows)))
    else:
        for row, value in enumerate(table.cells[run_index]):
            if value is None or (isinstance(value, str) and not value.strip()):
                raise table.refuse("empty run name", table.rows[row], table.header[run_index].strip())
            groups.setdefault(_run_name(value), []).append(row)
    runs = []
    for run_name, rows in groups.items():
        run = Run(run_name, table.file, table.sheet, columns=uses)
        try:
            run.recording = _recording(table, recording_map, run_name, rows, time_index, indices)
        except NckConfigError as exc:
            run.error = exc
        runs.append(run)
    return runs


def _recording(table: Table, recording_map: RecordingMap, name: str, rows: list[int], time_index: int,
               indices: list[tuple[ColumnMap, int]]) -> Recording:
    time_column = table.header[time_index].strip()
    _check_decimal_marks(table, rows, [time_index, *(index for _, index in indices)])
    t_s = _time_column(table, time_index, rows, recording_map)
    if len(rows) < MIN_ROWS:
        raise table.refuse(f"run {name!r}: {len(rows)} data row{'s' if len(rows) != 1 else ''}; a run needs at "
                           f"least {MIN_ROWS}")
    _check_time(table, t_s, rows, time_column)
    source = table.file if table.sheet is None else f"{table.file}, sheet {table.sheet!r}"
    recording = Recording(source, t_s - t_s[0], name=name)
    for column, index in indices:
        values = convert_decimal(_numbers(table, index, rows, nullable=column.kind in ("err", "sim")),
                                 *VALUE_UNITS[column.kind][column.unit])
        key = column.key
        if column.kind == "temp":
            recording.temperatures_C[column.name] = values
        elif column.kind == "rpm":
            recording.spindle_rpm = values
        elif column.kind == "pos":
            recording.positions_mm[key] = values
        elif column.kind == "err":
            recording.errors_um[key] = values
        elif column.kind == "sim":
            recording.simulated_um[key] = values
    return recording


def _check_decimal_marks(table: Table, rows: list[int], columns: list[int]) -> None:
    """Refuse the first cell, line by line, that writes the other decimal mark than the file's (sniffed
    from the marks most cells show), rather than a good cell that only reads wrong beside it."""
    if table.decimal is None:
        return
    for row in rows:
        for index in columns:
            cell = table.cells[index][row]
            if isinstance(cell, str) and (refusal := decimal_mark_refusal(cell.strip(), table.decimal)) is not None:
                raise table.refuse(refusal, table.rows[row], table.header[index].strip())


def _selected_tables(tables: list[Table], recording_map: RecordingMap, source: str) -> list[tuple[Table, bool]]:
    """The tables that hold runs, each with whether its runs are named after its sheet."""
    if tables[0].sheet is None:
        return [(tables[0], False)]
    time_column = recording_map.time.column.strip()

    def has_time(table: Table) -> bool:
        return any(h.strip() == time_column for h in table.header)

    patterns = recording_map.run_sheets
    if patterns is None:
        with_time = [t for t in tables if has_time(t)]
        if len(tables) == 1 or not with_time:
            return [(tables[0], False)]
        if len(with_time) > 1:
            raise NckConfigError(f"{len(with_time)} sheets have the time column {time_column!r} "
                                 f"({', '.join(repr(t.sheet) for t in with_time[:6])}): say which are runs in "
                                 f'{recording_map.source}: [runs] sheets = "*" (every one) or a list of names',
                                 path=source)
        return [(with_time[0], False)]
    selected: list[tuple[Table, bool]] = []
    for pattern in patterns:
        literal = not any(ch in pattern for ch in "*?[")
        matches = [t for t in tables if (t.sheet or "").strip() == pattern or
                   (not literal and fnmatch.fnmatchcase((t.sheet or "").strip(), pattern))]
        if literal and not matches:
            raise NckConfigError(f"no sheet {pattern!r} ({recording_map.source}, line {recording_map.run_sheets_line}, "
                                 f"runs.sheets); the sheets: {', '.join(repr(t.sheet) for t in tables)}", path=source)
        if not literal:
            # a pattern picks the sheets that hold the time column; blank sheets are no runs
            matches = [t for t in matches if has_time(t)]
        selected += [(t, True) for t in matches if all(t is not s for s, _ in selected)]
    if not selected:
        raise NckConfigError(f"no sheet has the time column {time_column!r} (sheets: "
                             f"{', '.join(repr(t.sheet) for t in tables)})", path=source)
    return selected


@dataclass
class SourceReading:
    """What a source gave under a map: its runs, and the sheets that were left out."""

    file: str
    runs: list[Run]
    skipped_sheets: list[str] = field(default_factory=list)


def read_source(path: str | Path, recording_map: RecordingMap, *, need_errors: bool = True) -> SourceReading:
    source = str(path)
    if need_errors and not any(c.kind == "err" for c in recording_map.columns):
        raise NckConfigError("the map names no err_<axis>_um column (this command needs a measured error)",
                             path=recording_map.source, field="columns")
    tables = read_tables(path)
    selected = _selected_tables(tables, recording_map, source)
    runs: list[Run] = []
    for table, by_sheet in selected:
        name = (table.sheet or Path(source).stem) if by_sheet else Path(source).stem
        try:
            runs += apply_map(table, recording_map, name=name)
        except NckConfigError as exc:  # this sheet (or file) gives no run; the other sheets still do
            runs.append(Run(name, table.file, table.sheet, error=exc))
    chosen = {id(t) for t, _ in selected}
    skipped = [t.sheet or "" for t in tables if id(t) not in chosen and t.sheet is not None]
    return SourceReading(source, runs, skipped)


def read_sources(paths: Sequence[str | Path], recording_map: RecordingMap, *,
                 need_errors: bool = True) -> list[SourceReading]:
    """Every source under the map; two runs of one name across the sources are refused."""
    readings = [read_source(path, recording_map, need_errors=need_errors) for path in paths]
    seen: dict[str, Run] = {}
    for reading in readings:
        for run in reading.runs:
            if run.name in seen:
                first = seen[run.name]
                raise NckConfigError(f"a second run named {run.name!r} (the first is in {first.file}"
                                     f"{'' if first.sheet is None else f', sheet {first.sheet!r}'})",
                                     path=run.file if run.sheet is None else f"{run.file}, sheet {run.sheet!r}")
            seen[run.name] = run
    return readings


def load_mapped_runs(paths: Sequence[str | Path], map_path: str | Path, *,
                     need_errors: bool = True) -> list[Recording]:
    """The runs of ``paths`` under the map at ``map_path``; the first failed run is raised."""
    recording_map = load_map(map_path)
    runs = [run for reading in read_sources(paths, recording_map, need_errors=need_errors) for run in reading.runs]
    for run in runs:
        if run.error is not None:
            raise run.error
    return [run.recording for run in runs if run.recording is not None]


def safe_file_name(name: str) -> str:
    """A run's name as a file name: runs of whitespace and path separators become '_'."""
    cleaned = re.sub(r"[^\w.\-]+", "_", name).strip("._")
    return cleaned or "run"


def load_recording(path: str | Path, *, need_errors: bool = True, map_path: str | Path | None = None) -> Recording:
    """``recording.load_recording``, or with ``map_path`` the one run of a foreign file read through the map
    (a source that gives several runs is refused: ``nckemu recording import`` writes one file each)."""
    if map_path is None:
        return project.load_recording(path, need_errors=need_errors)
    runs = load_mapped_runs([path], map_path, need_errors=need_errors)
    if len(runs) != 1:
        raise NckConfigError(f"{len(runs)} runs under the map ({', '.join(repr(r.name) for r in runs[:5])}"
                             f"{', ...' if len(runs) > 5 else ''}); this command takes one: name one sheet in "
                             "[runs] sheets, or write one file per run with `nckemu recording import`",
                             path=str(path))
    return runs[0]


def load_runs(specs: Sequence[str | Path], axis: str | None = None, *,
              map_path: str | Path | None = None) -> list[Recording]:
    """``recording.load_runs``, or with ``map_path`` the runs of foreign files (files, directories, globs of
    workbooks, CSV and Parquet files), each giving one run or several, checked as runs of one machine."""
    if map_path is None:
        return project.load_runs(specs, axis)
    return check_runs(load_mapped_runs(find_recordings(specs, MAPPED_SUFFIXES), map_path), axis)
