"""Each sensor's heat response, found term by term and admitted on held-out data.

Per sensor, a forward search over the families (families.py): in each round every family's best
parameters (speed power, time constants, which sensor) are picked in-sample on the part the fit may
see, against the terms already named; each family's best is then judged on data it was not fitted
on, and the one that lowers the held-out RMS most while passing the guards is named. After each
naming, an earlier term that no longer earns its place on held-out data is withdrawn. The search stops
when no family passes.

Held out, as discovery holds out (discovery/splitters.py, discovery/admission.runs_improve):
- one recording: the coefficients are fitted on its first ``train_share`` and judged on the rest; the
  rest is cut into ``blocks`` blocks of time (``Blocks``), most of which must improve;
- several runs: each run is held out once (``LeaveOneRunOut``), fitted on the others, each run with
  its own offset; the runs' paired test (or, for a few runs, most runs improving) must pass.
Either way the held-out RMS must fall by ``min_improvement``. An in-sample fit never admits a term.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from nckemu.heat_response import SPINDLE, HeatTerm
from nckemu.thermal import stats
from nckemu.thermal.discovery.readings import white_noise_C

from .families import Columns, Spec, family_candidates, is_reference, label_terms, polish
from .judge import Judge, Judgement, Settings, products
from .table import HeatRun

# The gains a sensor term may have (K per K): a neighbour passes on part of its rise; a structure
# follows the room by about as much as the room moves (a little more where it is better coupled).
MAX_NEIGHBOUR_K_PER_K = 1.5
MAX_AMBIENT_K_PER_K = 3.0
# When no family passes alone, pairs of the round's best this many are tried together.
PAIR_FAMILIES = 3


@dataclass
class Named:
    """A term of a sensor's response with the figures that admitted it."""

    term: HeatTerm
    share: float = 0.0
    heldout_before_K: float = 0.0
    heldout_after_K: float = 0.0


@dataclass
class SensorHeat:
    sensor: str
    base_C: float
    range_K: float
    heldout_before_K: float
    heldout_after_K: float
    terms: list[Named] = field(default_factory=list)
    withdrawn: list[str] = field(default_factory=list)
    # The best family that did not pass in the last round: (label, held-out after, why not).
    closest: str = ""
    # Where the response still fails: when, in which phase, what the residual follows.
    left: str = ""
    heldout_residual_K: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # The search's own record: the terms' shapes, the fitted rise over every row, when each was named.
    specs: list[Spec] = field(default_factory=list)
    rise_K: np.ndarray = field(default_factory=lambda: np.zeros(0))
    admitted_at: dict[Spec, tuple[float, float]] = field(default_factory=dict)

    @property
    def improvement(self) -> float:
        return 1.0 - self.heldout_after_K / self.heldout_before_K if self.heldout_before_K > 0 else 0.0

    def to_json(self) -> dict[str, object]:
        return {"sensor": self.sensor, "base_C": round(self.base_C, 4), "range_K": round(self.range_K, 4),
                "heldout_rms_before_K": round(self.heldout_before_K, 4),
                "heldout_rms_after_K": round(self.heldout_after_K, 4),
                "terms": [{**n.term.to_table(), "unit": n.term.unit(), "share": round(n.share, 3)} for n in self.terms],
                "withdrawn": self.withdrawn, "closest": self.closest, "left": self.left}


@dataclass
class HeatFit:
    runs: list[str]
    judged_on: str
    sensors: list[SensorHeat]
    reference: list[str] = field(default_factory=list)
    judge: Judge | None = None   # how it was judged (words.explain_left reads the held-out rows)

    def to_json(self) -> dict[str, object]:
        return {"runs": self.runs, "judged_on": self.judged_on, "reference": self.reference,
                "sensors": [s.to_json() for s in self.sensors]}


def _contribution_shares(terms: list[HeatTerm], columns: list[np.ndarray]) -> list[float]:
    spreads = [abs(term.K) * float(np.mean(np.abs(column - np.mean(column)))) for term, column in zip(terms, columns, strict=True)]
    total = sum(spreads)
    return [spread / total if total > 0 else 0.0 for spread in spreads]


class SensorSearch:
    """The forward search for one sensor (``neighbours``: whether other sensors' responses may drive it)."""

    def __init__(self, sensor: str, runs: list[HeatRun], columns: Columns, judge: Judge, settings: Settings,
                 *, neighbours: bool = False) -> None:
        self.sensor, self.runs, self.columns, self.judge, self.settings = sensor, runs, columns, judge, settings
        self.neighbours = neighbours
        self.y = np.concatenate([run.sensors_C[sensor] for run in runs])
        self._y_fit: np.ndarray | None = None

    def design(self, specs: list[Spec], *, cache: bool = True) -> np.ndarray:
        if not specs:
            return np.empty((len(self.y), 0))
        return np.column_stack([self.columns.column(spec, cache=cache) for spec in specs])

    def in_sample_sse(self, specs: list[Spec], *, cache: bool = True) -> float:
        """The residual sum of squares of ``specs`` fitted where the fit may look (normal equations:
        a handful of columns; the columns' fitting rows are kept between calls)."""
        if self._y_fit is None:
            self._y_fit, _x = self.judge.fitting_rows(self.y, self.design([]))
        y = self._y_fit
        columns = [self.columns.fitting_one(spec, cache=cache) for spec in specs]
        if not self.judge.per_run:
            columns.insert(0, np.ones(len(y)))
        if not columns:
            return float(y @ y)
        x = np.column_stack(columns)
        gram, cross = products(x, x), products(x, y)
        try:
            coef = np.linalg.solve(gram, cross)
        except np.linalg.LinAlgError:
            coef = stats.least_squares(x, y)
        residual = y - np.einsum("ij,j->i", x, coef)
        return float(np.einsum("i,i->", residual, residual))

    def unphysical(self, specs: list[Spec]) -> str:
        """Why a design's fitted gains are none a machine can have ("" when they are): a sensor passes on
        a share of its own rise, and the room moves a structure by about as much as it moves."""
        y, x = self.judge.fitting_rows(self.y, self.design(specs))
        coef = stats.least_squares(x, y)[0 if self.judge.per_run else 1:]
        for spec, k in zip(specs, coef, strict=True):
            if spec.kind != "sensor":
                continue
            low, high = (0.0, MAX_AMBIENT_K_PER_K) if spec.source in self.columns.reference else (0.0, MAX_NEIGHBOUR_K_PER_K)
            if not low < k <= high:
                return f"{spec.describe()} would take {k:+.2f} K per K (a machine's is {low:g} to {high:g})"
        return ""

    def too_small(self, specs: list[Spec], before: list[Spec], noise_K: float) -> str:
        """Why a new term is no finding ("" when it is one): it moves the sensor by less than a few
        times the sensor's own white noise (a slow lag of any input mops up what is left otherwise)."""
        y, x = self.judge.fitting_rows(self.y, self.design(specs))
        coef = stats.least_squares(x, y)[0 if self.judge.per_run else 1:]
        for spec, k in zip(specs, coef, strict=True):
            if spec in before:
                continue
            moves_K = abs(float(k)) * float(np.ptp(self.columns.column(spec)))
            if moves_K < self.settings.min_effect_noise * noise_K:
                return (f"{spec.describe()} would move the sensor by {moves_K:.3f} K, less than "
                        f"{self.settings.min_effect_noise:g}x its white noise ({noise_K:.3f} K)")
        return ""

    def run(self, start: SensorHeat | None = None) -> SensorHeat:
        s = self.settings
        first = self.judge.judge(self.y, self.design([]))
        specs: list[Spec] = list(start.specs) if start else []
        current = self.judge.judge(self.y, self.design(specs)) if specs else first
        withdrawn: list[str] = list(start.withdrawn) if start else []
        closest = ""
        admitted_at: dict[Spec, tuple[float, float]] = dict(start.admitted_at) if start else {}
        noise_K = white_noise_C(self.y)
        rounds = 0
        while len(specs) < s.max_terms and rounds < 2 * s.max_terms:
            rounds += 1
            if current.rms <= s.noise_factor * noise_K:
                closest = (f"what is left ({current.rms:.3f} K held-out) is the sensor's own white noise "
                           f"({noise_K:.3f} K): nothing more to find")
                break
            candidates = family_candidates(self, specs)
            judged = []
            for family, new_specs in candidates:
                verdict = self.judge.judge(self.y, self.design(new_specs))
                ok, why = self.judge.passes(current, verdict, len(candidates))
                unphysical = self.unphysical(new_specs) or self.too_small(new_specs, specs, noise_K)
                if unphysical:
                    ok, why = False, f"{why}; {unphysical}"
                judged.append((verdict.rms, ok, family, new_specs, verdict, why))
            passing = sorted((j for j in judged if j[1]), key=lambda j: j[0])
            if not passing:   # two families that only together explain what each alone cannot
                passing = self._pairs(specs, current, judged)
            if not passing:
                best = min(judged, key=lambda j: j[0], default=None)
                closest = f"{best[2]}: {best[5]}" if best is not None else ""
                break
            _rms, _ok, _family, new_specs, verdict, _why = passing[0]
            polished = polish(self, polish(self, list(new_specs))) if s.polish else new_specs
            if polished != new_specs:   # the earlier terms' time constants again, given the new one
                again = self.judge.judge(self.y, self.design(polished))
                if again.rms <= verdict.rms and not self.unphysical(polished):
                    new_specs, verdict = polished, again
            for spec in new_specs:
                if spec not in specs:
                    admitted_at[spec] = (current.rms, verdict.rms)
            specs, current = list(new_specs), verdict
            specs, current, gone = self._withdraw(specs, current)
            withdrawn += gone
        return self._result(specs, first, current, withdrawn, closest, admitted_at)

    def _pairs(self, specs: list[Spec], current: Judgement, judged: list) -> list:
        """Two of the round's best families named together (each alone confounded with the other: a
        coolant switched while the spindle runs), judged as one candidate against the pairs tried."""
        best = sorted(judged, key=lambda j: j[0])[:PAIR_FAMILIES]
        tries = []
        for i, first in enumerate(best):
            for second in best[i + 1:]:
                added = [spec for spec in second[3] if spec not in first[3]]
                if not added or any(a.kind == b.kind == "spindle" for a in added for b in first[3] if b not in specs):
                    continue
                merged = list(first[3]) + added
                tries.append((f"{first[2]} + {second[2]}", polish(self, merged) if self.settings.polish else merged))
        passing = []
        for family, merged in tries:
            verdict = self.judge.judge(self.y, self.design(merged))
            ok, why = self.judge.passes(current, verdict, len(judged) + len(tries))
            if ok and not self.unphysical(merged) and not self.too_small(merged, specs, white_noise_C(self.y)):
                passing.append((verdict.rms, ok, family, merged, verdict, why))
        return sorted(passing, key=lambda j: j[0])

    def _withdraw(self, specs: list[Spec], current: Judgement) -> tuple[list[Spec], Judgement, list[str]]:
        """Earlier terms that the later ones made unnecessary on held-out data."""
        gone = []
        for spec in list(specs):   # the newest too: a polish of the others may have done its work
            if len(specs) < 2:
                break
            without = [other for other in specs if other != spec]
            verdict = self.judge.judge(self.y, self.design(without))
            if verdict.rms <= current.rms * (1.0 + self.settings.withdraw_share):
                gone.append(f"{spec.describe()}: held-out {current.rms:.3f} K with it, {verdict.rms:.3f} K without "
                            f"(the terms named after it explain what it did)")
                specs, current = without, verdict
        return specs, current, gone

    def _result(self, specs: list[Spec], first: Judgement, final: Judgement, withdrawn: list[str], closest: str,
                admitted_at: dict[Spec, tuple[float, float]]) -> SensorHeat:
        judge = self.judge
        design = self.design(specs)
        if judge.per_run:
            coef = stats.least_squares(judge.within(design), judge.within(self.y)) if specs else np.zeros(0)
            offsets = [float(np.mean((self.y - design @ coef)[judge.groups == g])) for g in range(len(self.runs))]
            base = float(np.median(offsets))
        else:
            x = np.column_stack((np.ones(len(self.y)), design))
            full = stats.least_squares(x[judge.train], self.y[judge.train])
            base, coef = float(full[0]), full[1:]
        terms = [spec.term(float(k), self.columns) for spec, k in zip(specs, coef, strict=True)]
        terms = label_terms(terms, self.columns.reference)
        shares = _contribution_shares(terms, [design[:, i] for i in range(design.shape[1])])
        named = []
        for spec, term, share in zip(specs, terms, shares, strict=True):
            before, after = admitted_at.get(spec, (first.rms, final.rms))
            named.append(Named(term, share, before, after))
        named.sort(key=lambda n: -n.share)
        return SensorHeat(self.sensor, base, float(np.ptp(self.y)), first.rms, final.rms, named, withdrawn, closest,
                          heldout_residual_K=final.residual, specs=list(specs), rise_K=design @ coef,
                          admitted_at=admitted_at)


def choose_reference(runs: list[HeatRun], columns: Columns, judge: Judge, settings: Settings) -> tuple[str, ...]:
    """The sensors that read the room: those declared or named so, else the one the spindle explains
    least (in-sample, one lag), when the spindle was recorded and the machine has several sensors."""
    names = sorted(runs[0].sensors_C)
    if settings.reference:
        return settings.reference
    named = tuple(name for name in names if is_reference(name, ()))
    if named or len(names) < 3 or not all(SPINDLE in run.inputs for run in runs):
        return named
    shares = {}
    for name in names:
        search = SensorSearch(name, runs, columns, judge, settings)
        total = search.in_sample_sse([])
        found = family_candidates(search, [], only="spindle")
        best = min((search.in_sample_sse(specs) for _label, specs in found), default=total)
        shares[name] = 1.0 - best / total if total > 0 else 1.0
    return (min(shares, key=lambda name: shares[name]),)


def fit_heat(runs: list[HeatRun], settings: Settings | None = None, sensors: list[str] | None = None) -> HeatFit:
    """Every sensor's response (``sensors``: a few of them) over ``runs``: first from the machine's inputs
    and the room alone, then with the heat other sensors' responses pass on (a neighbour's response is
    its first one, and a sensor that passes heat on takes none: the twin stays a chain from the inputs)."""
    settings = settings or Settings()
    judge = Judge(runs, settings)
    columns = Columns(runs, settings, judge)
    columns.reference = choose_reference(runs, columns, judge, settings)
    names = [name for name in (sensors or sorted(runs[0].sensors_C)) if name not in columns.reference]
    results = {name: SensorSearch(name, runs, columns, judge, settings).run() for name in names}
    sources: set[str] = set()
    for name in names:
        offered = {other: results[other] for other in names if other != name and results[other].terms
                   and not any(n.term.name == "neighbour" for n in results[other].terms)}
        if name in sources or not offered:
            continue
        columns.offer({other: result.rise_K for other, result in offered.items()})
        search = SensorSearch(name, runs, columns, judge, settings, neighbours=True)
        # Afresh, with neighbours among the first candidates: a neighbour's heat is also what a slower
        # spindle term approximates, so a search that starts from those would rarely replace them.
        again = search.run()
        passed_on = [n.term.sensor for n in again.terms if n.term.name == "neighbour"]
        before = results[name]
        better = again.heldout_after_K < before.heldout_after_K * (1 - settings.min_improvement / 2)
        simpler = (len(again.terms) < len(before.terms)
                   and again.heldout_after_K <= before.heldout_after_K * (1 + settings.withdraw_share))
        if passed_on and (better or simpler):
            again.withdrawn.append(f"the response from the inputs alone ({len(before.terms)} terms, "
                                   f"{before.heldout_after_K:.3f} K held-out) gave way to one with a neighbour's heat "
                                   f"({len(again.terms)} terms, {again.heldout_after_K:.3f} K)")
            results[name] = again
            sources |= set(passed_on)
    out = [results[name] for name in names]
    for name in columns.reference:
        values = np.concatenate([run.sensors_C[name] for run in runs])
        out.append(SensorHeat(name, float(values[0]), float(np.ptp(values)), 0.0, 0.0,
                              left="the room's reference: read as recorded, it drives the others' ambient terms"))
    if judge.per_run:
        judged_on = f"{len(runs)} runs, each held out once and fitted on the others (each run its own offset)"
    else:
        judged_on = (f"fitted on the first {settings.train_share:.0%} of {runs[0].name} "
                     f"({runs[0].duration_s * settings.train_share / 3600:.1f} h), judged on the rest")
    return HeatFit([run.name for run in runs], judged_on, out, list(columns.reference), judge)


__all__ = ["HeatFit", "Settings", "SensorHeat", "fit_heat"]
