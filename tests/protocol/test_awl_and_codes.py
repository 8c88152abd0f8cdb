"""NCVar-selector address DB sources, and the error-code texts."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.catalogue.names import as_variable
from nckemu.errors import NckConfigError
from nckemu.protocol.addresses import NckAddress, NckType
from nckemu.protocol.awl import NcVarDb, NcVarEntry, parse_ncvar_db, render_ncvar_db
from nckemu.protocol.codes import describe_header_error, describe_return_code

FIXTURE = Path(__file__).resolve().parents[2] / "fixtures" / "awl" / "db140_tc_addresses.awl"

# The structure of seed 000's DB130 (its three entries), written out here for the test.
SEED000_STYLE = """DATA_BLOCK DB 130
VERSION : 0.0
STRUCT
TEMP_COMP_ABS_VALUE:
STRUCT
SYNTAX_ID : BYTE := B#16#82;
bereich_u_einheit :byte := B#16#64;
spalte :word := W#16#AB7C;
zeile :word := W#16#1;
bausteintyp :byte := B#16#16;
ZEILENANZAHL : BYTE := B#16#1;
typ :byte := B#16#F;
laenge :byte := B#16#8;
END_STRUCT ;
TEMP_COMP_REF_POSITION:
STRUCT
SYNTAX_ID : BYTE := B#16#82;
bereich_u_einheit :byte := B#16#64;
spalte :word := W#16#AB90;
zeile :word := W#16#1;
bausteintyp :byte := B#16#16;
ZEILENANZAHL : BYTE := B#16#1;
typ :byte := B#16#F;
laenge :byte := B#16#8;
END_STRUCT ;
END_STRUCT ;
BEGIN
END_DATA_BLOCK
"""


def test_seed000_style_source() -> None:
    db = parse_ncvar_db(SEED000_STYLE.replace("TEMP_COMP_ABS_VALUE:\nSTRUCT", "TEMP_COMP_ABS_VALUE : STRUCT")
                        .replace("TEMP_COMP_REF_POSITION:\nSTRUCT", "TEMP_COMP_REF_POSITION : STRUCT"))
    assert db.number == 130
    assert db.by_name("TEMP_COMP_ABS_VALUE").address == NckAddress(3, 4, 0xAB7C, 1, 0x16, 1)
    assert db.by_name("TEMP_COMP_REF_POSITION").address.column == 43920
    assert db.entries[0].nck_type == NckType.REAL8 and db.entries[0].length == 8


def test_fixture_entries_feed_the_client() -> None:
    db = parse_ncvar_db(FIXTURE.read_text(), str(FIXTURE))
    assert [e.name for e in db.entries] == ["Z_K0", "Z_SLOPE", "Z_P0", "R10", "PROGRAM"]
    program = as_variable(db.by_name("PROGRAM"))
    assert program.nck_type == NckType.STRING and program.length == 32


@pytest.mark.parametrize(("broken", "line"), [
    ("spalte : WORD := W#16#XYZ;", 11),
    ("spalte : BYTE := B#16#1;", 11),
    ("farbe : BYTE := B#16#1;", 11),
])
def test_malformed_lines_are_named(broken: str, line: int) -> None:
    text = FIXTURE.read_text().splitlines()
    assert text[line - 1].strip().startswith("spalte")
    text[line - 1] = broken
    with pytest.raises(NckConfigError, match=f"db140.awl, line {line}"):
        parse_ncvar_db("\n".join(text), "db140.awl")


def test_missing_field_and_unclosed_struct() -> None:
    text = FIXTURE.read_text()
    with pytest.raises(NckConfigError, match="laenge missing"):
        parse_ncvar_db(text.replace("  laenge : BYTE := B#16#8;\n", "", 1), "x.awl")
    with pytest.raises(NckConfigError, match="not closed"):
        parse_ncvar_db(text.rsplit("END_STRUCT ;", 2)[0], "x.awl")


entries = st.builds(
    NcVarEntry, name=st.from_regex(r"[A-Z][A-Z0-9_]{0,15}", fullmatch=True),
    address=st.builds(NckAddress, area=st.integers(0, 7), unit=st.integers(0, 31), column=st.integers(0, 0xFFFF),
                      line=st.integers(0, 0xFFFF), module=st.integers(0, 255), line_count=st.integers(0, 255)),
    nck_type=st.sampled_from(list(NckType)), length=st.integers(0, 255))


@given(st.integers(1, 9999), st.lists(entries, min_size=1, max_size=5))
def test_render_then_parse_round_trip(number: int, items: list[NcVarEntry]) -> None:
    db = NcVarDb(number, tuple(items))
    assert parse_ncvar_db(render_ncvar_db(db)) == db


def test_code_texts() -> None:
    assert describe_return_code(0x0A) == "object does not exist (0x0A)"
    assert describe_header_error(0x85, 0x00) == "wrong frames (0x8500)"
    assert "0x1234" in describe_header_error(0x12, 0x34)
