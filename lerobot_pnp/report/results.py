"""The study's results pooled into the report's tables (no simulation, no text here).

``results``: method -> tag -> suite -> ``EpisodeRecord`` list, where a tag is a training seed, ``"-"``
(nothing trained) or ``"n<demos>"`` (a data-efficiency run, left out of the pooled rates). Success of a
learned method pools its training seeds (each seed evaluated on the same eval seeds); comparisons with the
lookup table are paired (exact McNemar per training seed; the largest p-value over seeds is reported, so
"beats" means "beats with every training seed").
"""

from __future__ import annotations

from lerobot_pnp.evaluation.stats import Rate, paired_comparison
from lerobot_pnp.evaluation.suites import HELD_OUT_AXES, SUITES, Axis

BASELINE = "lookup_table"


def is_main(tag: str) -> bool:
    """A training seed or ``"-"``: a run that the pooled rates count (not a data-efficiency run)."""
    return tag == "-" or tag.isdigit()


def pooled(runs: dict[str, dict[str, list]], suite: str) -> tuple[Rate, list[Rate]] | None:
    """Pooled rate over training seeds and the per-seed rates (seed tags that are numbers, or "-")."""
    per = [Rate(sum(r.success for r in s[suite]), len(s[suite])) for t, s in runs.items() if is_main(t) and suite in s]
    if not per:
        return None
    return Rate(sum(p.successes for p in per), sum(p.n for p in per)), per


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


def evaluated_suites(results) -> list[str]:
    """The suites some method was evaluated on, in catalogue order."""
    return [s for s in SUITES if any(s in runs for r in results.values() for runs in r.values())]


def build_table(results, methods, suite_names) -> dict:
    """suite -> method -> ``{"rate", "interval", "n", "per_seed"}`` (``summary.json``'s ``success``)."""
    table = {}
    for m in methods:
        for s in suite_names:
            p = pooled(results.get(m.name, {}), s)
            if p:
                table.setdefault(s, {})[m.name] = {
                    "rate": p[0].rate,
                    "interval": p[0].interval,
                    "n": p[0].n,
                    "per_seed": [q.rate for q in p[1]],
                }
    return table


def build_comparisons(results, methods, suite_names) -> dict:
    """method -> suite -> ``{"difference", "max_p", "per_seed"}`` against the lookup table."""
    comparisons = {}
    for m in methods:
        for s in suite_names:
            comps = compare(results, m.name, s)
            if comps:
                comparisons.setdefault(m.name, {})[s] = {
                    "difference": sum(c.difference for c in comps) / len(comps),
                    "max_p": max(c.p_value for c in comps),
                    "per_seed": [str(c) for c in comps],
                }
    return comparisons


def _pool(results, method: str, suites: tuple[str, ...]) -> Rate | None:
    """One rate over every record of ``method`` on the evaluated ones of ``suites`` (all training seeds)."""
    recs = [r for s in suites for r in main_records(results, method, s)]
    return Rate(sum(r.success for r in recs), len(recs)) if recs else None


def held_out_rates(results, methods) -> list[tuple[Axis, str, Rate, Rate]]:
    """Per disturbance axis of ``HELD_OUT_AXES`` and method: (axis, method, in distribution, held out), each
    pooled over the axis' suites that were evaluated; only where both sides were."""
    rows = []
    for axis in HELD_OUT_AXES:
        for m in methods:
            inside, outside = _pool(results, m.name, axis.in_distribution), _pool(results, m.name, axis.held_out)
            if inside and outside:
                rows.append((axis, m.name, inside, outside))
    return rows
