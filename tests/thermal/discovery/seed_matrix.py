"""The twenty-seed matrices' shared loop: each seed's outcome, the seeds that hit, and one printed
line naming the misses."""

from __future__ import annotations

from collections.abc import Callable

SEEDS = range(1, 21)
Outcome = tuple[bool, list[str]]


def seed_outcomes(name: str, outcome: Callable[[str, int], Outcome]) -> tuple[dict[int, Outcome], list[int]]:
    """``outcome(name, seed)`` for every seed, and the seeds whose outcome is a hit."""
    outcomes = {seed: outcome(name, seed) for seed in SEEDS}
    hits = [seed for seed, (ok, _) in outcomes.items() if ok]
    print(f"{name}: {len(hits)}/20; misses: "
          + (", ".join(f"seed {s} {outcomes[s][1] or 'nothing'}" for s in SEEDS if s not in hits) or "none"))
    return outcomes, hits
