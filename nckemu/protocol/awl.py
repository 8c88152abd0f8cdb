"""NCVar-selector address DB sources (STEP 7 ``DATA_BLOCK`` with one STRUCT per variable).

Each STRUCT holds the 10 bytes GET/PUT send: SYNTAX_ID, bereich_u_einheit (area << 5 | unit),
spalte (column), zeile (line), bausteintyp (module), ZEILENANZAHL (line count), and the two bytes
only the client uses: typ (data type) and laenge (length in bytes).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from .addresses import NckAddress, NckType
from .errors import NckConfigError

FIELDS = ("syntax_id", "bereich_u_einheit", "spalte", "zeile", "bausteintyp", "zeilenanzahl", "typ", "laenge")
_FIELD_TYPES = {"syntax_id": "BYTE", "bereich_u_einheit": "BYTE", "spalte": "WORD", "zeile": "WORD",
                "bausteintyp": "BYTE", "zeilenanzahl": "BYTE", "typ": "BYTE", "laenge": "BYTE"}
_STRUCT_START = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*:\s*STRUCT\s*;?$", re.IGNORECASE)
_FIELD = re.compile(r"^(?P<field>[A-Za-z_]+)\s*:\s*(?P<type>BYTE|WORD)\s*(?::=\s*(?P<value>[^;]+))?;?$",
                    re.IGNORECASE)
_DB_HEADER = re.compile(r"^DATA_BLOCK\s+DB\s*(?P<number>\d+)", re.IGNORECASE)


@dataclass(frozen=True)
class NcVarEntry:
    name: str
    address: NckAddress
    nck_type: NckType
    length: int


@dataclass(frozen=True)
class NcVarDb:
    number: int | None
    entries: tuple[NcVarEntry, ...]

    def by_name(self, name: str) -> NcVarEntry:
        for entry in self.entries:
            if entry.name.upper() == name.upper():
                return entry
        raise KeyError(name)


def parse_step7_number(text: str) -> int:
    """``B#16#82``, ``W#16#AB7C``, ``16#1F``, ``2#101``, ``B#(1, 2)`` is not supported, decimals."""
    value = text.strip().upper().replace("_", "")
    match = re.fullmatch(r"(?:[BW]#|DW#)?(?:(16|2|8)#)?([0-9A-F]+)", value)
    if match is None:
        raise ValueError(text)
    base = int(match.group(1) or 10)
    return int(match.group(2), base)


def parse_ncvar_db(text: str, source: str = "<string>") -> NcVarDb:
    number: int | None = None
    entries: list[NcVarEntry] = []
    current: str | None = None
    current_line = 0
    fields: dict[str, int] = {}
    for line_number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("//", 1)[0].strip().strip("`").strip()
        if not line:
            continue
        header = _DB_HEADER.match(line)
        if header:
            number = int(header["number"])
            continue
        upper = line.upper()
        if upper.startswith(("VERSION", "TITLE", "AUTHOR", "FAMILY", "NAME", "BEGIN", "END_DATA_BLOCK",
                             "{", "KNOW_HOW")) or upper in ("STRUCT", "STRUCT;"):
            continue
        start = _STRUCT_START.match(line)
        if start:
            if current is not None:
                raise NckConfigError(f"STRUCT {start['name']} begins inside {current}", path=source,
                                     line=line_number)
            current, current_line, fields = start["name"], line_number, {}
            continue
        if upper.rstrip(";").strip() == "END_STRUCT":
            if current is None:
                continue  # the end of the outer STRUCT
            missing = [f for f in FIELDS if f not in fields]
            if missing:
                raise NckConfigError(f"{current}: field {missing[0]} missing", path=source, line=line_number)
            try:
                nck_type = NckType(fields["typ"])
            except ValueError:
                raise NckConfigError(f"{current}: typ 0x{fields['typ']:02X} is not an NCK data type",
                                     path=source, line=current_line, field="typ") from None
            try:
                address = NckAddress.from_area_unit(fields["bereich_u_einheit"], fields["spalte"], fields["zeile"],
                                                    fields["bausteintyp"], fields["zeilenanzahl"], fields["syntax_id"])
            except ValueError as exc:
                raise NckConfigError(f"{current}: {exc}", path=source, line=current_line) from None
            entries.append(NcVarEntry(current, address, nck_type, fields["laenge"]))
            current = None
            continue
        field = _FIELD.match(line)
        if field is None or current is None:
            raise NckConfigError(f"cannot read {raw.strip()!r}", path=source, line=line_number)
        name = field["field"].lower()
        if name not in _FIELD_TYPES:
            raise NckConfigError(f"unknown field {field['field']!r}", path=source, line=line_number,
                                 field=field["field"])
        if field["type"].upper() != _FIELD_TYPES[name]:
            raise NckConfigError(f"{field['field']} must be a {_FIELD_TYPES[name]}", path=source,
                                 line=line_number, field=field["field"])
        try:
            value = parse_step7_number(field["value"]) if field["value"] else 0
        except ValueError:
            raise NckConfigError(f"{field['value'].strip()!r} is not a number", path=source, line=line_number,
                                 field=field["field"]) from None
        limit = 0xFFFF if _FIELD_TYPES[name] == "WORD" else 0xFF
        if value > limit:
            raise NckConfigError(f"{value} does not fit a {_FIELD_TYPES[name]}", path=source, line=line_number,
                                 field=field["field"])
        fields[name] = value
    if current is not None:
        raise NckConfigError(f"STRUCT {current} is not closed", path=source, line=current_line)
    if not entries:
        raise NckConfigError("no NCVar-selector entries found", path=source)
    return NcVarDb(number, tuple(entries))


def render_ncvar_db(db: NcVarDb) -> str:
    """A source that parses back to the same entries."""
    lines = [f"DATA_BLOCK DB {db.number if db.number is not None else 1}", "VERSION : 0.1", "", "STRUCT"]
    for entry in db.entries:
        a = entry.address
        lines += [f"{entry.name} : STRUCT",
                  f"  SYNTAX_ID : BYTE := B#16#{a.syntax_id:02X};",
                  f"  bereich_u_einheit : BYTE := B#16#{a.area_unit:02X};",
                  f"  spalte : WORD := W#16#{a.column:04X};",
                  f"  zeile : WORD := W#16#{a.line:X};",
                  f"  bausteintyp : BYTE := B#16#{a.module:02X};",
                  f"  ZEILENANZAHL : BYTE := B#16#{a.line_count:X};",
                  f"  typ : BYTE := B#16#{int(entry.nck_type):X};",
                  f"  laenge : BYTE := B#16#{entry.length:X};",
                  "END_STRUCT ;"]
    lines += ["END_STRUCT ;", "BEGIN", "END_DATA_BLOCK", ""]
    return "\n".join(lines)
