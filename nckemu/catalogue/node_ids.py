"""SINUMERIK OPC UA node ids (the ``SinumerikVarProvider`` namespace) to typed catalogue names.

Accepted forms (the controller's own; spaces inside brackets allowed, names case-insensitive):
  /Channel/State/progStatus          BTSS path: unit 1, line 1
  /Channel/Parameter/R[u1,10]        unit 1, line 10 (BTSS lines are the wire lines)
  /Nck/Spindle/driveLoad[u1, 3]      spaces allowed
  /Channel/Parameter/R[u1,1,5]       lines 1..5 (an array)      R[u1,1,#5]: 5 lines from line 1
  /Tool/Compensation/cuttEdgeParam[u1, c2, 3, 5]   column (T number) 2, lines 3..5
  /NC/_N_CH_TEA_ACX/$MC_CHAN_NAME[u1]               machine data (TEA) of a channel
  /NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]     setting data (SEA) of axis 4 (scheme inferred)
  /NC/_N_AX_TEA_ACX/$MA_ENC_COMP_ENABLE[1, u4]      a number in an /NC/ id: 0-based array index
  /Plc/M5.0  /Plc/MB6  /Plc/DB5.DBW2  /Plc/DB8.DBB2:STRING  /Plc/DB8.DBW2:[10]  /Plc/DB2.DBD0:REAL[10]
  (``/Random/Plc/...`` is the same as ``/Plc/...``)
Catalogue rows without a BTSS path and without an SD/MD number are served as ``/Nckemu/<area>/<name>``.

Two typed errors: ``NckNodeIdUnknown`` (malformed, or no SINUMERIK namespace) and ``NckNodeNotConfigured``
(well formed, but this machine's table lacks the variable or the index lies outside it).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

from nckemu.errors import NckNodeIdUnknown, NckNodeNotConfigured
from nckemu.protocol.addresses import NckAddress, NckArea

from .table import VariableSpec, load_table

MAX_TEXT = 400            # longer ids are not read at all (the controller's paths are short)
MAX_PLC_ITEMS = 1024      # array length of a PLC id
MAX_PLC_BYTE = 0xFFFF

_AREA_WORD = {NckArea.N: "NC", NckArea.B: "NC", NckArea.C: "CH", NckArea.A: "AX", NckArea.T: "NC"}
_AREA_LETTER = {NckArea.N: "N", NckArea.B: "N", NckArea.C: "C", NckArea.A: "A", NckArea.T: "N"}
_AREA_FOLDER = {NckArea.N: "Nck", NckArea.B: "Bag", NckArea.C: "Channel", NckArea.A: "Axis", NckArea.T: "Tool",
                NckArea.V: "Drive", NckArea.H: "Drive", NckArea.M: "Mmc"}
# First path segments of the controller's NC namespace: a well-formed id under one of them that this
# machine's table lacks is "not configured", anything else "unknown".
NC_ROOTS = frozenset({"nck", "channel", "bag", "tool", "axis", "drive", "nc", "nckemu", "hmi", "geometricaxis",
                      "drivevsa"})
# Public OPC UA collectors read a motor module's parameters both as /DriveVsa/Drive/r0035[uN] and as
# /DriveVsa/DC/R0026[uN] (docs/assumptions.md): the second is served as another name of the first.
_DRIVE_FOLDER, _DRIVE_ALIAS = "/DriveVsa/Drive/", "/DriveVsa/DC/"

_PATH = re.compile(r"^(?P<path>/[A-Za-z0-9_/$]+?)\s*(?:\[(?P<index>[^\[\]]*)\])?$")
_NC_DATA = re.compile(r"^/nc/_n_(?P<area>nc|ch|ax)_(?P<kind>sea|tea)_acx/\$(?P<sm>[sm])(?P<letter>[nca])_"
                      r"(?P<name>[a-z0-9_]+)$")
_PLC = re.compile(
    r"^(?:/random)?/plc/(?:db(?P<db>\d{1,5})\.db(?P<dbwidth>[xbwd])|(?P<area>[ieqam])(?P<width>[xbwd]?))"
    r"(?P<byte>\d{1,5})(?:\.(?P<bit>[0-7]))?(?::(?P<type>[a-z]*)(?:\[(?P<count>\d{1,5})\])?)?$")
_PLC_TYPES = {"": None, "bool": "BOOL", "byte": "BYTE", "char": "BYTE", "word": "WORD", "int": "INT",
              "dword": "DWORD", "dint": "DINT", "real": "REAL", "string": "STRING"}
_WIDTH_TYPE = {"x": "BOOL", "b": "BYTE", "w": "WORD", "d": "DWORD"}
PLC_TYPE_BYTES = {"BOOL": 1, "BYTE": 1, "WORD": 2, "INT": 2, "DWORD": 4, "DINT": 4, "REAL": 4}
_GERMAN = {"e": "i", "a": "q"}


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


@dataclass(frozen=True)
class PlcNodeName:
    """PLC memory: area "I", "Q", "M" or "DB"; ``kind`` the element type; ``count`` elements (array if
    ``array``). A STRING is an S7 string (max length, length, characters) read whole."""

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


NodeName = NcNodeName | PlcNodeName


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
        paths.append("/Channel/Parameter/R")
    if not paths:
        paths.append(f"/Nckemu/{_AREA_FOLDER.get(area, 'Nck')}/{spec.name}")
    return paths


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


def parse_node_id(text: str, specs: Sequence[VariableSpec] | None = None) -> NodeName:
    """A SINUMERIK node id (see the module docstring) against ``specs`` (default: the built-in table)."""
    if not isinstance(text, str) or len(text) > MAX_TEXT:
        raise NckNodeIdUnknown("not a SINUMERIK node id (not text, or too long)")
    source = text.strip()
    lower = source.lower()
    if lower.startswith(("/plc/", "/random/plc/")):
        return _parse_plc(source, lower)
    match = _PATH.match(source)
    if match is None:
        raise NckNodeIdUnknown(f"{text!r} is not a SINUMERIK node id like /Channel/State/progStatus[u1]")
    path = match["path"].rstrip("/")
    root = path.lower().split("/")[1] if "/" in path[1:] or len(path) > 1 else ""
    if root not in NC_ROOTS:
        raise NckNodeIdUnknown(f"{text!r}: no SINUMERIK namespace /{root}")
    table = tuple(specs) if specs is not None else load_table()
    spec = _path_index(table).get(path.lower())
    if spec is None:
        data = _NC_DATA.match(path.lower())
        if data is not None or root != "nc":
            raise NckNodeNotConfigured(f"{path}: this machine has no such variable")
        raise NckNodeIdUnknown(f"{text!r}: not an /NC/_N_<NC|CH|AX>_<SEA|TEA>_ACX/$.. id")
    return _nc_name(text, path, spec, match["index"])


def _nc_name(text: str, path: str, spec: VariableSpec, index: str | None) -> NcNodeName:
    area = min(spec.areas)
    unit, column = 1, spec.column
    numbers: list[int] = []
    count: int | None = None
    machine_data = path.lower().startswith("/nc/")
    for part in [p.strip() for p in (index or "").split(",")]:
        lower = part.lower()
        if not lower and index is not None and index.strip():
            raise NckNodeIdUnknown(f"{text!r}: empty index part")
        if not lower:
            continue
        if lower[0] in "uc" and lower[1:].isdigit() and len(lower) <= 6:
            if lower[0] == "u":
                unit = int(lower[1:])
            else:
                column = int(lower[1:])
        elif lower.startswith("#") and lower[1:].isdigit() and len(lower) <= 6:
            count = int(lower[1:])
        elif lower.isdigit() and len(lower) <= 6:
            numbers.append(int(lower))
        else:
            raise NckNodeIdUnknown(f"{text!r}: cannot read index part {part!r}")
    if len(numbers) > 2 or (count is not None and len(numbers) != 1):
        raise NckNodeIdUnknown(f"{text!r}: expected [uN, line], [uN, first, last] or [uN, first, #count]")
    line = (numbers[0] + 1 if machine_data else numbers[0]) if numbers else 1
    if len(numbers) == 2:
        last = numbers[1] + 1 if machine_data else numbers[1]
        count = last - line + 1
    array = count is not None
    count = 1 if count is None else count
    if count < 1 or line < 1:
        raise NckNodeNotConfigured(f"{text!r}: empty or negative range")
    if line + count - 1 > spec.lines:
        raise NckNodeNotConfigured(f"{text!r}: {spec.name} has lines 1..{spec.lines}")
    if not spec.column <= column < spec.column + spec.columns:
        raise NckNodeNotConfigured(f"{text!r}: {spec.name} has columns {spec.column}..{spec.column + spec.columns - 1}")
    if not 0 <= unit <= 31:
        raise NckNodeNotConfigured(f"{text!r}: unit {unit} does not exist")
    return NcNodeName(spec, area, unit, line, count, column, realm_of(path), array)


def _parse_plc(text: str, lower: str) -> PlcNodeName:
    match = _PLC.match(lower.replace(" ", ""))
    if match is None:
        raise NckNodeIdUnknown(f"{text!r} is not a PLC id like /Plc/DB5.DBW2, /Plc/M5.0 or /Plc/DB2.DBD0:REAL[10]")
    if match["db"] is not None:
        area, db, width = "DB", int(match["db"]), match["dbwidth"]
    else:
        area, db, width = _GERMAN.get(match["area"], match["area"]).upper(), 0, match["width"] or "x"
    byte = int(match["byte"])
    bit = int(match["bit"]) if match["bit"] is not None else None
    if (width == "x") != (bit is not None):
        raise NckNodeIdUnknown(f"{text!r}: a bit needs .0...7 (M5.0, DB1.DBX2.3), a byte/word/double word none")
    named = match["type"]
    if named is not None and named not in _PLC_TYPES:
        raise NckNodeIdUnknown(f"{text!r}: unknown PLC type {named!r}")
    kind = _PLC_TYPES.get(named or "") or _WIDTH_TYPE[width]
    if kind != "STRING" and kind != "BOOL" and PLC_TYPE_BYTES[kind] != PLC_TYPE_BYTES[_WIDTH_TYPE[width]]:
        raise NckNodeIdUnknown(f"{text!r}: {kind} does not fit a {_WIDTH_TYPE[width]}")
    if kind == "STRING" and width != "b":
        raise NckNodeIdUnknown(f"{text!r}: a STRING starts at a byte (DBB)")
    array = match["count"] is not None
    count = int(match["count"]) if array else 1
    if not 1 <= count <= MAX_PLC_ITEMS or (kind in ("STRING", "BOOL") and array):
        raise NckNodeIdUnknown(f"{text!r}: array length 1..{MAX_PLC_ITEMS} of a byte/word/double word type")
    if byte > MAX_PLC_BYTE or db > 0xFFFF:
        raise NckNodeNotConfigured(f"{text!r}: address outside the PLC's memory")
    return PlcNodeName(area, db, byte, bit, kind, count, array)
