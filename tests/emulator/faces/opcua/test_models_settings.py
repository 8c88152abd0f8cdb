"""The companion models' part of the [opcua] table, and the NodeSet files' reading."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from nckemu.emulator.faces.opcua import nodesets
from nckemu.emulator.faces.opcua.settings import MODELS, OpcUaSettings
from nckemu.emulator.machine.machine_file import parse_machine
from nckemu.errors import NckConfigError


def test_both_models_by_default_and_switched_in_the_machine_file() -> None:
    assert OpcUaSettings.from_machine({}).models == MODELS == ("MachineTool", "CNC")
    machine = parse_machine('name = "m"\n[opcua]\nmodels = ["CNC"]\n[opcua.identification]\n'
                            'manufacturer = "ACME"\nyear_of_construction = 2019\n')
    settings = OpcUaSettings.from_machine(machine.opcua)
    assert settings.models == ("CNC",)
    assert settings.identification == {"manufacturer": "ACME", "year_of_construction": 2019}
    assert OpcUaSettings.from_machine({"models": []}).models == ()


@pytest.mark.parametrize(("table", "field"), [
    ({"models": ["umati"]}, "opcua.models"),
    ({"models": "CNC"}, "opcua.models"),
    ({"identification": {"serial": "1"}}, "opcua.identification.serial"),
    ({"identification": {"year_of_construction": "2019"}}, "opcua.identification.year_of_construction"),
    ({"identification": {"model": 5}}, "opcua.identification.model"),
    ({"nodesets": ""}, "opcua.nodesets"),
])
def test_errors_name_the_field(table: dict[str, object], field: str) -> None:
    with pytest.raises(NckConfigError) as caught:
        OpcUaSettings.from_machine(table, "m.toml")
    assert caught.value.field == field


_NS = "http://opcfoundation.org/UA/2011/03/UANodeSet.xsd"
_FILE = f"""<?xml version="1.0" encoding="utf-8"?>
<UANodeSet xmlns="{_NS}">
  <NamespaceUris><Uri>urn:test</Uri></NamespaceUris>
  <UAObjectType NodeId="ns=1;i=1" BrowseName="1:T">
    <References><Reference ReferenceType="HasSubtype" IsForward="false">i=58</Reference>
      <Reference ReferenceType="GeneratesEvent" IsForward="false">ns=1;i=20</Reference></References>
  </UAObjectType>
  <UAObject NodeId="ns=1;i=5" BrowseName="1:Kept" ParentNodeId="i=85">
    <References><Reference ReferenceType="Organizes" IsForward="false">i=85</Reference></References>
  </UAObject>
  <UAObject NodeId="ns=1;i=9" BrowseName="1:Tool" DesignToolOnly="true">
    <References><Reference ReferenceType="HasTypeDefinition">i=58</Reference></References>
  </UAObject>
  <UAObject NodeId="ns=1;i=10" BrowseName="1:Orphan">
    <References><Reference ReferenceType="HasComponent">ns=1;i=11</Reference>
      <Reference ReferenceType="Organizes">ns=1;i=20</Reference></References>
  </UAObject>
  <UAVariable NodeId="ns=1;i=11" BrowseName="1:Below" ParentNodeId="ns=1;i=10" DataType="Double">
    <References><Reference ReferenceType="HasComponent" IsForward="false">ns=1;i=10</Reference></References>
  </UAVariable>
  <UAObject NodeId="ns=1;i=20" BrowseName="1:HeldByOrphan">
    <References><Reference ReferenceType="HasTypeDefinition">i=58</Reference></References>
  </UAObject>
  <UAObject NodeId="ns=1;i=30" BrowseName="1:test">
    <References><Reference ReferenceType="Organizes" IsForward="false">i=85</Reference>
      <Reference ReferenceType="HasTypeDefinition">ns=1;i=1</Reference>
      <Reference ReferenceType="HasComponent">ns=1;i=31</Reference></References>
  </UAObject>
  <UAObject NodeId="ns=1;i=31" BrowseName="1:ListOfTheExample" ParentNodeId="ns=1;i=30">
    <References><Reference ReferenceType="HasComponent" IsForward="false">ns=1;i=30</Reference></References>
  </UAObject>
</UANodeSet>
"""


def test_reading_leaves_out_design_tool_nodes_orphans_and_examples_and_nothing_else(tmp_path: Path) -> None:
    path = tmp_path / "t.xml"
    path.write_text(_FILE, encoding="utf-8")
    text, left_out = nodesets.readable_xml(path)
    root = ET.fromstring(text)
    kept = [el.get("NodeId") for el in root if el.tag.startswith("{" + _NS + "}UA")]
    assert kept == ["ns=1;i=1", "ns=1;i=5"] and left_out == 6
    refs = [(r.get("ReferenceType"), r.text) for r in root[1].iter("{" + _NS + "}Reference")]
    assert refs == [("HasSubtype", "i=58")]  # the reference to the orphan gone, the supertype last


def test_missing_nodesets_say_how_to_get_them() -> None:
    line = nodesets.how_to_get()
    assert "make nodesets" in line and nodesets.NPM_PACKAGE in line and "\n" not in line
