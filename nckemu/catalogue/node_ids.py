"""SINUMERIK OPC UA node ids (the ``SinumerikVarProvider`` namespace) to typed catalogue names.

The OPC UA face's entry into the one grammar (``grammar``, docs/addresses.md), which reads here only
the forms the controller serves:
  /Channel/State/progStatus          BTSS path: unit 1, line 1
  /Channel/Parameter/R[u1,10]        unit 1, line 10 (BTSS lines count from 1: this is R9)
  /Nck/Spindle/driveLoad[u1, 3]      spaces allowed
  /Channel/Parameter/R[u1,1,5]       lines 1..5 (an array)      R[u1,1,#5]: 5 lines from line 1
  /Tool/Compensation/cuttEdgeParam[u1, c2, 3, 5]   column (T number) 2, lines 3..5
  /NC/_N_CH_TEA_ACX/$MC_CHAN_NAME[u1]               machine data (TEA) of a channel
  /NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u4]     setting data (SEA) of axis 4 (scheme inferred)
  /NC/_N_AX_TEA_ACX/$MA_ENC_COMP_ENABLE[2, u4]      a number in an /NC/ id: a line from 1 (NC index 1)
  /Plc/M5.0  /Plc/MB6  /Plc/DB5.DBW2  /Plc/DB8.DBB2:STRING  /Plc/DB8.DBW2:[10]  /Plc/DB2.DBD0:REAL[10]
  (``/Random/Plc/...`` is the same as ``/Plc/...``; ``ns=2;s=`` in front is allowed)
Catalogue rows without a BTSS path and without an SD/MD number are served as ``/Nckemu/<area>/<name>``.

Two typed errors: ``NckNodeIdUnknown`` (malformed, or no SINUMERIK namespace) and ``NckNodeNotConfigured``
(well formed, but this machine's table lacks the variable or the index lies outside it).
"""

from __future__ import annotations

from collections.abc import Sequence

from .grammar import (
    MAX_PLC_BYTE,
    MAX_PLC_ITEMS,
    MAX_TEXT,
    NC_ROOTS,
    PLC_TYPE_BYTES,
    NcNodeName,
    NodeName,
    PlcNodeName,
    display_node_id,
    node_paths,
    parse_name,
    realm_of,
)
from .table import VariableSpec

__all__ = ["MAX_PLC_BYTE", "MAX_PLC_ITEMS", "MAX_TEXT", "NC_ROOTS", "PLC_TYPE_BYTES", "NcNodeName", "NodeName",
           "PlcNodeName", "display_node_id", "node_paths", "parse_node_id", "realm_of"]


def parse_node_id(text: str, specs: Sequence[VariableSpec] | None = None) -> NodeName:
    """A SINUMERIK node id (see the module docstring) against ``specs`` (default: the built-in table)."""
    return parse_name(text, specs, node_ids_only=True)
