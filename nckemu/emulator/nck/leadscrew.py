"""Moved to ``nckemu.catalogue.leadscrew`` (0.2); kept so that imports of the old path keep working."""

from nckemu.catalogue.leadscrew import LeadscrewTable, parse_leadscrew_program  # noqa: F401
