"""The opening of ``report.md``: how the study was produced (command, machine, stage wall times, this
invocation), how it evaluates (stock ``eval_policy``, the seeds, the episode counts' rules, the ``lerobot-eval``
cross-check) and its Methods section (the study's changes to the recovering recipe, one line per method).

It states the config and the timings as they are; the results sections are ``markdown``'s.
"""

from __future__ import annotations

import json
import math

from lerobot_pnp.dataset.splits import train_count
from lerobot_pnp.report import coverage
from lerobot_pnp.report.methods import METHODS


def _invocation(cfg, t: dict) -> str:
    """What this invocation itself did: report only, or its wall clock and job processes."""
    if cfg.report_only:
        return f"This invocation: the report only ({t.get('run/wall_clock', 0):.0f} s; nothing trained or evaluated)."
    return (
        f"This invocation: {t.get('run/wall_clock', 0) / 60:.0f} min wall clock with {t.get('run/processes', 1):.0f} "
        "job process(es) (training and evaluation jobs run side by side, one core each)."
    )


def _code_sentence(mach: dict) -> str:
    """The commit the study ran (and whether its code had uncommitted changes) and the date, where recorded."""
    if not mach.get("commit"):
        return ""
    dirty = " with uncommitted changes to the study's code" if mach.get("uncommitted_changes") else ""
    return f" Code: commit `{mach['commit'][:12]}`{dirty}, run on {mach.get('date', '?')}."


def header(layout, cfg, methods, summary, left=()) -> list[str]:
    """What produced the report and how it evaluates, then the Methods section (``left``: the evaluations
    ``--report_only`` left out, named in the method lines)."""
    mach, t = summary["machine"], summary["timings_s"]
    total = sum(v for k, v in t.items() if not k.startswith("run/"))
    return [
        f"Produced by `{summary['command']}` (preset `{cfg.preset}`; full config in `{layout.config.name}`). "
        f"Task: `{cfg.task_preset}` (the demonstrations' task, recorded with them; every suite changes it).",
        f"Machine: {mach['cpu']}, {mach['cores_available']} cores available; Python {mach['python']}, "
        f"LeRobot {mach['lerobot']}, torch {mach['torch']}, MuJoCo {mach['mujoco']}, gymnasium {mach['gymnasium']}."
        + _code_sentence(mach),
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
        "Intervals: 95 %. A rate pooled over training seeds has an interval that counts the seeds as well as the "
        "episodes (the pooled rate +- t s / sqrt(k) over the k seeds' rates, joined with the Wilson interval of the "
        "episodes), so that a rerun, which trains the seeds anew, is expected inside it; the per-seed range is shown "
        "beside it. One seed, or nothing trained: Wilson's." + _episodes_rule_sentence(cfg),
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
