"""The selector's words: how a share, a bar and what a machine cannot have read in a guard's figure."""

from __future__ import annotations

from nckemu.thermal.model.terms import Term

from . import shapes

CANNOT_HAVE = "fits, but a machine cannot have it"


def percent(share: float) -> str:
    """A share in percent: whole when it is whole (5%), else to a tenth (9.8%)."""
    return f"{share:.0%}" if abs(share * 100 - round(share * 100)) < 1e-9 else f"{share:.1%}"


def per_parameter_words(bar: float, one: float, terms: tuple[Term, ...]) -> str:
    """Where a bar is weighed by the term's parameters, how."""
    if len(terms) != 1 or abs(bar - one) < 1e-12:
        return ""
    return f" ({percent(one)} for each of its {shapes.parameters_of(terms[0])} parameters)"
