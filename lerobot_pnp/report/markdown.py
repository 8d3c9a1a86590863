"""``report.md``'s text from the pooled tables (``results``), the claims (``claims``) and the figure list; its
opening (how the study was produced and evaluated, its methods) is ``preamble``'s.

No numbers are computed here beyond formatting: the rates and comparisons come from ``results.build_table``
and ``results.build_comparisons``, so ``summary.json`` and ``report.md`` state the same values.
"""

from __future__ import annotations

from lerobot_pnp.evaluation.records import summarize
from lerobot_pnp.evaluation.results import Pooled, held_out_axes, main_records
from lerobot_pnp.evaluation.verdicts import MARGIN, TARGET, Verdict
from lerobot_pnp.presets import FULL_TASK, PAPER_TASK
from lerobot_pnp.report import coverage
from lerobot_pnp.report.claims import render_claims
from lerobot_pnp.report.preamble import header
from lerobot_pnp.sim.env_config import DENSE_FPS, DENSE_SECONDS_PER_KEYFRAME, dense_episode_length
from lerobot_pnp.sim.suites import RECOVERY_BUDGET, SUITES


def render(layout, cfg, methods, results, suite_names, table, comparisons, figures, summary, covered=((), {})) -> str:
    """The whole report, section by section; ``covered``: what it left out and the suite aliases (``coverage``),
    the first stated at the top."""
    left, aliases = covered
    lines = [
        "# lerobot_pnp: reproduction report",
        "",
        *_left_out_section(left, methods, summary),
        *header(layout, cfg, methods, summary, left),
        *_success_table(methods, suite_names, table, coverage.marks(left), aliases),
        *_alias_section(aliases),
        *_comparison_table(comparisons),
        *_failure_table(methods, results, suite_names),
        "## Figures",
        "",
    ]
    for caption, name in figures:
        lines += [f"### {caption}", "", f"![{caption}](figures/{name})", ""]
    stated = ["A claim that reads an evaluation left out of this report is not stated.", ""] if left else []
    lines += ["## Claims", "", *stated, *render_claims(table, comparisons), ""]
    lines += ["## Where the methods differ beyond their intervals", "", *_separations(table, methods), ""]
    lines += _held_out_section(table, methods)
    lines += _notes(methods, suite_names, getattr(cfg, "task_preset", "paper"))
    return "\n".join(lines)


def _success_table(methods, suite_names, table, marks: dict, aliases: dict) -> list[str]:
    """Pooled success per suite and method; a cell left out of the report reads "stale" or "missing"."""
    lines = [
        "## Success by suite",
        "",
        "| suite | what changes | " + " | ".join(m.label for m in methods) + " |",
        "|---|---|" + "---|" * len(methods),
    ]
    for s in suite_names:
        same = f" (the same conditions as `{aliases[s]}` on this task: its evaluation)" if s in aliases else ""
        lines.append(
            f"| `{s}` | {SUITES[s].description}{same} | "
            + " | ".join(marks.get((s, m.name)) or _cell(table.get(s, {}).get(m.name)) for m in methods)
            + " |"
        )
    return lines


def _left_out_section(left, methods, summary) -> list[str]:
    """Every evaluation (and stage) the report does not show, and why: at the top, so that it is read."""
    datasets = {k: v for k, v in summary["generation"].items() if isinstance(v, dict)} | {
        "keyframe": summary["generation"]
    }
    stale_data = [
        f"`{v['root']}` {v['status']}" for v in datasets.values() if "report_only" in str(v.get("status", ""))
    ]
    cli = (summary.get("lerobot_eval_cli_check") or {}).get("left_out")
    if not (left or stale_data or cli):
        return []
    labels = {m.name: m.label for m in methods}
    lines = [
        "## Left out of this report",
        "",
        "Written with `--report_only` from the finished evaluations only: the stages below do not match the config "
        "this report states, so no table, figure or claim below uses them (their cells read **stale** or "
        "**missing**; a figure's caption names what it does not draw). Their files are kept as they are; run the "
        "same command without `--report_only` to bring them up to date.",
        *(f"- Dataset {d}: every training and evaluation keyed on it is left out." for d in stale_data),
        *([f"- The `lerobot-eval` cross-check: {cli}."] if cli else []),
    ]
    if left:
        lines += ["", "| method | training seed | suite | why |", "|---|---|---|---|"]
        lines += [f"| {labels.get(x.method, x.method)} | {x.tag} | `{x.suite}` | {x.why()} |" for x in left]
    return [*lines, ""]


def _alias_section(aliases: dict) -> list[str]:
    """Which suites repeat another's conditions on this task (each such set is one evaluation)."""
    if not aliases:
        return []
    groups: dict[str, list[str]] = {}
    for alias, of in aliases.items():
        groups.setdefault(of, []).append(alias)
    return [
        "",
        "Suites of the same conditions on this task (their env configs built on it are equal) are one evaluation "
        "(the same seeds, the same episodes), shown under each name: "
        + "; ".join(f"{', '.join(f'`{a}`' for a in names)} = `{of}`" for of, names in groups.items())
        + ".",
    ]


def _comparison_table(comparisons) -> list[str]:
    lines = [
        "",
        "## Paired comparison with the lookup table (same eval seeds)",
        "",
        "Difference in success (method minus lookup table), mean over training seeds; p: exact McNemar "
        "(sign test on the episodes where exactly one of the two succeeds), the largest over training seeds.",
        "",
        "| method | suite | difference | max p | per seed |",
        "|---|---|---|---|---|",
    ]
    for m, rows in comparisons.items():
        for s, c in rows.items():
            verdict = " (significant)" if c.max_p < 0.05 else ""
            lines.append(
                f"| {m} | `{s}` | {100 * c.difference:+.1f} pts{verdict} | {c.max_p:.2g} | "
                + "; ".join(c.per_seed)
                + " |"
            )
    return lines


def _failure_table(methods, results, suite_names) -> list[str]:
    lines = [
        "",
        "## Failures by cause (all seeds pooled)",
        "",
        "| method | suite | failures by cause | by furthest phase |",
        "|---|---|---|---|",
    ]
    for m in methods:
        for s in suite_names:
            recs = main_records(results, m.name, s)
            if recs and any(not r.success for r in recs):
                sm = summarize(recs)
                lines.append(f"| {m.label} | `{s}` | {_fmt(sm['by_cause'])} | {_fmt(sm['by_phase'])} |")
    return [*lines, ""]


def _difference(v: Verdict) -> str:
    lo, hi = v.interval
    return f"{100 * v.difference:+.1f} [{100 * lo:+.1f}, {100 * hi:+.1f}]"


def _verdict_cell(v: Verdict) -> str:
    if v.code == "undecided" and v.episodes_to_decide:
        return f"{v.text} (about {v.episodes_to_decide} episodes a side would decide it)"
    return v.text


def _held_out_section(table, methods) -> list[str]:
    """A table per disturbance axis (``HELD_OUT_AXES``): each method's success in distribution vs held out,
    for the methods evaluated on every suite of the axis; the rule of the verdict column stated above them."""
    rows = held_out_axes(table, methods)
    if not rows:
        return []
    labels = {m.name: m.label for m in methods}
    lines = [
        "## In distribution vs held out, per disturbance axis",
        "",
        "Trained on the training conditions (the recorded task's distributions); each axis' held-out suites go "
        "beyond them on that axis only. Each side pools every episode of its suites over all training seeds "
        "(95 % Wilson). Difference: held out minus in distribution, with its 95 % interval (Newcombe, the two "
        f"sides are different suites: not paired). **Verdict rule** (non-inferiority, margin {100 * MARGIN:.0f} "
        f"points): with >= {100 * TARGET:.0f} % in distribution, recovery generalises along an axis when the "
        f"interval's lower bound lies above -{100 * MARGIN:.0f} points, does not generalise when its upper bound "
        f"lies below -{100 * MARGIN:.0f}, and is undecided otherwise (with the episodes a side that would decide "
        f"it); below {100 * TARGET:.0f} % in distribution there is no verdict.",
        "",
    ]
    for axis in dict.fromkeys(r.axis for r in rows):
        lines += [
            f"### {axis.name}: {axis.description}",
            "",
            f"In distribution: {', '.join(f'`{s}`' for s in axis.in_distribution)}; held out: "
            f"{', '.join(f'`{s}`' for s in axis.held_out)}.",
            "",
            "| method | in distribution | held out | per held-out suite | difference [95 %] | verdict |",
            "|---|---|---|---|---|---|",
        ]
        for r in (r for r in rows if r.axis == axis):
            each = "<br>".join(f"`{s}` {v} n={v.n}" for s, v in r.held_out.items())
            lines.append(
                f"| {labels[r.method]} | {r.inside} n={r.inside.n} | {r.outside} n={r.outside.n} | {each} | "
                f"{_difference(r.judged)} | {_verdict_cell(r.judged)} |"
            )
        lines.append("")
    return lines


def _notes(methods, suite_names, task: str) -> list[str]:
    """The limits that apply to this study's suites and task (a note about a suite it did not run is noise)."""
    names = set(suite_names)
    ring = {"edge_strip", "outside_ring"} & names
    recovery = {n for n in names if n.split("_")[0] in ("grasp", "drop", "displace")}
    return [
        "## Notes and limits",
        "",
        *(
            [
                "- The inside strip and the outside ring are sampled exactly uniformly: one box minus an excluded inner "
                "box (`object_exclude_low/high`, rejection sampling in the env)."
            ]
            if ring
            else []
        ),
        "- The expert is privileged (it reads the simulator) and runs its own loop on the same seeds.",
        *(
            [
                f"- Perturbations that need room to recover (missed grasp, drop, displacement) get a {RECOVERY_BUDGET}-"
                "keyframe budget for every method; the clocked LSTM stops acting after its 10-step clock (it holds its "
                "last action)."
            ]
            if recovery and task == "paper"
            else []
        ),
        *(
            [
                "- Each protocol suite keeps the recorded task's perturbations and gives every method 10 keyframes per "
                "event plus two spare attempts (`suites._kind`); `train_nudge` and `train_mixture` are the training task "
                "itself: one evaluation with `nominal` (see under the success table)."
            ]
            if task != "paper"
            else []
        ),
        *_dense_notes(methods),
        "",
    ]


def _cell(v: Pooled | None) -> str:
    if not v:
        return "-"
    lo, hi = v.interval
    spread = ""
    if len(v.per_seed) > 1:
        rates = [q.rate for q in v.per_seed]
        spread = f"<br>seeds {min(rates) * 100:.0f}-{max(rates) * 100:.0f}%"
    return f"**{100 * v.rate.rate:.1f}%** [{100 * lo:.1f}, {100 * hi:.1f}] n={v.rate.n}{spread}"


def _dense_notes(methods) -> list[str]:
    if not any(m.data == "dense" for m in methods):
        return []

    paper, full = PAPER_TASK["keyframe_budget"], FULL_TASK["keyframe_budget"]
    return [
        f"- Dense-control methods (ACT) run each suite's task at {DENSE_FPS} fps with {DENSE_SECONDS_PER_KEYFRAME} s "
        f"of control per keyframe of the suite's budget ({dense_episode_length(paper)} steps for the paper task's "
        f"{paper} keyframes, {dense_episode_length(RECOVERY_BUDGET)} for its recovery suites' {RECOVERY_BUDGET}, "
        f"{dense_episode_length(full)} for the full task's {full}): "
        "the keyframe methods' budget at the dense expert's pace (15-18 steps per keyframe, "
        "`benchmarks/dense_pace.py`) with a few steps to spare. A nudge fires at the dense step where the expert "
        "reaches its first keyframe (median "
        "over the training demonstrations), the keyframe suites' 'after the first keyframe'. Observation latency "
        "counts env steps: one is 50 ms in dense mode against one whole keyframe move in keyframe mode, so the "
        "latency suites do not compare the two control modes.",
    ]


def _fmt(d: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(d.items(), key=lambda kv: -kv[1])) or "-"


def _separations(table, methods) -> list[str]:
    """Per suite: the best learned or baseline method (not the expert) and those whose 95 % interval lies
    entirely below its interval (the benchmark tells them apart)."""
    labels = {m.name: m.label for m in methods}
    rows = ["| suite | best (not the expert) | below it beyond both intervals |", "|---|---|---|"]
    separated = 0
    for s, row in table.items():
        cands = {m: v for m, v in row.items() if m != "expert"}
        if len(cands) < 2:
            continue
        best = max(cands, key=lambda m: (cands[m].interval[0], cands[m].rate.rate))
        below = [m for m, v in cands.items() if v.interval[1] < cands[best].interval[0]]
        separated += bool(below)
        rows.append(
            f"| `{s}` | {labels.get(best, best)} {100 * cands[best].rate.rate:.1f}% | "
            + (", ".join(f"{labels.get(m, m)} {100 * cands[m].rate.rate:.1f}%" for m in below) or "-")
            + " |"
        )
    return [f"The methods are told apart on {separated} of {len(rows) - 2} suites.", "", *rows]
