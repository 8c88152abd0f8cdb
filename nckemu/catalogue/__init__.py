"""What the controller's address space is: NCK variables (name, number, module, column, type, limits,
access), name parsing and display, the NC PI services and NC-program formats.

The vocabulary clients, trace tools and emulator share (the role of asyncua's ``ua/``). It imports
only ``protocol/`` and ``nckemu.errors``; nothing here holds state.
"""

from .grammar import (
    IndexRanges,
    NcNodeName,
    PlcNodeName,
    display_btss,
    display_node_id,
    index_ranges,
    parse_name,
)
from .leadscrew import LeadscrewTable, parse_leadscrew_program
from .names import (
    PlcVariable,
    Variable,
    as_item,
    as_variable,
    parse_item,
    parse_variable,
    variable_for_address,
    with_overrides,
)
from .pi_services import NC_SERVICE_ARGUMENTS, PI_LOAD_LEADSCREW, PI_POWER_ON
from .table import (
    KNOWN_MODULES,
    R_PARAMETER_LINE_OFFSET,
    READ_ONLY,
    VariableSpec,
    build_table,
    display_name,
    find_by_name,
    line_kind,
    load_table,
    machine_table,
    spec_at,
    table_index,
)

__all__ = [
    "IndexRanges", "NcNodeName", "PlcNodeName", "PlcVariable", "as_item", "display_btss", "display_node_id",
    "index_ranges", "line_kind", "parse_item", "parse_name",
    "KNOWN_MODULES", "NC_SERVICE_ARGUMENTS", "PI_LOAD_LEADSCREW", "PI_POWER_ON", "READ_ONLY",
    "R_PARAMETER_LINE_OFFSET", "LeadscrewTable", "Variable", "VariableSpec", "as_variable", "build_table",
    "display_name", "find_by_name", "load_table", "machine_table", "parse_leadscrew_program", "parse_variable", "spec_at",
    "table_index",
    "variable_for_address", "with_overrides",
]
