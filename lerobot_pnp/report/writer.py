"""``report.md``, its figures and ``summary.json`` from the evaluation records (no simulation here).

The pooled tables come from ``results``, the figures from ``figures``, the text from ``markdown`` (with the
claims of ``claims``); every path from the study's ``StudyLayout``.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

from lerobot_pnp.evaluation.results import build_comparisons, build_table, evaluated_suites, held_out_axes
from lerobot_pnp.outputs import write_bytes_atomic, write_json_atomic
from lerobot_pnp.report import figures, markdown
from lerobot_pnp.report.layout import StudyLayout

HEADLINE_SUITES = ("nominal", "nudge_0.03")


@dataclass(frozen=True)
class StudyInputs:
    """What the report is written from: the study's config and methods, its records (method -> tag -> suite ->
    records), the training task, and the run's provenance (generation summaries, timings, machine, command)."""

    cfg: object
    methods: list
    results: dict
    base_env: object
    generation: dict
    timings: dict
    machine: dict
    command: str
    cli_check: dict | None = None
    left_out: list = field(default_factory=list)
    aliases: dict = field(default_factory=dict)


def _figures_drawn_before(layout: StudyLayout) -> set[str]:
    """The figure files the previous report in this folder drew (its ``summary.json``): the only files in
    ``figures/`` a new report may remove, so that a figure it no longer draws does not linger beside its own,
    and nothing it did not write is touched."""
    try:
        names = json.loads(layout.summary.read_text()).get("figures", [])
    except (OSError, ValueError, AttributeError):
        return set()
    return {n for n in names if isinstance(n, str) and n == Path(n).name and n.endswith(".png")}


def write_report(layout: StudyLayout, study: StudyInputs) -> dict:
    """Write the figures, ``summary.json`` and ``report.md``; return the report path and the headline rates."""
    cfg, methods, results = study.cfg, study.methods, study.results
    prov = (
        f"{study.command}  |  config: {layout.config}  |  {study.machine['cpu']}, "
        f"{study.machine['cores_available']} cores"
    )
    suite_names = evaluated_suites(results)
    drawn_before = _figures_drawn_before(layout)
    figs = figures.make_figures(layout, cfg, methods, results, suite_names, study.base_env, prov, study.left_out)
    for stale in drawn_before - {f for _, f in figs}:  # drawn by an earlier report here, not by this one
        layout.figure(stale).unlink(missing_ok=True)
    suite_names = evaluated_suites(results, [x.suite for x in study.left_out])  # a left-out cell is marked
    table = build_table(results, methods, suite_names)
    comparisons = build_comparisons(results, methods, suite_names)
    summary = {
        "command": study.command,
        "machine": study.machine,
        "config": asdict(cfg),
        "generation": study.generation,
        "success": {s: {m: cell.to_json() for m, cell in row.items()} for s, row in table.items()},
        "vs_lookup_table": {m: {s: c.to_json() for s, c in row.items()} for m, row in comparisons.items()},
        "timings_s": study.timings,
        "lerobot_eval_cli_check": study.cli_check,
        "figures": [f for _, f in figs],
        "left_out": [x.to_json() for x in study.left_out],  # evaluations not shown (report_only), and why
        "suite_aliases": study.aliases,  # suite -> the suite of the same conditions whose evaluation it shows
    }
    held_out = held_out_axes(table, methods)
    if held_out:  # only a study that ran every suite of an axis (the held-out protocol)
        summary["held_out_axes"] = [r.to_json() for r in held_out]
    write_json_atomic(layout.summary, summary)
    text = markdown.render(layout, cfg, methods, results, suite_names, table, comparisons, figs, summary,
                           (study.left_out, study.aliases))  # fmt: skip
    write_bytes_atomic(layout.report, text.encode())
    labels = {m.name: m.label for m in methods}
    return {
        "report": str(layout.report),
        **{
            f"{labels[m]} / {s}": str(v.rate)
            for s, row in table.items()
            if s in HEADLINE_SUITES
            for m, v in row.items()
        },
    }
