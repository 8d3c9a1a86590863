"""What a report covers: the evaluations it left out and why, and the suites that are one evaluation.

A report never states a config it did not run. With ``--report_only`` nothing is trained or evaluated, so an
evaluation whose key no longer matches the config (its training's key changed, say) or that was never made is
**left out** (``LeftOut``): named at the top of ``report.md`` and in ``summary.json`` with the part of its key
that changed, its cell marked instead of a rate pooled over fewer training seeds (the method's current seeds
of that cell are withheld too, and named), and its files kept as they are (a cached stage deletes only its own).

Suites whose env configs built on the task are equal (``train_nudge`` and ``train_mixture`` are ``nominal``
on ``full``, which already draws them) are **aliases** (``suite_aliases``): one evaluation under the first
name, its records shown under every name, and the report says which suite each one repeats.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

from lerobot_pnp.cache import Stage, canonical
from lerobot_pnp.evaluation.results import is_main

REASONS = {
    "missing": "never evaluated",
    "stale": "its key changed since it ran",
    "withheld": "current, but another training seed of this cell is left out: no rate pooled over fewer seeds",
}


@dataclass(frozen=True)
class LeftOut:
    """One method x tag x suite evaluation the report does not show: ``reason`` (``REASONS``) and, when stale,
    the parts of its key that changed (a training's own changed parts as ``train.<part>``)."""

    method: str
    tag: str  # a training seed, "-" or "n<demos>" (``run.Job.tag``)
    suite: str
    reason: str
    changed: tuple[str, ...] = ()

    def why(self) -> str:
        detail = f" ({', '.join(self.changed)})" if self.changed else ""
        return f"{self.reason}: {REASONS[self.reason]}{detail}"

    def to_json(self) -> dict:
        return {**asdict(self), "changed": list(self.changed), "why": self.why()}


def left_out(method: str, tag: str, suite: str, stage: Stage, train: Stage | None) -> LeftOut:
    """Why the evaluation of ``stage`` is not current. A changed ``train`` part is told apart further by the
    training's own record (``train``: its current stage): which of its parts changed, or that it has no record
    (never trained), or none changed (trained again since this evaluation ran)."""
    changed = stage.changes()
    if changed is None:
        return LeftOut(method, tag, suite, "missing")
    parts = []
    for name in changed:
        if name == "train" and train is not None:
            train_changed = train.changes()
            if train_changed is None:
                parts.append("train: no training on disk")
            elif train_changed:
                parts += [f"train.{p}" for p in train_changed]
            else:
                parts.append("train: trained again since")
        else:
            parts.append(name)
    return LeftOut(method, tag, suite, "stale", tuple(parts))


def withhold(results: dict, left: list[LeftOut]) -> tuple[dict, list[LeftOut]]:
    """``results`` without the cells that lost a training seed, and every entry left out: the given ones and
    the withheld current seeds of those cells (so no table pools fewer seeds than the config states)."""
    cells = {(x.method, x.suite) for x in left if is_main(x.tag)}
    kept: dict = {}
    withheld = []
    for method, runs in results.items():
        for tag, suites in runs.items():
            for suite, records in suites.items():
                if is_main(tag) and (method, suite) in cells:
                    withheld.append(LeftOut(method, tag, suite, "withheld"))
                else:
                    kept.setdefault(method, {}).setdefault(tag, {})[suite] = records
    return kept, sorted([*left, *withheld], key=lambda x: (x.method, x.suite, x.tag))


def marks(left: list[LeftOut]) -> dict[tuple[str, str], str]:
    """(suite, method) -> the text of its table cell: "stale" or "missing" with the seeds concerned."""
    out: dict[tuple[str, str], list[LeftOut]] = {}
    for x in left:
        if x.reason != "withheld" and is_main(x.tag):
            out.setdefault((x.suite, x.method), []).append(x)
    return {
        cell: "; ".join(
            f"**{reason}**" + ("" if xs[0].tag == "-" else f" (seed {', '.join(x.tag for x in xs)})")
            for reason in ("stale", "missing")
            if (xs := [x for x in entries if x.reason == reason])
        )
        for cell, entries in out.items()
    }


def figure_note(left: list[LeftOut], suites, labels: dict[str, str], data_efficiency: bool = False) -> str:
    """The caption's note for a figure drawn from ``suites``: the methods not drawn on them, or ""."""
    gone = dict.fromkeys(
        (labels.get(x.method, x.method), x.suite)
        for x in left
        if x.suite in suites and (x.tag.startswith("n") if data_efficiency else is_main(x.tag))
    )
    if not gone:
        return ""
    return " (not drawn, left out of this report: " + ", ".join(f"{m} on `{s}`" for m, s in gone) + ")"


def training_note(left: list[LeftOut], method: str, label: str) -> str:
    """The caption's note for a figure drawn from ``method``'s trainings when one of them is not current."""
    changed = sorted(
        {p for x in left if x.method == method and is_main(x.tag) for p in x.changed if p.startswith("train")}
    )
    if not changed:
        return ""
    return f" (the {label}'s training on disk, not the one this report's config states: {', '.join(changed)})"


def suite_aliases(pairs, base_env) -> dict[str, str]:
    """suite name -> the name of the first suite in ``pairs`` ((suite, episodes), in study order) with the same
    effective conditions: env configs built on ``base_env`` and episodes per part (itself when none before)."""
    first: dict[str, str] = {}
    out = {}
    for suite, n in pairs:
        conditions = [
            (c.to_dict(), k) for c, k in zip(suite.env_configs(base_env), suite.part_episodes(n), strict=True)
        ]
        out[suite.name] = first.setdefault(json.dumps(canonical(conditions), sort_keys=True), suite.name)
    return out
