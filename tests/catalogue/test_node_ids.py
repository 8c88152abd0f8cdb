"""SINUMERIK OPC UA node ids: the controller's examples, and random text only ever gives a typed error."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.catalogue.node_ids import NcNodeName, PlcNodeName, node_paths, parse_node_id, realm_of
from nckemu.catalogue.table import load_table
from nckemu.errors import NckNodeIdError, NckNodeIdUnknown, NckNodeNotConfigured
from nckemu.protocol.addresses import NckArea


@pytest.mark.parametrize(("text", "unit", "line", "count", "array"), [
    ("/Channel/State/progStatus", 1, 1, 1, False),
    ("/Channel/State/progStatus[u1]", 1, 1, 1, False),
    ("/Channel/Parameter/R[u1,10]", 1, 10, 1, False),
    ("/Channel/Parameter/R[u2, 56]", 2, 56, 1, False),
    ("/Channel/Parameter/R[u1,1,5]", 1, 1, 5, True),
    ("/Channel/Parameter/R[u1,1,#5]", 1, 1, 5, True),
    ("/Channel/Parameter/R[ u1 , 3 , #2 ]", 1, 3, 2, True),
    ("/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]", 4, 1, 1, False),
    ("/NC/_N_CH_TEA_ACX/$MC_CHAN_NAME[u1]", 1, 1, 1, False),
    ("/NC/_N_AX_TEA_ACX/$MA_ENC_COMP_ENABLE[2, u4]", 4, 2, 1, False),  # /NC/ ids count lines from 1 too
    ("/NC/_N_NC_TEA_ACX/$MN_VERSION_INFO[u1,1]", 1, 1, 1, False),  # as the BTSS form MD18040[u1,1]
    ("/channel/state/PROGSTATUS", 1, 1, 1, False),
])
def test_nc_examples(text: str, unit: int, line: int, count: int, array: bool) -> None:
    name = parse_node_id(text)
    assert isinstance(name, NcNodeName)
    assert (name.unit, name.line, name.count, name.array) == (unit, line, count, array)
    assert name.address.line_count == count


def test_machine_and_setting_data_name_the_sd_md_rows() -> None:
    sea = parse_node_id("/NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]")
    assert isinstance(sea, NcNodeName) and sea.spec.number == "SD43900" and sea.area == NckArea.A
    assert sea.realm == "Sea"
    assert parse_node_id("/NC/_N_CH_TEA_ACX/$MC_CHAN_NAME").realm == "Tea"


@pytest.mark.parametrize(("text", "area", "db", "byte", "bit", "kind", "count"), [
    ("/Plc/M5.0", "M", 0, 5, 0, "BOOL", 1),
    ("/Plc/MB6", "M", 0, 6, None, "BYTE", 1),
    ("/Plc/DB5.DBW2", "DB", 5, 2, None, "WORD", 1),
    ("/Plc/DB8.DBB2:STRING", "DB", 8, 2, None, "STRING", 1),
    ("/Plc/DB8.DBW2:[10]", "DB", 8, 2, None, "WORD", 10),
    ("/Plc/DB2.DBD0:REAL[10]", "DB", 2, 0, None, "REAL", 10),
    ("/Random/Plc/DB2.DBD4:DINT", "DB", 2, 4, None, "DINT", 1),
    ("/Plc/E1.3", "I", 0, 1, 3, "BOOL", 1),
])
def test_plc_examples(text: str, area: str, db: int, byte: int, bit: int | None, kind: str, count: int) -> None:
    name = parse_node_id(text)
    assert isinstance(name, PlcNodeName)
    assert (name.area, name.db, name.byte, name.bit, name.kind, name.count) == (area, db, byte, bit, kind, count)
    assert name.realm == "Plc"


@pytest.mark.parametrize(("text", "error"), [
    ("Channel/State/progStatus", NckNodeIdUnknown),          # no leading slash
    ("/Channel/State/progStatus[u1", NckNodeIdUnknown),      # bad brackets
    ("/Channel/Parameter/R[u1,99999999]", NckNodeIdUnknown),  # huge index
    ("/Channel/Parameter/R[u1,1000]", NckNodeNotConfigured),  # beyond the variable
    ("/Nck/Spindle/driveLoad[u1, 3]", NckNodeNotConfigured),  # a real variable this machine lacks
    ("/Foo/Bar", NckNodeIdUnknown),
    ("/Plc/DB5.DBW2.1", NckNodeIdUnknown),
    ("/Plc/DB5.DBW2:REAL", NckNodeIdUnknown),                # a REAL is not a word
    ("/Plc/M5", NckNodeIdUnknown),
    ("", NckNodeIdUnknown),
])
def test_errors(text: str, error: type[Exception]) -> None:
    with pytest.raises(error):
        parse_node_id(text)


def test_every_catalogue_row_has_a_node_id_that_parses_back() -> None:
    for spec in load_table():
        for path in node_paths(spec):
            name = parse_node_id(path)
            assert isinstance(name, NcNodeName) and name.spec is spec, path


def test_realms() -> None:
    assert realm_of("/Plc/M5.0") == "Plc"
    assert realm_of("/Tool/Compensation/cuttEdgeParam") == "Tool"
    assert realm_of("/NC/_N_NC_GD3_ACX/ARRAY") == "Gud"
    assert realm_of("/Channel/State/progStatus") == "State"


_ALPHABET = st.sampled_from(list("/[]#,.:$_ uUcC0123456789abcdefgDBWXMRPlcNhnel") + ["/Channel/Parameter/R",
                            "/Plc/DB", "/NC/_N_AX_SEA_ACX/$SA_", "[u", "99999999999"])


@given(st.one_of(st.text(max_size=60), st.lists(_ALPHABET, max_size=12).map("".join)))
def test_random_text_only_ever_gives_a_typed_error(text: str) -> None:
    try:
        name = parse_node_id(text)
    except NckNodeIdError:
        return
    if isinstance(name, NcNodeName):
        assert 1 <= name.line and name.line + name.count - 1 <= name.spec.lines
        name.address  # a valid NckAddress  # noqa: B018
    else:
        assert 1 <= name.count and name.byte <= 0xFFFF
