"""Moved to ``nckemu.catalogue.names`` (0.2); kept so that imports of the old path keep working."""

from nckemu.catalogue.names import (  # noqa: F401
    PlcVariable,
    Variable,
    as_item,
    as_variable,
    parse_item,
    parse_variable,
    variable_for_address,
    with_overrides,
)
