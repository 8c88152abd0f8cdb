"""Moved to ``nckemu.catalogue.table`` (0.2); kept so that imports of the old path keep working."""

from nckemu.catalogue.table import *  # noqa: F403
from nckemu.catalogue.table import (  # noqa: F401
    KNOWN_MODULES,
    R_PARAMETER_LINE_OFFSET,
    READ_ONLY,
    VariableSpec,
    display_name,
    find_by_name,
    load_table,
    table_index,
)
