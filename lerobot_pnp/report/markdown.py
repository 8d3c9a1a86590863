"""``report.md``'s text from the pooled tables (``results``), the claims (``claims``) and the figure list.

No numbers are computed here beyond formatting: the rates and comparisons come from ``results.build_table``
and ``results.build_comparisons``, so ``summary.json`` and ``report.md`` state the same values.
"""

from __future__ import annotations

import json
import math

from lerobot_pnp.dataset.splits import train_count
from lerobot_pnp.env_config import DENSE_FPS, DENSE_SECONDS_PER_KEYFRAME, dense_episode_length
from lerobot_pnp.evaluation.records import summarize
from lerobot_pnp.evaluation.suites import RECOVERY_BUDGET, SUITES
from lerobot_pnp.presets import FULL_TASK, PAPER_TASK
from lerobot_pnp.report import coverage
from lerobot_pnp.report.claims import render_claims
from lerobot_pnp.report.methods import METHODS
from lerobot_pnp.report.results import ALPHA, TARGET, Pooled, held_out_axes, main_records


def render(layout, cfg, methods, results, suite_names, table, comparisons, figures, summary, covered=((), {})) -> str:
    """The whole report, section by section; ``covered``: what it left out and the suite aliases (``coverage``),
    the first stated at the top."""
    left, aliases = covered
    lines = [
        "# lerobot_pnp: reproduction report",
        "",
        *_left_out_section(left, methods, summary),
        *_header(layout, cfg, methods, summary, left),
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


def _invocation(cfg, t: dict) -> str:
    """What this invocation itself did: report only, or its wall clock and job processes."""
    if cfg.report_only:
        return f"This invocation: the report only ({t.get('run/wall_clock', 0):.0f} s; nothing trained or evaluated)."
    return (
        f"This invocation: {t.get('run/wall_clock', 0) / 60:.0f} min wall clock with {t.get('run/processes', 1):.0f} "
        "job process(es) (training and evaluation jobs run side by side, one core each)."
    )


def _header(layout, cfg, methods, summary, left=()) -> list[str]:
    mach, t = summary["machine"], summary["timings_s"]
    total = sum(v for k, v in t.items() if not k.startswith("run/"))
    return [
        f"Produced by `{summary['command']}` (preset `{cfg.preset}`; full config in `{layout.config.name}`). "
        f"Task: `{cfg.task_preset}` (the demonstrations' task, recorded with them; every suite changes it).",
        f"Machine: {mach['cpu']}, {mach['cores_available']} cores available; Python {mach['python']}, "
        f"LeRobot {mach['lerobot']}, torch {mach['torch']}, MuJoCo {mach['mujoco']}, gymnasium {mach['gymnasium']}.",
        f"Stage wall time (s): dataset {t.get('dataset', 0):.0f}"
        + "".join(f" (+ {k.split('_', 1)[1]} recording {v:.0f})" for k, v in t.items() if k.startswith("dataset_"))
        + ", training "
        f"{sum(v for k, v in t.items() if k.startswith('train/')):.0f}, evaluation "
        f"{sum(v for k, v in t.items() if k.startswith('eval/')):.0f} (total {total:.0f}; an evaluation reused from an "
        "earlier run shows its original time, a training its original time if it was recorded (none otherwise), a "
        "reused dataset only the time to find it). " + _invocation(cfg, t),
        "",
        "Evaluation: stock LeRobot `lerobot.scripts.lerobot_eval.eval_policy` (the function `lerobot-eval` runs), "
        f"called in process on the `SyncVectorEnv` of `BaxterPnPEnvConfig.create_envs` ({cfg.eval_batch_size} envs "
        "at a time, part of each evaluation's key: a learned policy's marginal episodes can end differently at "
        "another batch size), with a recording wrapper for the final `info` of each episode. Every method runs "
        f"the same seeds ({cfg.eval_seed} onwards, unseen "
        f"by the dataset's seeds 0..). Learned methods: {len(cfg.train_seeds)} training seeds {cfg.train_seeds}, "
        f"{cfg.epochs} epochs each on {train_count(cfg.num_episodes)} demonstrations"
        + (" (dense-control methods: their budget is under Methods)" if any(m.data == "dense" for m in methods) else "")
        + "; their rate pools the seeds.",
        *_cli_lines(summary.get("lerobot_eval_cli_check")),
        "Intervals: 95 % Wilson. Pooling seeds treats them as one sample; the per-seed range is shown beside it."
        + _episodes_rule_sentence(cfg),
        "",
        "## Methods",
        "",
        *_recipe_changes_line(cfg, methods),
        *_method_lines(methods, t, _parameter_counts(layout, methods, cfg), left),
        "",
    ]


def _recipe_changes_line(cfg, methods) -> list[str]:
    """The study's changes to the recovering recipe (``StudyConfig.recipe_changes``), when a method takes it:
    the method descriptions below name the shipped recipe."""
    changes = getattr(cfg, "recipe_changes", None) or {}
    takers = [m.label for m in methods if m.policy_overrides.get("mode") == "recovering"]
    if not (changes and takers):
        return []
    listed = ", ".join(f"`{k}` = {json.dumps(v)}" for k, v in changes.items())
    return [
        f"This study changes the shipped recovering recipe for every method that takes it ({', '.join(takers)}): "
        f"{listed}. The descriptions below name the shipped recipe; the parameter counts are of what was trained.",
        "",
    ]


def _episodes_rule_sentence(cfg) -> str:
    """The episode counts' rules in a few sentences (``StudyConfig.split_over_seeds``, ``config.EpisodeRule``),
    or "" when every evaluation of every seed runs its suite's n."""
    split = ""
    if getattr(cfg, "split_over_seeds", False):
        split = (
            f" A suite's n is split over a learned method's {len(cfg.train_seeds)} training seeds (n / "
            f"{len(cfg.train_seeds)} per seed, rounded up to whole batches of {cfg.eval_batch_size}), so that a "
            "cell, which pools the seeds, holds about n episodes as a method without seeds does."
        )
    rule = getattr(cfg, "episodes_rule", None)
    if rule is None:
        return split
    fixed = ", ".join(METHODS[m].label for m in rule.fixed_methods if m in METHODS)
    claims = ", ".join(METHODS[m].label for m in rule.claim_methods if m in METHODS)
    claim = (
        f" The claims' method ({claims}) runs at least every suite's n, exactly the fixed run's episodes, and "
        f"goes on in blocks of {rule.block} seeds while its interval is wider than +-{100 * rule.claim_half_width:g}"
        f" pts, up to {rule.claim_max_factor}x n: a cell near a bar (90 / 95 / 98 %) is where an interval at n "
        "cannot decide it, so more episodes go there and nowhere else (a training seed that scores lower runs "
        "more of them, which weighs the pooled cell towards it)."
        if claims
        else ""
    )
    others = "every other method's" if fixed else "every method's" + (" but the claims' method's" if claims else "")
    return split + (
        " Episode counts are chosen from the interval widths they need: "
        + (f"{fixed} run every suite's n; " if fixed else "")
        + f"{others} evaluation runs blocks of {rule.block} seeds from the first and stops after the first block "
        f"whose 95 % Wilson interval is at most +-{100 * rule.half_width:g} pts, or at the suite's n (a target "
        f"per evaluation: a cell pooling {len(cfg.train_seeds)} seeds is about {len(cfg.train_seeds) ** 0.5:.1f}x "
        "narrower; each cell shows its n). Every method runs the same first seeds, so a paired comparison pairs two methods on the "
        "seeds both ran (the common prefix). An evaluation reused by cutting an earlier fixed-n one to the rule's "
        "stop (exactly the episodes a fresh run makes) shows its share of the original time, estimated by steps."
        + claim
    )


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


VERDICT_TEXT = {  # results.VERDICTS
    "generalises": "generalises",
    "degrades": f"every held-out suite >= {100 * TARGET:.0f} %, but significantly below in distribution",
    "fails": f"does not generalise: a held-out suite below {100 * TARGET:.0f} %",
    "no_recovery": f"below {100 * TARGET:.0f} % in distribution already: nothing to generalise",
}


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
        "(95 % Wilson). p: one-sided exact (Fisher) test that the held-out rate is below the in-distribution "
        f"one by chance (different suites: not paired). **Verdict rule**: recovery generalises along an axis "
        f"when the method gets >= {100 * TARGET:.0f} % in distribution, >= {100 * TARGET:.0f} % on every "
        f"held-out suite (point estimates) and p >= {ALPHA:g}; 'significantly below' when every held-out suite "
        f"reaches {100 * TARGET:.0f} % but p < {ALPHA:g}.",
        "",
    ]
    for axis in dict.fromkeys(r.axis for r in rows):
        lines += [
            f"### {axis.name}: {axis.description}",
            "",
            f"In distribution: {', '.join(f'`{s}`' for s in axis.in_distribution)}; held out: "
            f"{', '.join(f'`{s}`' for s in axis.held_out)}.",
            "",
            "| method | in distribution | held out | per held-out suite | p | verdict |",
            "|---|---|---|---|---|---|",
        ]
        for r in (r for r in rows if r.axis == axis):
            each = "<br>".join(f"`{s}` {v} n={v.n}" for s, v in r.held_out.items())
            lines.append(
                f"| {labels[r.method]} | {r.inside} n={r.inside.n} | {r.outside} n={r.outside.n} | {each} | "
                f"{r.p_below:.2g} | {VERDICT_TEXT[r.verdict]} |"
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
    lo, hi = v.rate.interval
    spread = ""
    if len(v.per_seed) > 1:
        rates = [q.rate for q in v.per_seed]
        spread = f"<br>seeds {min(rates) * 100:.0f}-{max(rates) * 100:.0f}%"
    return f"**{100 * v.rate.rate:.1f}%** [{100 * lo:.1f}, {100 * hi:.1f}] n={v.rate.n}{spread}"


def _parameter_counts(layout, methods, cfg) -> dict[str, int]:
    """Trained parameters of each learned method (its first seed's checkpoint), read from the safetensors header."""
    from safetensors import safe_open

    counts = {}
    for m in methods:
        files = sorted(layout.train(m.name, str(cfg.train_seeds[0])).rglob("model.safetensors"))
        if m.learned and files:
            with safe_open(str(files[-1]), "pt") as f:
                counts[m.name] = sum(math.prod(f.get_slice(k).get_shape()) for k in f.keys())  # noqa: SIM118
    return counts


def _method_lines(methods, timings: dict, params: dict[str, int], left=()) -> list[str]:
    """One line per method: what it is and, for a learned one, its size and training wall time per seed (of
    the training on disk: said so when that is not the one the config states)."""
    out = []
    for m in methods:
        times = [v for k, v in timings.items() if k.startswith(f"train/{m.name}/") and k.split("/")[-1].isdigit()]
        cost = f" Training wall time per seed: {', '.join(f'{v:.0f} s' for v in times)}." if times else ""
        if m.name in params:
            cost = f" {params[m.name]:,} parameters.{cost}"
        only = f" Evaluated on {', '.join(m.suites)} only (cost)." if m.suites is not None else ""
        cost += coverage.training_note(left, m.name, m.label)
        out.append(f"- **{m.label}** (`{m.name}`): {m.description}.{only}{cost}")
    return out


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


def _cli_lines(c: dict | None) -> list[str]:
    if not c:
        return []
    if "left_out" in c:
        return [f"Cross-check with the real `lerobot-eval` CLI: left out ({c['left_out']}; see the top)."]
    return [
        f"Cross-check with the real `lerobot-eval` CLI (subprocess, `{c['eval_info']}`): {c['method']} seed "
        f"{c['seed']} on the first {c['n']} nominal seeds: {c['cli_pc_success']:.1f}% success; the in-process "
        f"records agree on {c['agree']} of {c['n']} episodes.",
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
        best = max(cands, key=lambda m: (cands[m].rate.interval[0], cands[m].rate.rate))
        below = [m for m, v in cands.items() if v.rate.interval[1] < cands[best].rate.interval[0]]
        separated += bool(below)
        rows.append(
            f"| `{s}` | {labels.get(best, best)} {100 * cands[best].rate.rate:.1f}% | "
            + (", ".join(f"{labels.get(m, m)} {100 * cands[m].rate.rate:.1f}%" for m in below) or "-")
            + " |"
        )
    return [f"The methods are told apart on {separated} of {len(rows) - 2} suites.", "", *rows]
