"""``report.md``, its figures and ``summary.json`` from the evaluation records (no simulation here).

Success of a learned method pools its training seeds (each seed evaluated on the same eval seeds); the
per-seed rates are listed beside it so the spread between seeds is visible. Comparisons with the lookup
table are paired (exact McNemar per training seed; the largest p-value over seeds is reported, so "beats"
means "beats with every training seed").
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

from lerobot_pnp import robot
from lerobot_pnp.report import adapters, plots
from lerobot_pnp.report.stats import Rate, paired_comparison
from lerobot_pnp.report.suites import SUITES

BASELINE = "lookup_table"


def pooled(runs: dict[str, dict[str, list]], suite: str) -> tuple[Rate, list[Rate]] | None:
    """Pooled rate over training seeds and the per-seed rates (seed tags that are numbers, or "-")."""
    per = [Rate(sum(r.success for r in s[suite]), len(s[suite])) for t, s in runs.items() if _main(t) and suite in s]
    if not per:
        return None
    return Rate(sum(p.successes for p in per), sum(p.n for p in per)), per


def _main(tag: str) -> bool:
    return tag == "-" or tag.isdigit()


def compare(results, method: str, suite: str):
    """Paired comparison of ``method`` with the lookup table on ``suite``, per training seed."""
    base = results.get(BASELINE, {}).get("-", {}).get(suite)
    if base is None or method == BASELINE:
        return None
    b = {r.seed: r.success for r in base}
    comps = [
        paired_comparison({r.seed: r.success for r in runs[suite]}, b)
        for tag, runs in results[method].items()
        if _main(tag) and suite in runs
    ]
    return comps or None


def write_report(
    out: Path, cfg, methods, results, base_env, generation, timings, machine, command, cli_check=None
) -> dict:
    figs = out / "figures"
    prov = f"{command}  |  config: {out / 'study_config.json'}  |  {machine['cpu']}, {machine['cores_available']} cores"
    labels = {m.name: m.label for m in methods}
    suite_names = [s for s in SUITES if any(s in runs for r in results.values() for runs in r.values())]
    figures: list[tuple[str, str]] = []

    # ---- figures
    histories = {
        f"seed {s}": adapters.loss_history(out / "train" / "clocked_lstm" / f"seed{s}") for s in cfg.train_seeds
    }
    if any(histories.values()):
        figures.append(("Train vs held-out loss of the clocked LSTM (paper Fig. 4)", "loss_clocked_lstm.png"))
        plots.loss_curves(histories, figs / figures[-1][1], prov)
    first_seed = str(cfg.train_seeds[0])
    heat_suites = [s for s in ("nominal", "nudge_0.03") if s in suite_names]
    for suite in heat_suites:
        panels = {}
        for m in methods:
            tag = "-" if not m.learned else first_seed
            if suite in results.get(m.name, {}).get(tag, {}):
                panels[m.label if tag == "-" else f"{m.label} s{tag}"] = results[m.name][tag][suite]
        name = f"heatmap_{suite}.png"
        figures.append((f"Success over the object box, suite `{suite}` (first training seed)", name))
        plots.success_heatmap(
            panels, base_env.object_low, base_env.object_high, figs / name, prov, title=f"suite {suite}"
        )
    for group in sorted({SUITES[s].group for s in suite_names if SUITES[s].group}):
        members = [s for s in suite_names if SUITES[s].group == group]
        curves = {}
        for m in methods:
            pts = [
                (SUITES[s].x * (100 if "cm" in SUITES[s].x_label else 1000), pooled(results[m.name], s))
                for s in members
            ]
            if "nominal" in suite_names:
                pts.append((0.0, pooled(results[m.name], "nominal")))
            curves[m.label] = [(x, p[0]) for x, p in pts if p]
        name = f"robustness_{group}.png"
        figures.append((f"Robustness: {group} sweep (x = 0 is the nominal suite)", name))
        plots.rate_curves(curves, figs / name, prov, SUITES[members[0]].x_label, f"success vs {group}")
    if cfg.data_efficiency:
        curves = {}
        for m in ("lookup_table", "clocked_lstm"):
            pts = []
            for n in cfg.data_efficiency:
                recs = results.get(m, {}).get(f"n{n}", {}).get("nominal")
                if recs:
                    pts.append((float(n), Rate(sum(r.success for r in recs), len(recs))))
            curves[labels.get(m, m)] = pts
        figures.append(("Data efficiency: nominal success vs training demonstrations", "data_efficiency.png"))
        plots.rate_curves(curves, figs / figures[-1][1], prov, "training demonstrations", "data efficiency", logx=True)
    fail_suite = next((s for s in ("nudge_0.03", "grasp_miss", "nominal") if s in suite_names), None)
    if fail_suite:
        failures = {}
        for m in methods:
            per: dict[str, dict[str, int]] = {}
            for tag, runs in results[m.name].items():
                for r in runs.get(fail_suite, []) if _main(tag) else []:
                    if not r.success:
                        phase = robot.PHASE_NAMES[r.furthest_phase] if r.furthest_phase >= 0 else "unknown"
                        per.setdefault(phase, {}).setdefault(r.failure_cause, 0)
                        per[phase][r.failure_cause] += 1
            failures[m.label] = per
        figures.append(
            (f"Failures by furthest phase and cause, suite `{fail_suite}` (all training seeds)", "failures.png")
        )
        plots.failures_by_phase(failures, figs / "failures.png", prov, f"failures, suite {fail_suite}")

    # ---- tables
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
    summary = {
        "command": command,
        "machine": machine,
        "config": asdict(cfg),
        "generation": generation,
        "success": table,
        "vs_lookup_table": comparisons,
        "timings_s": timings,
        "lerobot_eval_cli_check": cli_check,
        "figures": [f for _, f in figures],
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    (out / "report.md").write_text(_markdown(cfg, methods, results, suite_names, table, comparisons, figures, summary))
    return {
        "report": str(out / "report.md"),
        **{
            f"{labels[m]} / {s}": f"{100 * v['rate']:.1f}% [{100 * v['interval'][0]:.1f}, {100 * v['interval'][1]:.1f}]"
            for s, row in table.items()
            if s in ("nominal", "nudge_0.03")
            for m, v in row.items()
        },
    }


def _cell(v: dict | None) -> str:
    if not v:
        return "-"
    lo, hi = v["interval"]
    spread = ""
    if len(v["per_seed"]) > 1:
        spread = f"<br>seeds {min(v['per_seed']) * 100:.0f}-{max(v['per_seed']) * 100:.0f}%"
    return f"**{100 * v['rate']:.1f}%** [{100 * lo:.1f}, {100 * hi:.1f}] n={v['n']}{spread}"


def _markdown(cfg, methods, results, suite_names, table, comparisons, figures, summary) -> str:
    mach, t = summary["machine"], summary["timings_s"]
    total = sum(v for k, v in t.items())
    lines = [
        "# lerobot_pnp: reproduction report",
        "",
        f"Produced by `{summary['command']}` (preset `{cfg.preset}`; full config in `study_config.json`).",
        f"Machine: {mach['cpu']}, {mach['cores_available']} cores available; Python {mach['python']}, "
        f"LeRobot {mach['lerobot']}, torch {mach['torch']}, MuJoCo {mach['mujoco']}, gymnasium {mach['gymnasium']}.",
        f"Stage wall time (s): dataset {t.get('dataset', 0):.0f}"
        + (f" (+ dense recording {t['dataset_dense']:.0f})" if "dataset_dense" in t else "")
        + ", training "
        f"{sum(v for k, v in t.items() if k.startswith('train/')):.0f}, evaluation "
        f"{sum(v for k, v in t.items() if k.startswith('eval/')):.0f} (total {total:.0f}; an evaluation reused from an "
        "earlier run shows its original time, a reused dataset or training only the time to find it).",
        "",
        "Evaluation: stock LeRobot `lerobot.scripts.lerobot_eval.eval_policy` (the function `lerobot-eval` runs), "
        "called in process on the `SyncVectorEnv` of `BaxterPnPEnvConfig.create_envs`, with a recording wrapper "
        f"for the final `info` of each episode. Every method runs the same seeds ({cfg.eval_seed} onwards, unseen "
        f"by the dataset's seeds 0..). Learned methods: {len(cfg.train_seeds)} training seeds {cfg.train_seeds}, "
        f"{cfg.epochs} epochs each on {int(cfg.num_episodes * 0.8)} demonstrations"
        + (" (dense-control methods: their budget is under Methods)" if any(m.data == "dense" for m in methods) else "")
        + "; their rate pools the seeds.",
        *_cli_lines(summary.get("lerobot_eval_cli_check")),
        "Intervals: 95 % Wilson. Pooling seeds treats them as one sample; the per-seed range is shown beside it.",
        "",
        "## Methods",
        "",
        *_method_lines(methods, t),
        "",
        "## Success by suite",
        "",
        "| suite | what changes | " + " | ".join(m.label for m in methods) + " |",
        "|---|---|" + "---|" * len(methods),
    ]
    for s in suite_names:
        lines.append(
            f"| `{s}` | {SUITES[s].description} | "
            + " | ".join(_cell(table.get(s, {}).get(m.name)) for m in methods)
            + " |"
        )
    lines += [
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
            verdict = " (significant)" if c["max_p"] < 0.05 else ""
            lines.append(
                f"| {m} | `{s}` | {100 * c['difference']:+.1f} pts{verdict} | {c['max_p']:.2g} | "
                + "; ".join(c["per_seed"])
                + " |"
            )
    lines += [
        "",
        "## Failures by cause (all seeds pooled)",
        "",
        "| method | suite | failures by cause | by furthest phase |",
        "|---|---|---|---|",
    ]
    from lerobot_pnp.report.evaluation import summarize

    for m in methods:
        for s in suite_names:
            recs = [r for tag, runs in results.get(m.name, {}).items() if _main(tag) for r in runs.get(s, [])]
            if recs and any(not r.success for r in recs):
                sm = summarize(recs)
                lines.append(f"| {m.label} | `{s}` | {_fmt(sm['by_cause'])} | {_fmt(sm['by_phase'])} |")
    lines += ["", "## Figures", ""]
    for caption, name in figures:
        lines += [f"### {caption}", "", f"![{caption}](figures/{name})", ""]
    lines += ["## Claims", "", *_claims(table, comparisons), ""]
    lines += [
        "## Notes and limits",
        "",
        "- The inside strip and the outside ring are unions of four boxes (the env config samples a box); their "
        "corners are sampled about twice as densely as the rest of the band.",
        "- The expert is privileged (it reads the simulator) and runs its own loop on the same seeds.",
        "- Perturbations that need room to recover (missed grasp, drop, displacement) get a 20-keyframe budget for "
        "every method; the clocked LSTM stops acting after its 10-step clock (it holds its last action).",
        *_dense_notes(methods),
        "",
    ]
    return "\n".join(lines)


def _method_lines(methods, timings: dict) -> list[str]:
    """One line per method: what it is and, for a learned one, its training wall time per seed."""
    out = []
    for m in methods:
        times = [v for k, v in timings.items() if k.startswith(f"train/{m.name}/") and k.split("/")[-1].isdigit()]
        cost = f" Training wall time per seed: {', '.join(f'{v:.0f} s' for v in times)}." if times else ""
        only = f" Evaluated on {', '.join(m.suites)} only (cost)." if m.suites is not None else ""
        out.append(f"- **{m.label}** (`{m.name}`): {m.description}.{only}{cost}")
    return out


def _dense_notes(methods) -> list[str]:
    if not any(m.data == "dense" for m in methods):
        return []
    return [
        "- Dense-control methods (ACT) run each suite's task at 20 fps with 3 s of control per keyframe of the "
        "budget (600 steps nominal, 1200 with the recovery budget). A nudge fires at the dense step where the "
        "expert reaches its first keyframe (median over the training demonstrations), the keyframe suites' "
        "'after the first keyframe'. `latency` stays one env step: 50 ms in dense mode against one whole keyframe "
        "move in keyframe mode, so that row does not compare the two control modes.",
    ]


def _cli_lines(c: dict | None) -> list[str]:
    if not c:
        return []
    return [
        f"Cross-check with the real `lerobot-eval` CLI (subprocess, `{c['eval_info']}`): {c['method']} seed "
        f"{c['seed']} on the first {c['n']} nominal seeds: {c['cli_pc_success']:.1f}% success; the in-process "
        f"records agree on {c['agree']} of {c['n']} episodes.",
    ]


def _fmt(d: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(d.items(), key=lambda kv: -kv[1])) or "-"


def _claims(table, comparisons) -> list[str]:
    """What the numbers say about the paper's claims (generated from the measurements, never hard-coded)."""
    out = []
    nom = table.get("nominal", {}).get("clocked_lstm")
    if nom:
        lo = nom["interval"][0]
        out.append(
            f"- *The LSTM planner generalises to unseen object positions*: {100 * nom['rate']:.1f}% "
            f"(95 % interval from {100 * lo:.1f}%) -> {'holds' if lo >= 0.9 else 'does not hold (below 90 %)'}."
        )
    c = comparisons.get("clocked_lstm", {}).get("nominal")
    if c:
        out.append(
            f"- *A learned planner is needed for unseen positions*: against an open-loop lookup table of the same "
            f"demonstrations the nominal difference is {100 * c['difference']:+.1f} pts (max p {c['max_p']:.2g}) -> "
            + (
                "holds."
                if c["max_p"] < 0.05 and c["difference"] > 0
                else "not shown: the paper's task does not separate them."
            )
        )
    for s in ("nudge_0.03", "nudge_0.05", "obs_noise_0.005"):
        c = comparisons.get("clocked_lstm", {}).get(s)
        if c:
            holds = c["max_p"] < 0.05 and c["difference"] > 0
            out.append(
                f"- *Feedback at every step corrects a disturbed object* (suite `{s}`): clocked LSTM vs lookup table "
                f"{100 * c['difference']:+.1f} pts (max p {c['max_p']:.2g}) -> "
                + ("holds: the benchmark discriminates here." if holds else "not shown on this suite.")
            )
    for s in ("grasp_miss", "drop", "displace"):
        v = table.get(s, {}).get("clocked_lstm")
        if v:
            out.append(
                f"- *The planner corrects itself after a {s.replace('_', ' ')}*: {100 * v['rate']:.1f}% -> "
                + ("holds." if v["interval"][0] >= 0.5 else "does not hold: the clocked LSTM cannot retry a phase.")
            )
    worse = [
        (s, c)
        for s, c in comparisons.get("clocked_lstm", {}).items()
        if c["max_p"] < 0.05 and c["difference"] < 0 and all(str(x).startswith("-") for x in c["per_seed"])
    ]
    if worse:
        listed = "; ".join(f"`{s}` {100 * c['difference']:+.1f} pts (max p {c['max_p']:.2g})" for s, c in worse)
        out.append(
            "- *Feedback has a cost*: the open-loop lookup table beats the clocked LSTM, with every training seed, on "
            f"{listed}. The planner acts on what it observes, so a stale observation or a disturbance it never saw "
            "in training (the cube's yaw is not observed in the paper's task) derails it, while the replay ignores it."
        )
    mem, lstm = table.get("nominal", {}).get("memoryless"), table.get("nominal", {}).get("clocked_lstm")
    if mem and lstm:
        out.append(
            f"- *Memory matters (LSTM vs memoryless, nominal)*: {100 * lstm['rate']:.1f}% vs {100 * mem['rate']:.1f}% "
            "(the memoryless variant here is not capacity-matched: see methods.py)."
        )
    return out or ["- (no suite with the clocked LSTM was evaluated)"]
