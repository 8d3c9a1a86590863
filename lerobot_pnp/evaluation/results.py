"""The study's results pooled into the report's tables (no simulation, no text here).

``results``: method -> tag -> suite -> ``EpisodeRecord`` list, where a tag is a training seed, ``"-"``
(nothing trained) or ``"n<demos>"`` (a data-efficiency run, left out of the pooled rates). Success of a
learned method pools its training seeds (each seed evaluated on the same eval seeds); comparisons with the
lookup table are paired (exact McNemar per training seed; the largest p-value over seeds is reported, so
"beats" means "beats with every training seed"). Per axis of the held-out protocol (``ALL_AXES``): each
side pooled over its suites and the verdict of the one rule, ``verdicts.axis_verdict`` (``axis_result``).
"""

from __future__ import annotations

from dataclasses import dataclass

from lerobot_pnp.evaluation.stats import Rate, paired_comparison, seed_interval
from lerobot_pnp.evaluation.verdicts import MARGIN, Verdict, axis_verdict
from lerobot_pnp.sim.suites import ALL_AXES, SUITES, Axis

BASELINE = "lookup_table"


@dataclass(frozen=True)
class Pooled:
    """A method's success on a suite: its training seeds pooled, and each seed's own rate. Its ``interval``
    counts the training seeds as well as the episodes (``stats.seed_interval``); ``rate.interval`` is the
    episodes' Wilson interval alone."""

    rate: Rate
    per_seed: tuple[Rate, ...]

    @property
    def interval(self) -> tuple[float, float]:
        return seed_interval(self.rate, [q.rate for q in self.per_seed])

    def __str__(self) -> str:
        lo, hi = self.interval
        return f"{100 * self.rate.rate:.1f}% [{100 * lo:.1f}, {100 * hi:.1f}]"

    def to_json(self) -> dict:
        """``summary.json``'s cell: the pooled rate, its interval (seeds counted) and the episodes' Wilson interval,
        its episodes, and the per-seed rates."""
        return {"rate": self.rate.rate, "interval": self.interval, "episode_interval": self.rate.interval,
                "n": self.rate.n, "per_seed": [q.rate for q in self.per_seed]}  # fmt: skip


@dataclass(frozen=True)
class Comparison:
    """A method against the lookup table on one suite: the mean difference over training seeds, the largest
    p-value over them (so "beats" means with every seed) and each seed's paired comparison as text."""

    difference: float
    max_p: float
    per_seed: tuple[str, ...]

    def to_json(self) -> dict:
        return {"difference": self.difference, "max_p": self.max_p, "per_seed": list(self.per_seed)}


def is_main(tag: str) -> bool:
    """A training seed or ``"-"``: a run that the pooled rates count (not a data-efficiency run)."""
    return tag == "-" or tag.isdigit()


def pooled(runs: dict[str, dict[str, list]], suite: str) -> Pooled | None:
    """Pooled rate over training seeds and the per-seed rates (seed tags that are numbers, or "-")."""
    per = [Rate(sum(r.success for r in s[suite]), len(s[suite])) for t, s in runs.items() if is_main(t) and suite in s]
    if not per:
        return None
    return Pooled(Rate(sum(p.successes for p in per), sum(p.n for p in per)), tuple(per))


def main_records(results, method: str, suite: str) -> list:
    """Every record of ``method`` on ``suite`` over its training seeds (the data-efficiency runs left out)."""
    return [r for tag, runs in results.get(method, {}).items() if is_main(tag) for r in runs.get(suite, [])]


def compare(results, method: str, suite: str):
    """Paired comparison of ``method`` with the lookup table on ``suite``, per training seed."""
    base = results.get(BASELINE, {}).get("-", {}).get(suite)
    if base is None or method == BASELINE:
        return None
    b = {r.seed: r.success for r in base}
    comps = [
        paired_comparison({r.seed: r.success for r in runs[suite]}, b)
        for tag, runs in results.get(method, {}).items()
        if is_main(tag) and suite in runs
    ]
    return comps or None


def evaluated_suites(results, also=()) -> list[str]:
    """The suites some method was evaluated on (and those in ``also``), in catalogue order."""
    return [s for s in SUITES if s in also or any(s in runs for r in results.values() for runs in r.values())]


def build_table(results, methods, suite_names) -> dict[str, dict[str, Pooled]]:
    """suite -> method -> its pooled success (``summary.json``'s ``success``), for what was evaluated."""
    table: dict[str, dict[str, Pooled]] = {}
    for m in methods:
        for s in suite_names:
            p = pooled(results.get(m.name, {}), s)
            if p:
                table.setdefault(s, {})[m.name] = p
    return table


def build_comparisons(results, methods, suite_names) -> dict[str, dict[str, Comparison]]:
    """method -> suite -> its paired comparison with the lookup table (``summary.json``'s ``vs_lookup_table``)."""
    comparisons: dict[str, dict[str, Comparison]] = {}
    for m in methods:
        for s in suite_names:
            comps = compare(results, m.name, s)
            if comps:
                comparisons.setdefault(m.name, {})[s] = Comparison(
                    sum(c.difference for c in comps) / len(comps), max(c.p_value for c in comps), tuple(map(str, comps))
                )
    return comparisons


@dataclass(frozen=True)
class AxisResult:
    """A method on one axis of ``ALL_AXES`` (a disturbance or a visual one): each side pooled over its suites (and
    training seeds), each held-out suite's own rate, and the verdict of the one rule (``verdicts.axis_verdict``)."""

    axis: Axis
    method: str
    inside: Rate
    outside: Rate
    held_out: dict[str, Rate]  # per held-out suite
    judged: Verdict

    @property
    def verdict(self) -> str:
        """The verdict's code, one of ``verdicts.VERDICTS``."""
        return self.judged.code

    def to_json(self) -> dict:
        """``summary.json``'s ``held_out_axes`` entry."""

        def cell(r: Rate) -> dict:
            return {"rate": r.rate, "interval": r.interval, "successes": r.successes, "n": r.n}

        return {"axis": self.axis.name, "method": self.method, "in_distribution": cell(self.inside),
                "held_out": cell(self.outside), "held_out_suites": {s: cell(r) for s, r in self.held_out.items()},
                "difference": self.judged.difference, "difference_interval": list(self.judged.interval),
                "margin": MARGIN, "verdict": self.verdict,
                "episodes_to_decide": self.judged.episodes_to_decide}  # fmt: skip


def _sum(rates: list[Rate]) -> Rate:
    return Rate(sum(r.successes for r in rates), sum(r.n for r in rates))


def axis_result(axis: Axis, method: str, table: dict[str, dict[str, Pooled]]) -> AxisResult | None:
    """``method`` on ``axis`` from the pooled table; None unless every suite of the axis was evaluated for it
    (a verdict on part of an axis would claim more than was measured)."""
    cells = {s: table.get(s, {}).get(method) for s in axis.in_distribution + axis.held_out}
    if not all(cells.values()):
        return None
    inside = _sum([cells[s].rate for s in axis.in_distribution])
    held = {s: cells[s].rate for s in axis.held_out}
    outside = _sum(list(held.values()))
    return AxisResult(axis, method, inside, outside, held, axis_verdict(inside, outside))


def axis_phrase(r: AxisResult) -> str:
    """The verdict on one axis as a phrase (the report's claims and ``lerobot-pnp compare`` state it)."""
    return r.judged.phrase()


def held_out_axes(table: dict[str, dict[str, Pooled]], methods) -> list[AxisResult]:
    """Per axis of ``ALL_AXES`` (in order: the disturbance axes, then the visual ones), each method (in order) that
    has every suite of the axis."""
    found = (axis_result(axis, m.name, table) for axis in ALL_AXES for m in methods)
    return [r for r in found if r is not None]
