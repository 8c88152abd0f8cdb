"""The selector's words: each guard's figure, why a move of two effects or a withdrawal, and why a
common gain or recalibration was preferred. The numbers are the admission's and the search's; only
how they read is decided here (a figure is never called below a bar it clears: docs/thermal.md)."""

from __future__ import annotations

from collections.abc import Sequence

from nckemu.thermal.model.terms import Term

from . import shapes

CANNOT_HAVE = "fits, but a machine cannot have it"
# What the held-out figure admission rests on is, with several runs and with one record.
MEDIAN_OVER_RUNS = "the median over runs of held-out RMS"
HELD_OUT = "held-out RMS"
WITHOUT_NOISE = "held-out RMS without the sensors' noise"
HARM = "runs harmed"


def percent(share: float) -> str:
    """A share in percent: whole when it is whole (5%), else to a tenth (9.8%)."""
    return f"{share:.0%}" if abs(share * 100 - round(share * 100)) < 1e-9 else f"{share:.1%}"


def per_parameter_words(bar: float, one: float, terms: tuple[Term, ...], extra_parameters: int = 0) -> str:
    """Where a bar is weighed by the term's parameters, how (``extra_parameters``: a term fitted apart
    over groups of runs has its other group's coefficient beside its own)."""
    if len(terms) != 1 or abs(bar - one) < 1e-12:
        return ""
    return f" ({percent(one)} for each of its {shapes.parameters_of(terms[0]) + extra_parameters} parameters)"


def plural(count: int, word: str) -> str:
    return f"{word}{'s' if count > 1 else ''}"


# ---------------------------------------------------------------------- each guard's figure
def improved_words(improved: int, units: int, unit: str, need: int) -> str:
    """``unit``: "runs" or "blocks"."""
    return f"{improved} of {units} {unit} improve (at least {need} must)"


def paired_test_words(p: float, level: float, alpha: float, candidates: int) -> str:
    return (f"the runs' paired test gives p = {p:.2g} (level {level:.2g}, {alpha:g} over "
            f"{max(candidates, 1)} {plural(candidates, 'candidate')})")


def t_test_words(t_values: tuple[float, ...], t_critical: float) -> str:
    return f"t = {', '.join(f'{t:.2f}' for t in t_values)} (critical {t_critical:.2f})"


def physical_words(physical: bool, cannot: str) -> str:
    """``cannot``: why a machine cannot have the fitted term (empty: it can)."""
    if not physical:
        return "parameters outside what a machine can have"
    return f"{CANNOT_HAVE}: {cannot}" if cannot else "parameters a machine can have"


def harm_words(harmed: list[str], share: float, floor_um: float) -> str:
    """The runs a term leaves worse than the harm tolerance, the first four by name."""
    if not harmed:
        return ""
    return (f"; {len(harmed)} {plural(len(harmed), 'run')} worse by more than {share:.0%} and {floor_um:g} um: "
            f"{', '.join(harmed[:4])}{', ...' if len(harmed) > 4 else ''}")


def harm_guard_words(harmed: list[str], share: float, floor_um: float, refuses: bool = True) -> str:
    """The harm guard's figure: the runs a term leaves worse than the tolerance, or that none is;
    ``refuses=False``: such runs are named, and the term is not refused for them."""
    if not harmed:
        return f"no run worse by more than {share:.0%} and {floor_um:g} um"
    named = "" if refuses else " (named, not refused: Settings.run_harm_refuses is off)"
    return harm_words(harmed, share, floor_um)[2:] + named


def worst_run_words(run: str, before_um: float, after_um: float, limit_um: float, harmed: str) -> str:
    return f"the worst run ({run}) {before_um:.3f} -> {after_um:.3f} um (at most {limit_um:.3f}){harmed}"


def heldout_words(figure: str, before_um: float, after_um: float, gain: float, bar: float, one_bar: float,
                  terms: tuple[Term, ...]) -> str:
    """The held-out bar's figure; ``one_bar``: the bar of one parameter, when ``bar`` is weighed by them."""
    return (f"{figure} {before_um:.3f} -> {after_um:.3f} um ({gain:.1%}; the bar is {percent(bar)})"
            f"{per_parameter_words(bar, one_bar, terms)}")


def time_constant_words(simpler: str, figure: str, simpler_um: float, this_um: float, gain: float,
                        bar: float) -> str:
    return (f"its time constant against {simpler}: {figure} {simpler_um:.3f} -> {this_um:.3f} um "
            f"({gain:.1%}; the bar is {bar:.0%})")


def limit_words(max_effects: int) -> str:
    return f"the search stopped at {max_effects} terms (Settings.max_effects)"


def terms_named(count: int) -> str:
    return f"{count} term{'s' if count != 1 else ''} named"


def stopped_by_data_words(count: int) -> str:
    """The search reached Settings.max_effects and the next round, judged with the limit lifted,
    admitted nothing."""
    return (f"{terms_named(count)}, the most Settings.max_effects allows, and the next round was judged with "
            f"the limit lifted: nothing more earns its place; the data, not the limit, stopped the search")


def stopped_by_limit_words(count: int, max_effects: int, labels: list[str], before_um: float, after_um: float,
                           figure: str) -> str:
    """The next round, judged with the limit lifted, would name more: what, and its held-out figure."""
    allows = "the most Settings.max_effects allows" if count >= max_effects else \
        f"one short of Settings.max_effects = {max_effects}, too few for a move of two"
    return (f"{terms_named(count)}, {allows}: the next round would name {' and '.join(labels)} ({figure} "
            f"{before_um:.3g} -> {after_um:.3g} um): the limit, not the data, stopped the search; raise "
            f"Settings.max_effects to let it")


# ---------------------------------------------------------------------- moves of two effects
PAIR_WHY = ("no single effect passed the guards; these two pass them together, and each is needed (the pair "
            "clears the held-out bar over either alone)")


def hours(tau_s: float) -> str:
    return f"{tau_s / 3600:.2g} h"


def move_preferred(label: str, share: float) -> str:
    return f"{label}: a move of two effects ({share:.0%} of it this one)"


def two_time_constants_label(sensor_label: str, taus_s: Sequence[float]) -> str:
    return f"{sensor_label} at two time constants, {' and '.join(hours(tau_s) for tau_s in taus_s)}"


def split_why(fast: str, slow: str, chosen: str, chosen_um: float, move_um: float) -> str:
    return (f"one sensor at two time constants (a fast skin and a slow core): {fast} and {slow} "
            f"together clear the held-out bar over {chosen} alone (held-out "
            f"{chosen_um:.3f} um against {move_um:.3f} um) and over either alone")


def split_preferred(chosen: str, fast: str, slow: str, share: float) -> str:
    return f"{chosen} at {fast} and {slow}: two time constants of one sensor ({share:.0%} of it this one)"


def partner_why(plain: bool, move: str, chosen: str, chosen_um: float, move_um: float) -> str:
    """``plain``: the move is two plain temperatures (the time constant earned nothing beside the partner)."""
    return (f"{'two measured sensors in place of the time constant' if plain else 'a measured sensor beside the time constant'}: "
            f"{move} clears the held-out bar over {chosen} alone (held-out {chosen_um:.3f} um against "
            f"{move_um:.3f} um) and over either alone; "
            + ("the time constant, searched again beside the second sensor, earned nothing over the sensor "
               "itself" if plain else
               "the time constant alone had absorbed part of what the measured sensor explains"))


def equivalent_partners_words(margin: float, equivalent: list[str], partner: str | None, constructed: bool) -> str:
    """What the data cannot tell apart from the named move, and why it was named: ``partner`` the
    measured partner that fits best when other partners are equivalent, ``constructed`` when two time
    constants of the sensor are."""
    reasons = ([f"the measured partner that fits the record best (in-sample), {partner}"] if partner else []) \
        + (["the measured sensor, which needs no constructed signal and fewer parameters"] if constructed else [])
    return (f". Equivalent on these data (held-out without the sensors' noise within {margin:.0%}): "
            f"{', '.join(equivalent)}; the data cannot tell them apart. Named: {'; and '.join(reasons)}")


def partner_preferred(move: str, plain: bool, share: float) -> str:
    kind = "two measured sensors" if plain else "a time constant and a measured sensor"
    return f"{move}: {kind} that share drivers, judged together ({share:.0%} of it this one)"


# ---------------------------------------------------------------------- withdrawals
def withdrawn_words(without_um: float, with_um: float, loss: float, bar: float, one_bar: float, term: Term,
                    worst_without_um: float, worst_with_um: float, extra_parameters: int = 0) -> str:
    weighed = per_parameter_words(bar, one_bar, (term,), extra_parameters)
    return (f"the terms named after it explain what it did: without it the median over runs of held-out RMS "
            f"is {without_um:.3f} um against {with_um:.3f} um "
            f"with it ({loss:.1%}; the bar is {percent(bar)}){weighed}, "
            f"the worst run {worst_without_um:.3f} um against {worst_with_um:.3f} um")


def beyond_structure_words(why: str, figure: str, without_um: float, with_um: float) -> str:
    """Why a named term was withdrawn at the end: its size in the final joint fit is more than a
    machine can have."""
    return (f"{CANNOT_HAVE} at its size in the final fit with the terms named after it: {why}; {figure} "
            f"without it {without_um:.3f} um against {with_um:.3f} um with it")


def partner_withdrawn_words(withdrawn: str) -> str:
    return f"named in a move with {withdrawn}, which the later terms made redundant (withdrawn)"


# ---------------------------------------------------------------------- a common gain
GAIN_WHY = "one common factor on the whole model explains the mismatch"
GAIN_SET_ASIDE = "a common gain on the model was considered and set aside"


def gain_withdrawn_words(gain: float, low: float, high: float) -> str:
    return (f"a common gain was considered and withdrawn: with the other effects in, it is {gain:.3g} "
            f"(physical range {low:g}..{high:g}, and it must depart from 1)")


def gain_preferred_words(single: bool, physics: bool, gain_um: float, recalibrated_um: float) -> str:
    """Why gain x model was named: the model has one coefficient, recalibration found no ``physics``,
    or the gain holds out better."""
    reason = ("the model has one coefficient: its refit is the gain" if single else
              "recalibrating the model's coefficients finds no physics the gain does not explain"
              if not physics else
              f"gain x model explains held-out data better ({gain_um:.3f} um) than recalibrating and "
              f"adding physics ({recalibrated_um:.3f} um)")
    return f"gain_error preferred: {reason}"


def gain_set_aside_words(gain: float, gain_um: float, recalibrated_um: float, equivalence: float) -> str:
    return (f"a common gain of {gain:.3g} was considered: held-out {gain_um:.3f} um against "
            f"{recalibrated_um:.3f} um for recalibration + physics, not better by {equivalence:.0%}")


def alone_label(label: str) -> str:
    """An alternative to a move: the effect the round chose, alone."""
    return f"{label} alone"


def recalibration_label(effects: list[str]) -> str:
    """An alternative to a common gain: the model recalibrated plus the effects found beside it."""
    return "recalibration" + "".join(f" + {effect}" for effect in effects)
