"""The one address grammar (catalogue/grammar.py, docs/addresses.md): every form a user may type reads
back from its canonical display to the same address, and NC syntax (indices from 0), BTSS (lines from 1)
and the OPC UA node id of one variable name one address."""

from __future__ import annotations

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from nckemu.catalogue.grammar import (
    PLC_TYPE_BYTES,
    NcNodeName,
    PlcNodeName,
    btss_base,
    display_btss,
    display_node_id,
    parse_name,
)
from nckemu.catalogue.names import parse_item, parse_variable
from nckemu.catalogue.table import LINE_PREFIXES, display_name, line_kind, load_table, short_name
from nckemu.errors import NckConfigError, NckNodeIdError
from nckemu.protocol.addresses import NckAddress, NckArea

SPECS = load_table()


@st.composite
def addresses(draw: st.DrawFn) -> tuple[object, NckAddress]:
    """A catalogue row and a valid address in it: a unit 1..31, a column of the row, lines inside it."""
    spec = draw(st.sampled_from(SPECS))
    line = draw(st.integers(1, spec.lines))
    count = draw(st.integers(1, min(255, spec.lines - line + 1)))
    column = draw(st.integers(spec.column, spec.column + spec.columns - 1))
    unit = draw(st.integers(1, 31))
    return spec, NckAddress(min(spec.areas), unit, column, line, spec.module, count)


def _nc_unit(spec: object, address: NckAddress) -> str:
    return f"AX{address.unit}" if address.area == NckArea.A else f"{NckArea(address.area).name}{address.unit}"


@given(addresses())
def test_each_form_reads_back_from_its_display(case: tuple[object, NckAddress]) -> None:
    spec, address = case
    nc, btss, node_id = display_name(spec, address), display_btss(spec, address), display_node_id(spec, address)
    for text in (nc, btss, node_id, display_node_id(spec, address, namespace=None), f"  {nc.lower()} "):
        name = parse_name(text)
        assert isinstance(name, NcNodeName) and name.spec is spec, text
        assert name.address == address, text
        # the display of what was read is the display it was read from
        assert str(name) == nc
        assert display_btss(spec, name.address) == btss
        assert display_node_id(spec, name.address) == node_id


@given(addresses(), st.booleans(), st.booleans())
def test_nc_syntax_and_btss_name_one_address(case: tuple[object, NckAddress], by_number: bool,
                                             unit_first: bool) -> None:
    """Written from the parts, not from a display: NC index i is BTSS line i + 1."""
    spec, address = case
    name = short_name(spec) if by_number else spec.name
    index = address.line - 1
    unit = _nc_unit(spec, address)
    tail = ([f"col{address.column}"] if spec.columns > 1 else []) + \
        ([f"x{address.line_count}"] if address.line_count > 1 else [])
    parts = [unit, str(index)] if unit_first else [str(index), unit]
    nc_texts = [f"{name}[{','.join(parts + tail)}]"]
    if spec.name == "R":
        nc_texts += [f"R{index}[{','.join([unit] + tail)}]", f"$R[{','.join(parts + tail)}]"]
    kind = line_kind(spec)
    if kind is not None:
        nc_texts.append(f"{name}[{','.join([f'{LINE_PREFIXES[kind]}{address.line}', unit] + tail)}]")
    btss_parts = [f"u{address.unit}"] + ([f"c{address.column}"] if spec.columns > 1 else [])
    last = address.line + address.line_count - 1
    btss_texts = [f"{btss_base(spec)}[{','.join(btss_parts + [str(address.line), f'#{address.line_count}'])}]",
                  f"{name}[{','.join(btss_parts + [str(address.line), str(last)])}]"]
    for text in nc_texts + btss_texts:
        parsed = parse_name(text)
        assert isinstance(parsed, NcNodeName) and parsed.address == address, text


@given(addresses())
def test_an_nc_index_past_the_row_is_refused_naming_both_ranges(case: tuple[object, NckAddress]) -> None:
    spec, _address = case
    assume(spec.name != "R" and spec.lines > 1)
    with pytest.raises(NckConfigError) as refused:
        parse_variable(f"{spec.name}[{spec.lines}]")
    message = str(refused.value)
    assert f"0..{spec.lines - 1}" in message and f"1..{spec.lines}" in message


_PLC_KINDS = {"x": ["BOOL"], "b": ["BYTE", "STRING"], "w": ["WORD", "INT"], "d": ["DWORD", "DINT", "REAL"]}


@st.composite
def plc_names(draw: st.DrawFn) -> PlcNodeName:
    area = draw(st.sampled_from(["I", "Q", "M", "DB", "PI", "PQ"]))
    widths = "bwd" if area in ("PI", "PQ") else "xbwd"
    width = draw(st.sampled_from(widths))
    kind = draw(st.sampled_from(_PLC_KINDS[width]))
    array = kind not in ("BOOL", "STRING") and draw(st.booleans())
    count = draw(st.integers(1, 1024)) if array else 1
    return PlcNodeName(area, draw(st.integers(1, 0xFFFF)) if area == "DB" else 0, draw(st.integers(0, 0xFFFF)),
                       draw(st.integers(0, 7)) if kind == "BOOL" else None, kind, count, array)


_GERMAN = {"I": "E", "Q": "A", "PI": "PE", "PQ": "PA"}


@given(plc_names())
def test_s7_names_and_plc_node_ids_read_back(name: PlcNodeName) -> None:
    text = str(name)
    assert parse_name(text) == name and parse_name(text.lower()) == name
    assert parse_item(text) == name
    if name.area in _GERMAN:
        assert parse_name(_GERMAN[name.area] + text[len(name.area):]) == name
    if name.node_id is None:
        with pytest.raises(NckNodeIdError):
            parse_name(f"/Plc/{text}")
    else:
        assert parse_name(name.node_id) == name and parse_name(f"ns=2;s={name.node_id}") == name
        assert PLC_TYPE_BYTES.get(name.kind, 1) * name.count == name.size_bytes


_ALPHABET = st.sampled_from(list("/[]#,.:$_ uUcCxXlLaAsSpP0123456789-DBWMRQIE") + [
    "R", "SD43900", "MD10000", "actSpeed", "actToolBasePos", "AX", "SP", "col", "/Channel/Parameter/R",
    "/Plc/DB", "ns=2;s=", "DB130.DBW", "PIW", "99999999", ":REAL", ":STRING", "[u1,", " "])


@given(st.one_of(st.text(max_size=40), st.lists(_ALPHABET, max_size=10).map("".join)))
def test_any_text_is_a_name_or_a_typed_refusal(text: str) -> None:
    try:
        name = parse_name(text)
    except NckNodeIdError:
        return
    if isinstance(name, NcNodeName):
        assert 1 <= name.line and name.line + name.count - 1 <= name.spec.lines
        assert parse_name(str(name)).address == name.address
    else:
        assert parse_name(str(name)) == name
