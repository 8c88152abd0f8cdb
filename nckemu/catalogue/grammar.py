"""One grammar for every way to name a value: NC syntax, BTSS, SINUMERIK OPC UA node ids, S7 addresses.

``parse_name(text)`` reads each form below into one of two typed names, ``NcNodeName`` (an NCK variable
of the catalogue: everything an ``NckAddress`` needs) or ``PlcNodeName`` (PLC memory); the display
functions write each form back, so that what is printed can be typed again (docs/addresses.md says all
of it for people). Names are case-insensitive; spaces inside brackets are allowed.

NC syntax, as in part programs: a number in brackets is an array index counted from 0.
  R4  R[4]  $R[4]  R4[C1]             R parameter 4 (BTSS line 5)
  SD43900[AX4]  $SA_TEMP_COMP_ABS_VALUE[AX4]  TEMP_COMP_ABS_VALUE[AX4]   AXn: the axis (the unit)
  MD10000[1]                          the second entry (line 2): machine axis 2's name
  MD32700[1,AX4]                      index 1 of axis 4
  actToolBasePos[AX4]  actSpeed[SP1]  a row whose lines are machine axes or spindles (table.LINE_KINDS):
                                      AXn / SPn is the line; actToolBasePos[3] is the same line by index
  cuttEdgeParam[2,T1,col7,x25]        index 2 (D1 P3), TO unit T1, tool T7 (the column), 25 lines from there
  NAME[C1,l2,x3]                      Cn/Nn/Bn/Tn/Vn/Hn: unit of that area; l: the line itself; x: lines
  SSP2 actSpeed[SP1,C1]               the display: number, name and brackets (pasted back, it reads)
BTSS, the controller's paths and the NC-Var selector's lines: a number is a line counted from 1. A
``uN`` part in the brackets makes a catalogue name BTSS too.
  /Channel/Parameter/R[u1,5]  /Channel/Parameter/rpa[u1,5]  R[u1,5]   R4: unit 1, line 5
  R[u1,1,5]  R[u1,1,#5]               lines 1..5, or 5 lines from line 1: an array
  MD10000[u1,2]  TEMP_COMP_ABS_VALUE[u4]   by number or name
  /Tool/Compensation/cuttEdgeParam[u1, c7, 3]   TO unit 1, tool T7 (the column), line 3 (D1 P3)
SINUMERIK OPC UA node ids (``ns=2;s=`` in front is optional): the BTSS paths, and machine and setting
data, whose ``/NC/`` ids count lines from 1 too (the controller's GUD ids do: ARRAY[0] is ARRAY[1]):
  /NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]   /NC/_N_AX_TEA_ACX/$MA_ENC_COMP_ENABLE[2,u4] (index 1)
  /Plc/M5.0  /Plc/MB6  /Plc/DB5.DBW2  /Plc/DB8.DBB2:STRING  /Plc/DB8.DBW2:[10]  /Plc/DB2.DBD0:REAL[10]
  (``/Random/Plc/...`` is the same as ``/Plc/...``)
S7, as STEP 7 and S7 tools write PLC memory (German E/A for I/Q accepted):
  DB130.DBW0  DB1.DBX2.3  MB10  MW10  M5.0  IB0  I0.1  QW2  PIW420  PQW256  DB2.DBD0:REAL
  (``MD10`` stays machine data; the flag double word is ``MD10:DWORD`` or ``/Plc/MD10``)

Two typed errors: ``NckNodeIdUnknown`` (malformed, or no such name or namespace) and
``NckNodeNotConfigured`` (well formed, but the table lacks the variable or the index lies outside it);
each refusal of an index names the valid range in NC syntax and in BTSS.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

from nckemu.errors import NckNodeIdUnknown, NckNodeNotConfigured
from nckemu.protocol.addresses import NckAddress, NckArea, S7Area

from .edges import TOOL_OFFSETS
from .table import (
    LINE_PREFIXES,
    R_PARAMETER_LINE_OFFSET,
    VariableSpec,
    display_name,
    line_kind,
    load_table,
    short_name,
)

MAX_TEXT = 400            # longer names are not read at all (the controller's paths are short)
MAX_PLC_ITEMS = 1024      # array length of a PLC name
MAX_PLC_BYTE = 0xFFFF
MAX_DIGITS = 5            # a number in an index (99999 is past every line and column of a row)
MAX_UNIT = 31             # the unit's five bits on the wire

_AREA_WORD = {NckArea.N: "NC", NckArea.B: "NC", NckArea.C: "CH", NckArea.A: "AX", NckArea.T: "NC"}
_AREA_LETTER = {NckArea.N: "N", NckArea.B: "N", NckArea.C: "C", NckArea.A: "A", NckArea.T: "N"}
_AREA_FOLDER = {NckArea.N: "Nck", NckArea.B: "Bag", NckArea.C: "Channel", NckArea.A: "Axis", NckArea.T: "Tool",
                NckArea.V: "Drive", NckArea.H: "Drive", NckArea.M: "Mmc"}
# First path segments of the controller's NC namespace: a well-formed id under one of them that the
# table lacks is "not configured", anything else "unknown".
NC_ROOTS = frozenset({"nck", "channel", "bag", "tool", "axis", "drive", "nc", "nckemu", "hmi", "geometricaxis",
                      "drivevsa"})
# Public OPC UA collectors read a motor module's parameters both as /DriveVsa/Drive/r0035[uN] and as
# /DriveVsa/DC/R0026[uN] (docs/assumptions.md): the second is served as another name of the first.
_DRIVE_FOLDER, _DRIVE_ALIAS = "/DriveVsa/Drive/", "/DriveVsa/DC/"

_NS = re.compile(r"^ns=\d{1,5};s=", re.IGNORECASE)
_PATH = re.compile(r"^(?P<path>/[A-Za-z0-9_/$]+?)\s*(?:\[(?P<index>[^\[\]]*)\])?$")
_NC_DATA = re.compile(r"^/nc/_n_(?P<area>nc|ch|ax)_(?P<kind>sea|tea)_acx/\$(?P<sm>[sm])(?P<letter>[nca])_"
                      r"(?P<name>[a-z0-9_]+)$")
_NAME = re.compile(r"^\$?(?:[SM][ACN]_)?(?P<name>[A-Z_][A-Z0-9_]*?)\s*(?:\[(?P<index>[^\[\]]*)\])?$",
                   re.IGNORECASE)
_R_SHORT = re.compile(r"^\$?R(?P<number>\d+)\s*(?:\[(?P<index>[^\[\]]*)\])?$", re.IGNORECASE)
_NUMBERED = re.compile(r"^(?P<number>[A-Za-z_$][A-Za-z0-9_]*)\s+(?P<rest>[A-Za-z_$].*)$")
_PART = re.compile(r"^(?P<prefix>[a-z#]*)(?P<number>\d+)$")
_PLC = re.compile(
    r"^(?:db(?P<db>\d{1,5})\.db(?P<dbwidth>[xbwd])|(?P<area>p[ieqa]|[ieqam])(?P<width>[xbwd]?))"
    r"(?P<byte>\d{1,6})(?:\.(?P<bit>\d{1,2}))?(?::(?P<type>[a-z]*)(?:\[(?P<count>\d{1,5})\])?)?$")
_PLC_TYPES = {"": None, "bool": "BOOL", "byte": "BYTE", "char": "BYTE", "word": "WORD", "int": "INT",
              "dword": "DWORD", "dint": "DINT", "real": "REAL", "string": "STRING"}
_WIDTH_TYPE = {"x": "BOOL", "b": "BYTE", "w": "WORD", "d": "DWORD"}
_TYPE_WIDTH = {"BOOL": "X", "BYTE": "B", "STRING": "B", "WORD": "W", "INT": "W", "DWORD": "D", "DINT": "D",
               "REAL": "D"}
PLC_TYPE_BYTES = {"BOOL": 1, "BYTE": 1, "WORD": 2, "INT": 2, "DWORD": 4, "DINT": 4, "REAL": 4}
_GERMAN = {"e": "i", "a": "q", "pe": "pi", "pa": "pq"}
PLC_S7_AREAS = {"I": S7Area.I, "Q": S7Area.Q, "M": S7Area.M, "DB": S7Area.DB, "PI": S7Area.P, "PQ": S7Area.P}
NC_UNIT_LETTERS = {"n": NckArea.N, "b": NckArea.B, "c": NckArea.C, "t": NckArea.T, "v": NckArea.V,
                   "h": NckArea.H, "m": NckArea.M}


@dataclass(frozen=True)
class NcNodeName:
    """An NC variable, unit, lines and column: everything an ``NckAddress`` needs, plus the realm."""

    spec: VariableSpec
    area: int
    unit: int
    line: int
    count: int
    column: int
    realm: str
    array: bool

    @property
    def address(self) -> NckAddress:
        return NckAddress(self.area, self.unit, self.column, self.line, self.spec.module, self.count)

    def __str__(self) -> str:
        return display_name(self.spec, self.address)


@dataclass(frozen=True)
class PlcNodeName:
    """PLC memory: area "I", "Q", "M", "DB", or (S7 names only) "PI"/"PQ" for the peripheral area; ``kind``
    the element type; ``count`` elements (an array if ``array``). A STRING is an S7 string (maximum
    length, length, characters) read whole. ``str()`` is the S7 name (``DB130.DBW0``, ``M5.0``)."""

    area: str
    db: int
    byte: int
    bit: int | None
    kind: str
    count: int
    array: bool
    realm: str = "Plc"

    @property
    def size_bytes(self) -> int:
        return PLC_TYPE_BYTES.get(self.kind, 1) * self.count

    @property
    def s7_area(self) -> int:
        return int(PLC_S7_AREAS[self.area])

    def __str__(self) -> str:
        width = _TYPE_WIDTH[self.kind]
        if self.area == "DB":
            text = f"DB{self.db}.DB{width}{self.byte}"
        else:
            text = f"{self.area}{'' if width == 'X' else width}{self.byte}"
        if self.bit is not None:
            text += f".{self.bit}"
        default = _WIDTH_TYPE[width.lower()]
        # MD10 alone is machine data: the flag double word keeps its type
        suffix = "" if self.kind == default and (self.area, width) != ("M", "D") else self.kind
        if self.array:
            suffix += f"[{self.count}]"
        return f"{text}:{suffix}" if suffix else text

    @property
    def node_id(self) -> str | None:
        """The SINUMERIK OPC UA id (``/Plc/DB130.DBW0``); None for the peripheral area, which it lacks."""
        return None if self.area in ("PI", "PQ") else f"/Plc/{self}"


NodeName = NcNodeName | PlcNodeName


# ---------------------------------------------------------------------------------------------- forms
def node_paths(spec: VariableSpec) -> list[str]:
    """The node ids (without index) a catalogue row is served under; the first is the browse name."""
    area = NckArea(min(spec.areas))
    paths: list[str] = []
    if spec.path:
        paths.append(spec.path)
        if spec.path.startswith(_DRIVE_FOLDER):
            paths.append(_DRIVE_ALIAS + spec.path[len(_DRIVE_FOLDER):])
    number = spec.number.upper()
    if number[:2] in ("SD", "MD") and number[2:].isdigit():
        kind, sm = ("SEA", "S") if number.startswith("SD") else ("TEA", "M")
        paths.append(f"/NC/_N_{_AREA_WORD.get(area, 'NC')}_{kind}_ACX/${sm}{_AREA_LETTER.get(area, 'N')}_{spec.name}")
    if spec.name == "R":
        paths += ["/Channel/Parameter/R", "/Channel/Parameter/rpa"]  # rpa: the BTSS name
    if not paths:
        paths.append(f"/Nckemu/{_AREA_FOLDER.get(area, 'Nck')}/{spec.name}")
    return paths + list(spec.aliases)


def btss_base(spec: VariableSpec) -> str:
    """What the BTSS form writes before the brackets: the row's BTSS path, else its SD/MD number or name
    (nckemu's own ``/Nckemu/..`` and the NC-indexed ``/NC/..`` ids are node ids, not BTSS)."""
    for path in node_paths(spec):
        if not path.lower().startswith(("/nc/", "/nckemu/")):
            return path
    return short_name(spec)


def _unit_part(address: NckAddress) -> str:
    return f"u{address.unit}"


def display_btss(spec: VariableSpec, address: NckAddress) -> str:
    """The BTSS form, lines counted from 1: ``/Channel/Parameter/R[u1,5]``, ``R[u1,1,#5]``,
    ``/Tool/Compensation/cuttEdgeParam[u1,c7,3]``, ``SD43900[u4]``."""
    return f"{btss_base(spec)}[{','.join(_btss_parts(spec, address))}]"


def _btss_parts(spec: VariableSpec, address: NckAddress) -> list[str]:
    parts = [_unit_part(address)]
    if spec.columns > 1:
        parts.append(f"c{address.column}")
    if spec.lines > 1 or address.line != 1 or address.line_count > 1:
        parts.append(str(address.line))
    if address.line_count > 1:
        parts.append(f"#{address.line_count}")
    return parts


def display_node_id(spec: VariableSpec, address: NckAddress, namespace: int | None = 2) -> str:
    """The SINUMERIK OPC UA node id of an address (``ns=2;s=`` in front unless ``namespace`` is None):
    the BTSS path, or the ``/NC/`` id (line first, unit last), lines from 1 in both."""
    path = node_paths(spec)[0]
    if path.lower().startswith("/nc/"):
        parts = [str(address.line)] if spec.lines > 1 or address.line != 1 or address.line_count > 1 else []
        if address.line_count > 1:
            parts.append(f"#{address.line_count}")
        if spec.columns > 1:
            parts.append(f"c{address.column}")
        parts.append(_unit_part(address))
    else:
        parts = _btss_parts(spec, address)
    text = f"{path}[{','.join(parts)}]"
    return text if namespace is None else f"ns={namespace};s={text}"


@dataclass(frozen=True)
class IndexRanges:
    """A row's valid names as ranges: NC syntax (indices from 0; ``nc_index`` the same lines by index
    where ``nc`` names them by axis or spindle), BTSS (lines from 1), OPC UA node id."""

    nc: str
    btss: str
    node_id: str
    nc_index: str = ""
    indexed: bool = True  # has lines or columns to count (else only units differ)

    def __str__(self) -> str:
        nc = f"{self.nc} or {self.nc_index}" if self.nc_index else self.nc
        if not self.indexed:
            return f"{nc} (NC) or {self.btss} (BTSS)"
        return f"{nc} (NC, index from 0) or {self.btss} (BTSS, line from 1)"


def index_ranges(spec: VariableSpec) -> IndexRanges:
    """``R0..R99`` / ``/Channel/Parameter/R[u1,1..100]``; ``SD43900[AX1..AX31]`` / ``SD43900[u1..31]``;
    ``actSpeed[SP1..SP8]`` / ``/Channel/Spindle/actSpeed[u1,1..8]``. Units other than axes are not
    ranged (unit 1 is the default; a machine has as many channels as it has)."""
    axis = NckArea.A in spec.areas
    drive = bool(spec.areas & {NckArea.V, NckArea.H}) and not axis  # a drive's unit is the drive
    drive_letter = NckArea(min(spec.areas)).name
    last_column = spec.column + spec.columns - 1
    columns = [f"col{spec.column}..{last_column}"] if spec.columns > 1 else []
    kind = line_kind(spec)
    nc_index = ""
    if spec.name == "R" and spec.lines > 1:
        nc = f"R0..R{spec.lines - 1}"
    else:
        index = [f"0..{spec.lines - 1}"] if spec.lines > 1 else []
        rest = (["AX1..AX31"] if axis else [f"{drive_letter}1..{drive_letter}{MAX_UNIT}"] if drive else []) + columns
        if kind is not None:
            prefix = LINE_PREFIXES[kind]
            nc_index = f"{short_name(spec)}[{','.join(index + rest)}]"
            index = [f"{prefix}1..{prefix}{spec.lines}"]
        parts = index + rest
        nc = f"{short_name(spec)}[{','.join(parts)}]" if parts else short_name(spec)
    unit = f"u1..{MAX_UNIT}" if axis or drive else "u1"
    btss_parts = [unit] + ([f"c{spec.column}..{last_column}"] if spec.columns > 1 else []) + \
        ([f"1..{spec.lines}"] if spec.lines > 1 else [])
    btss = f"{btss_base(spec)}[{','.join(btss_parts)}]"
    path = node_paths(spec)[0]
    if path.lower().startswith("/nc/"):
        node_parts = ([f"1..{spec.lines}"] if spec.lines > 1 else []) + \
            ([f"c{spec.column}..{last_column}"] if spec.columns > 1 else []) + [unit]
    else:
        node_parts = btss_parts
    return IndexRanges(nc, btss, f"{path}[{','.join(node_parts)}]", nc_index, spec.lines > 1 or spec.columns > 1)


def realm_of(path: str) -> str:
    """The SINUMERIK access realm a path belongs to (State, Frame, Sea, Tea, Tool, Drive, Gud, Plc)."""
    lower = path.lower()
    if lower.startswith(("/plc", "/random/plc")):
        return "Plc"
    if lower.startswith("/nc/"):
        return "Sea" if "_sea_" in lower else "Gud" if "_gd" in lower else "Tea"
    if lower.startswith("/tool/"):
        return "Tool"
    if lower.startswith(("/drivevsa/", "/nckemu/drive/")):
        return "Drive"
    if "frame" in lower or "linshift" in lower:
        return "Frame"
    return "State"


@lru_cache(maxsize=16)
def _path_index(specs: tuple[VariableSpec, ...]) -> dict[str, VariableSpec]:
    return {path.lower(): spec for spec in specs for path in node_paths(spec)}


@lru_cache(maxsize=16)
def _name_index(specs: tuple[VariableSpec, ...]) -> dict[str, VariableSpec]:
    index: dict[str, VariableSpec] = {}
    for spec in specs:
        index.setdefault(spec.number.upper(), spec)
        index.setdefault(spec.name.upper(), spec)
    return index


def _table(specs: Sequence[VariableSpec] | None) -> tuple[VariableSpec, ...]:
    return tuple(specs) if specs is not None else load_table()


# ---------------------------------------------------------------------------------------------- parsing
def parse_name(text: str, specs: Sequence[VariableSpec] | None = None, *, node_ids_only: bool = False) -> NodeName:
    """Any form of the module docstring against ``specs`` (default: the built-in table); with
    ``node_ids_only`` only SINUMERIK OPC UA node ids (what the OPC UA face serves)."""
    if not isinstance(text, str) or len(text) > MAX_TEXT:
        raise NckNodeIdUnknown("not a name (not text, or too long)")
    source = text.strip()
    namespace = _NS.match(source)
    if namespace is not None:
        source, node_ids_only = source[namespace.end():], True
    if source.startswith("/"):
        return _parse_path(text, source, specs)
    if node_ids_only:
        raise NckNodeIdUnknown(f"{text!r} is not a SINUMERIK node id like /Channel/State/progStatus[u1]")
    return _parse_bare(text, source, _table(specs))


def _parse_path(text: str, source: str, specs: Sequence[VariableSpec] | None) -> NodeName:
    lower = source.lower()
    if lower.startswith(("/plc/", "/random/plc/")):
        return _parse_plc(text, lower.split("/plc/", 1)[1], node_id=True)
    match = _PATH.match(source)
    if match is None:
        raise NckNodeIdUnknown(f"{text!r} is not a SINUMERIK node id like /Channel/State/progStatus[u1]")
    path = match["path"].rstrip("/")
    table = _table(specs)
    spec = _path_index(table).get(path.lower())
    if spec is None:
        root = path.lower().split("/")[1] if len(path) > 1 else ""
        if root not in NC_ROOTS:
            raise NckNodeIdUnknown(f"{text!r}: no SINUMERIK namespace /{root}")
        if _NC_DATA.match(path.lower()) is not None or root != "nc":
            raise NckNodeNotConfigured(f"{path}: this machine has no such variable (nckemu vars lists them)")
        raise NckNodeIdUnknown(f"{text!r}: not an /NC/_N_<NC|CH|AX>_<SEA|TEA>_ACX/$.. id")
    return _resolve(text, spec, match["index"], "btss", realm_of(path))


def _parse_bare(text: str, source: str, table: tuple[VariableSpec, ...]) -> NodeName:
    numbered = _NUMBERED.match(source)
    if numbered is not None and "[" not in numbered["number"]:
        first = _name_index(table).get(numbered["number"].lstrip("$").upper())
        name = _parse_bare(text, numbered["rest"].strip(), table)
        # Rows of different areas may share a number (SSP3 is cmdSpeed in area N and in the channel):
        # the name decides which, as long as its row carries that number.
        if first is None or not isinstance(name, NcNodeName) or name.spec.number.upper() != first.number.upper():
            raise NckNodeIdUnknown(f"{text!r}: {numbered['number']!r} and {numbered['rest']!r} are not "
                                   "the number and name of one variable")
        return name
    match = _NAME.match(source)
    if match is not None:
        spec = _name_index(table).get(match["name"].upper())
        if spec is not None:
            return _resolve(text, spec, match["index"], _syntax_of(match["index"]), _realm(spec))
    short = _R_SHORT.match(source)
    r_spec = _name_index(table).get("R")
    if short is not None and r_spec is not None:
        extra = short["index"]
        if extra is not None and _syntax_of(extra) == "btss":
            line = int(short["number"]) + R_PARAMETER_LINE_OFFSET
            raise NckNodeIdUnknown(f"{text!r} mixes NC syntax (R{short['number']}) and BTSS (u): write "
                                   f"R{short['number']} or R[u1,{line}]")
        index = short["number"] + (f",{extra}" if extra and extra.strip() else "")
        return _resolve(text, r_spec, index, "nc", _realm(r_spec))
    plc = _PLC.match(source.lower().replace(" ", ""))
    if plc is not None:
        if plc["area"] == "m" and plc["width"] == "d" and plc["type"] is None:
            raise NckNodeIdUnknown(f"{text!r}: no machine data {source.upper()} in the catalogue (nckemu vars "
                                   f"'MD*' lists them); the flag double word is {source.upper()}:DWORD or "
                                   f"/Plc/{source.upper()}")
        return _parse_plc(text, source.lower(), node_id=False)
    if match is not None:
        raise NckNodeIdUnknown(f"{text!r}: unknown NCK variable {match['name']!r} (nckemu vars lists them), "
                               "and not an S7 address like DB130.DBW0, MB10, M5.0 or PIW420")
    raise NckNodeIdUnknown(f"{text!r} is not a name like SD43900[AX4], R4, /Channel/Parameter/R[u1,5] or "
                           "DB130.DBW0")


def _realm(spec: VariableSpec) -> str:
    return realm_of(node_paths(spec)[0])


def _syntax_of(index: str | None) -> str:
    """A bracket with a ``uN`` part is BTSS (lines from 1); any other is NC syntax (indices from 0)."""
    parts = [part.strip().lower() for part in (index or "").split(",")]
    return "btss" if any(len(p) > 1 and p[0] == "u" and p[1:].isdigit() for p in parts) else "nc"


def _where(spec: VariableSpec) -> str:
    return "/".join(NckArea(area).name for area in sorted(spec.areas))


def _resolve(text: str, spec: VariableSpec, index: str | None, syntax: str, realm: str) -> NcNodeName:
    """The bracket ``index`` of ``spec`` in ``syntax``: "nc" (NC syntax) or "btss" (BTSS and every OPC UA
    node id: lines from 1)."""
    parts = [part.strip().lower() for part in (index or "").split(",")]
    if parts == [""]:
        parts = []
    tokens: list[tuple[str, int]] = []
    for part in parts:
        found = _PART.match(part)
        if found is None:
            if not part:
                raise NckNodeIdUnknown(f"{text!r}: empty index part")
            if part.startswith("-"):
                raise NckNodeNotConfigured(f"{text!r}: no negative index: {spec.name} takes {index_ranges(spec)}")
            raise NckNodeIdUnknown(f"{text!r}: cannot read index part {part!r} ({_vocabulary(syntax)})")
        if len(found["number"]) > MAX_DIGITS:
            raise NckNodeIdUnknown(f"{text!r}: {part!r} is too long a number")
        tokens.append((found["prefix"], int(found["number"])))
    if syntax == "nc":
        area, unit, column, line, count, array = _resolve_nc(text, spec, tokens)
    else:
        area, unit, column, line, count, array = _resolve_btss(text, spec, tokens)
    _check(text, spec, area, unit, column, line, count, syntax)
    return NcNodeName(spec, area, unit, line, count, column, realm, array)


def _vocabulary(syntax: str) -> str:
    if syntax == "nc":
        return ("NC syntax: an index from 0, AXn, SPn, Cn/Nn/Bn/Tn unit, colN column, xN lines, lN line; "
                "a uN part makes it BTSS")
    return "BTSS: [uN, line], [uN, first, last], [uN, first, #count], cN column; lines from 1"


def _resolve_nc(text: str, spec: VariableSpec,
                tokens: list[tuple[str, int]]) -> tuple[int, int, int, int, int, bool]:
    area, unit, column, count = min(spec.areas), 1, spec.column, 1
    line: int | None = None
    unit_given = column_given = False
    kind = line_kind(spec)

    def set_line(value: int, what: str) -> None:
        nonlocal line
        if line is not None:
            raise NckNodeIdUnknown(f"{text!r}: two lines ({what} and another): {spec.name} takes "
                                   f"{index_ranges(spec)}")
        line = value

    def set_unit(new_area: int, value: int) -> None:
        nonlocal area, unit, unit_given
        if unit_given:
            raise NckNodeIdUnknown(f"{text!r}: two units")
        area, unit, unit_given = new_area, value, True

    for prefix, number in tokens:
        if prefix == "":
            set_line(number + 1, f"index {number}")
        elif prefix == "l":
            set_line(number, f"line {number}")
        elif prefix == "ax":
            if NckArea.A in spec.areas:
                if not 1 <= number <= MAX_UNIT:
                    raise NckNodeNotConfigured(f"{text!r}: no axis {number}: axes are AX1..AX{MAX_UNIT}")
                set_unit(NckArea.A, number)
            elif kind == "machine axis":
                set_line(number, f"AX{number}")
            else:
                raise NckNodeNotConfigured(f"{text!r}: {spec.name} is not per axis: it takes {index_ranges(spec)}")
        elif prefix == "sp":
            if kind != "spindle":
                raise NckNodeNotConfigured(f"{text!r}: {spec.name} is not per spindle: it takes "
                                           f"{index_ranges(spec)}")
            set_line(number, f"SP{number}")
        elif prefix in NC_UNIT_LETTERS:
            wanted = NC_UNIT_LETTERS[prefix]
            if wanted not in spec.areas:
                letter = "AX" if NckArea.A in spec.areas else NckArea(min(spec.areas)).name
                raise NckNodeNotConfigured(f"{text!r}: {spec.name} is an area {_where(spec)} variable, not "
                                           f"{wanted.name}: its unit is written {letter}n")
            set_unit(wanted, number)
        elif prefix == "col":
            column, column_given = number, True
        elif prefix == "x":
            count = number
        elif prefix in ("u", "#"):
            raise NckNodeIdUnknown(f"{text!r}: {prefix!r} belongs to BTSS: write [uN, first, #count]")
        else:
            raise NckNodeIdUnknown(f"{text!r}: cannot read index part {prefix}{number} "
                                   f"({_vocabulary('nc')})")
    if spec.columns > 1 and not column_given:
        # as an axis variable needs its axis: the column is the tool, never silently the first one
        raise NckNodeNotConfigured(f"{text!r}: {spec.name} needs its {_column_word(spec)}: colN, e.g. "
                                   f"{spec.name}[2,T1,col{spec.column}] ({_column_meaning(spec)}); it takes "
                                   f"{index_ranges(spec)}")
    return area, unit, column, 1 if line is None else line, count, count > 1


def _column_word(spec: VariableSpec) -> str:
    return "tool" if spec.name == TOOL_OFFSETS else "column"


def _column_meaning(spec: VariableSpec) -> str:
    """What each index of a row with several columns means (the tool offsets: TO unit, tool, edge and
    parameter; catalogue/edges.py)."""
    if spec.name == TOOL_OFFSETS:
        return ("index (D-1)*numCuttEdgeParams + P-1 for parameter P of edge D, Tn the TO unit, colN the "
                "tool's T number")
    return f"colN the column {spec.column}..{spec.column + spec.columns - 1}"


def _resolve_btss(text: str, spec: VariableSpec, tokens: list[tuple[str, int]]) -> tuple[int, int, int, int, int, bool]:
    unit, column = 1, spec.column
    numbers: list[int] = []
    count: int | None = None
    for prefix, number in tokens:
        if prefix == "u":
            unit = number
        elif prefix == "c":
            column = number
        elif prefix == "#":
            count = number
        elif prefix == "":
            numbers.append(number)
        else:
            raise NckNodeIdUnknown(f"{text!r}: {prefix}{number} is NC syntax; in BTSS write "
                                   f"{_vocabulary('btss')}")
    if len(numbers) > 2 or (count is not None and len(numbers) != 1):
        raise NckNodeIdUnknown(f"{text!r}: expected [uN, line], [uN, first, last] or [uN, first, #count]")
    if spec.columns > 1 and tokens and not any(prefix == "c" for prefix, _ in tokens):
        raise NckNodeNotConfigured(f"{text!r}: {spec.name} needs its {_column_word(spec)}: cN, e.g. "
                                   f"{btss_base(spec)}[u1,c{spec.column},3] ({_column_meaning(spec)})")
    line = numbers[0] if numbers else 1
    if len(numbers) == 2:
        count = numbers[1] - line + 1
    array = count is not None
    return min(spec.areas), unit, column, line, 1 if count is None else count, array


def _check(text: str, spec: VariableSpec, area: int, unit: int, column: int, line: int, count: int,
           syntax: str) -> None:
    if count < 1 or line < 1:
        if syntax == "btss" and line < 1:
            raise NckNodeNotConfigured(f"{text!r}: BTSS lines count from 1: {spec.name} takes {index_ranges(spec)}")
        raise NckNodeNotConfigured(f"{text!r}: empty or negative range: {spec.name} takes {index_ranges(spec)}")
    if count > 0xFF:
        raise NckNodeNotConfigured(f"{text!r}: at most 255 lines in one item")
    if line + count - 1 > spec.lines:
        if spec.lines == 1:
            raise NckNodeNotConfigured(f"{text!r}: {spec.name} has one line, no index: it takes "
                                       f"{index_ranges(spec)}")
        raise NckNodeNotConfigured(f"{text!r}: {_asked(spec, line, count, syntax)} outside {spec.name}: it takes "
                                   f"{index_ranges(spec)}")
    if not spec.column <= column < spec.column + spec.columns:
        raise NckNodeNotConfigured(f"{text!r}: {spec.name} has columns {spec.column}.."
                                   f"{spec.column + spec.columns - 1} ({_column_meaning(spec)})")
    if not 1 <= unit <= MAX_UNIT:
        what = "TO unit" if spec.name == TOOL_OFFSETS else "unit"
        raise NckNodeNotConfigured(f"{text!r}: {what} {unit} outside 1..{MAX_UNIT} (units count from 1): "
                                   f"{spec.name} takes {index_ranges(spec)}")
    if area not in spec.areas:
        raise NckNodeNotConfigured(f"{text!r}: {spec.name} is an area {_where(spec)} variable")


def _asked(spec: VariableSpec, line: int, count: int, syntax: str) -> str:
    last = line + count - 1
    if syntax == "btss":
        return f"line {line}" if count == 1 else f"lines {line}..{last}"
    kind = line_kind(spec)
    if kind is not None and syntax == "nc":
        prefix = LINE_PREFIXES[kind]
        return f"{prefix}{line}" if count == 1 else f"{prefix}{line}..{prefix}{last}"
    return f"index {line - 1}" if count == 1 else f"indices {line - 1}..{last - 1}"


def _parse_plc(text: str, lower: str, *, node_id: bool) -> PlcNodeName:
    """``lower``: the address after ``/Plc/`` (node ids) or the whole S7 name, lower case."""
    example = "/Plc/DB5.DBW2, /Plc/M5.0 or /Plc/DB2.DBD0:REAL[10]" if node_id else \
        "DB130.DBW0, DB1.DBX2.3, MB10, M5.0, PIW420 or DB2.DBD0:REAL"
    match = _PLC.match(lower.replace(" ", ""))
    if match is None:
        raise NckNodeIdUnknown(f"{text!r} is not a PLC address like {example}")
    if match["db"] is not None:
        area, db, width = "DB", int(match["db"]), match["dbwidth"]
    else:
        letters = _GERMAN.get(match["area"], match["area"])
        area, db, width = letters.upper(), 0, match["width"] or "x"
        if area in ("PI", "PQ"):
            if node_id:
                raise NckNodeIdUnknown(f"{text!r}: the OPC UA face serves /Plc/ I, Q, M and DB; read the "
                                       f"peripheral area over S7 ({lower.upper()})")
            if width == "x":
                raise NckNodeIdUnknown(f"{text!r}: the peripheral area is read by byte, word or double word "
                                       f"({area}B, {area}W, {area}D), not by bit")
    byte = int(match["byte"])
    bit = int(match["bit"]) if match["bit"] is not None else None
    if bit is not None and bit > 7:
        raise NckNodeNotConfigured(f"{text!r}: bit {bit}: bits are 0..7")
    if (width == "x") != (bit is not None):
        raise NckNodeIdUnknown(f"{text!r}: a bit needs .0...7 (M5.0, DB1.DBX2.3), a byte/word/double word none")
    named = match["type"]
    if named is not None and named not in _PLC_TYPES:
        raise NckNodeIdUnknown(f"{text!r}: unknown PLC type {named!r} (BOOL, BYTE, CHAR, WORD, INT, DWORD, DINT, "
                               "REAL, STRING)")
    kind = _PLC_TYPES.get(named or "") or _WIDTH_TYPE[width]
    if kind != "STRING" and kind != "BOOL" and PLC_TYPE_BYTES[kind] != PLC_TYPE_BYTES[_WIDTH_TYPE[width]]:
        raise NckNodeIdUnknown(f"{text!r}: {kind} does not fit a {_WIDTH_TYPE[width]}")
    if kind == "BOOL" and width != "x":
        raise NckNodeIdUnknown(f"{text!r}: a BOOL is a bit (M5.0, DB1.DBX2.3)")
    if kind == "STRING" and width != "b":
        raise NckNodeIdUnknown(f"{text!r}: a STRING starts at a byte (DBB)")
    array = match["count"] is not None
    count = int(match["count"]) if array else 1
    if not 1 <= count <= MAX_PLC_ITEMS or (kind in ("STRING", "BOOL") and array):
        raise NckNodeIdUnknown(f"{text!r}: array length 1..{MAX_PLC_ITEMS} of a byte/word/double word type")
    if byte > MAX_PLC_BYTE or db > 0xFFFF:
        raise NckNodeNotConfigured(f"{text!r}: address outside the PLC's memory (bytes 0..{MAX_PLC_BYTE}, "
                                   "DB1..65535)")
    return PlcNodeName(area, db, byte, bit, kind, count, array)
