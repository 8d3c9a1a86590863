"""What the episode rule (``report.config.EpisodeRule``) saves on a study's finished evaluations.

    .venv/bin/python benchmarks/episode_rule.py [--output_dir outputs/heldout] [--preset heldout]
        [--dataset_s 174] [--dense_s 630] [--json docs/results/episode_rule.json]

For every evaluation record of the study folder (``evals/<method>/seed<tag>/<suite>.json``, fixed-n records):
the episodes the preset's rule would stop at (``EpisodeRule.stop_at``, as the study's truncation reuses them)
and the share of the record's wall time those episodes took, estimated three ways: by episodes (n_rule / n), by
simulated steps (``stages.share_of_time``, the estimate the study reports: a batch's physics costs the sum of its
episodes' lengths) and by each batch's longest episode (the batched policy runs until the last episode of the
batch ends). A planned evaluation without a record yet (the study still running) is extrapolated from the same
method's records (mean wall time and mean share), and counted as such. The study's time is then estimated with
and without the rule: single-core seconds (every stage summed: the two dataset recordings, given on the command
line because a reused dataset records no time, the trainings' ``study_train_time.json`` and the evaluations),
and the wall clock of the study's job pool on 2 cores (jobs in the study's order, each to the first free
process, as ``schedule.run_jobs`` does; the dense recording counted at half its single-worker time).

``--verify METHOD/TAG/SUITE`` checks the premise of reusing a fixed-n record by truncation on a real trained
policy: the stage evaluated again with the current code, once as the fixed run (one call of n episodes) and once
block by block (one call per eval batch, as an adaptive evaluation that never stops), episode by episode, and both
against the stored record.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(HERE))

from lerobot_pnp.integration.recorded_task import read_recorded  # noqa: E402
from lerobot_pnp.report import coverage  # noqa: E402
from lerobot_pnp.report.config import StudyConfig  # noqa: E402
from lerobot_pnp.report.job import suites_for  # noqa: E402
from lerobot_pnp.report.layout import StudyLayout  # noqa: E402
from lerobot_pnp.report.methods import get_methods  # noqa: E402
from lerobot_pnp.report.stages import share_of_time  # noqa: E402
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig  # noqa: E402


def stage_row(record: Path, rule, batch: int, fixed: bool) -> dict:
    """One finished evaluation: its n, where the rule stops, and the three estimates of the kept time share."""
    data = json.loads(record.read_text())
    episodes = sorted(data["episodes"], key=lambda e: e["seed"])
    n = len(episodes)
    keep = n if fixed else rule.stop_at([e["success"] for e in episodes], data["parts"]["n_episodes"], batch)
    batches = [episodes[i : i + batch] for i in range(0, n, batch)]
    longest = [max(e["steps"] for e in b) for b in batches]
    kept_batches = -(-keep // batch)
    return {
        "n": n,
        "successes": sum(e["success"] for e in episodes),
        "n_rule": keep,
        "wall_s": data["wall_s"],
        "share_episodes": keep / n,
        "share_steps": share_of_time(episodes, keep),
        "share_batch_longest": sum(longest[:kept_batches]) / sum(longest),
    }


def verify(cfg: StudyConfig, layout: StudyLayout, what: str) -> dict:
    """The fixed run and the block-by-block run of one finished stage, compared episode by episode."""
    from dataclasses import asdict

    from lerobot_pnp.report.config import EpisodeRule
    from lerobot_pnp.report.job import evaluate, train_context
    from lerobot_pnp.report.methods import keyed_train, train_stage
    from lerobot_pnp.report.schedule import Job
    from lerobot_pnp.sim.suites import get_suites

    name, tag, suite_name = what.split("/")
    (method,) = get_methods([name])
    roots = {r: layout.dataset(r) for r in dict.fromkeys(["keyframe", method.data])}
    keys = {r: json.loads((root / "stage.json").read_text())["key"] for r, root in roots.items()}
    ctx = train_context(Job(name, tag, None), method, cfg, layout, roots, keys)
    if method.learned and not train_stage(method, ctx).done():
        raise SystemExit(f"--verify {what}: its training is not finished in {layout.out}")
    artifact, _ = keyed_train(method, ctx)  # the finished training's artefact (nothing is trained)
    (suite,) = get_suites([suite_name])
    base = BaxterPnPEnvConfig.from_dict(read_recorded(roots["keyframe"]) or {})
    stored = json.loads(layout.eval_record(name, tag, suite_name).read_text())
    n = stored["parts"]["n_episodes"]
    every_block = EpisodeRule(half_width=1e-9, block=cfg.eval_batch_size, fixed_methods=())  # never decided
    runs = {
        k: evaluate(method, artifact, ctx, suite, n, base, cfg, r)
        for k, r in (("fixed", None), ("blocks", every_block))
    }
    episodes = {k: d["episodes"] for k, d in runs.items()}
    episodes["stored"] = sorted(stored["episodes"], key=lambda e: e["seed"])
    return {
        "stage": what,
        "n": n,
        "batch": cfg.eval_batch_size,
        "successes": {k: sum(e["success"] for e in v) for k, v in episodes.items()},
        "blocks_equal_fixed": episodes["blocks"] == episodes["fixed"],
        "fixed_equal_stored": episodes["fixed"] == episodes["stored"],
        "wall_s": {k: d["wall_s"] for k, d in runs.items()},
        "rule": asdict(every_block),
    }


def _jobs(cfg: StudyConfig) -> list[tuple[str, str]]:
    return [(m.name, str(s)) for m in get_methods(cfg.methods) for s in (cfg.train_seeds if m.learned else ["-"])]


def collect(cfg: StudyConfig, layout: StudyLayout) -> tuple[dict, dict]:
    """(method, tag) -> suite -> row (measured, or extrapolated: ``extrapolated`` True); (method, tag) -> train s."""
    base = BaxterPnPEnvConfig.from_dict(read_recorded(layout.dataset()) or {})
    pairs = suites_for(cfg, None)
    planned = [s.name for s, _ in pairs if coverage.suite_aliases(pairs, base)[s.name] == s.name]
    rule, rows, train = cfg.episodes_rule, {}, {}
    for method, tag in _jobs(cfg):
        fixed = rule is None or method in rule.fixed_methods
        job = rows.setdefault((method, tag), {})
        for suite in planned:
            record = layout.eval_record(method, tag, suite)
            if record.is_file():
                job[suite] = {**stage_row(record, rule, cfg.eval_batch_size, fixed), "extrapolated": False}
        timing = layout.train(method, tag) / "study_train_time.json"
        train[(method, tag)] = json.loads(timing.read_text())["wall_s"] if timing.is_file() else 0.0
    for (method, _tag), job in rows.items():  # planned but not yet run: the method's mean
        measured = [r for (m, _), j in rows.items() if m == method for r in j.values() if not r["extrapolated"]]
        for suite in planned:
            if suite not in job and measured:
                mean = {k: sum(r[k] for r in measured) / len(measured) for k in ("wall_s", "share_steps")}
                job[suite] = {**mean, "extrapolated": True}
    return rows, train


def pool_wall(durations: list[float], processes: int = 2) -> float:
    """The wall clock of jobs run in order, each started on the first process to come free."""
    free = [0.0] * processes
    for d in durations:
        free[free.index(min(free))] += d
    return max(free)


def estimate(rows: dict, train: dict, dataset_s: float, dense_s: float) -> dict:
    """Single-core seconds and the 2-core wall clock, without and with the rule (steps share)."""
    out = {}
    for name, share in (("fixed_n", lambda r: 1.0), ("with_rule", lambda r: r["share_steps"])):
        jobs = [train[j] + sum(r["wall_s"] * share(r) for r in suites.values()) for j, suites in rows.items()]
        out[name] = {
            "single_core_s": dataset_s + dense_s + sum(jobs),
            "wall_2_cores_s": dataset_s + dense_s / 2 + pool_wall(jobs),
        }
    return out


def per_method(rows: dict) -> dict:
    """Per method: the measured stages (episodes and eval seconds, fixed and under the rule by each estimate) and
    the extrapolated ones (eval seconds fixed and under the rule, by steps)."""
    out: dict[str, dict] = {}
    for (method, _), suites in rows.items():
        m = out.setdefault(method, dict.fromkeys(("measured", "n", "n_rule", "eval_s", "rule_steps_s",
                                                  "rule_episodes_s", "rule_batch_s", "extrapolated",
                                                  "extrapolated_s", "extrapolated_rule_s"), 0))  # fmt: skip
        for r in suites.values():
            if r["extrapolated"]:
                m["extrapolated"] += 1
                m["extrapolated_s"] += r["wall_s"]
                m["extrapolated_rule_s"] += r["wall_s"] * r["share_steps"]
                continue
            m["measured"] += 1
            m["n"] += r["n"]
            m["n_rule"] += r["n_rule"]
            m["eval_s"] += r["wall_s"]
            for share in ("steps", "episodes", "batch"):
                m[f"rule_{share}_s"] += r["wall_s"] * r["share_batch_longest" if share == "batch" else f"share_{share}"]
    return out


def _print(cfg, args, methods: dict, train: dict, times: dict) -> None:
    print(f"# benchmarks/episode_rule.py --output_dir {args.output_dir} --preset {args.preset}")
    print(f"# {cfg.episodes_rule}; eval batch {cfg.eval_batch_size}")
    print("# measured stages: episodes fixed -> under the rule; eval s fixed -> under the rule, estimated by steps "
          "(by episodes, by each batch's longest episode) | stages not run yet, extrapolated: eval s fixed -> rule")  # fmt: skip
    for name, m in methods.items():
        print(f"{name:<15} {m['measured']:>3} stages {m['n']:>6} -> {m['n_rule']:>5} episodes, {m['eval_s']:>6.0f} -> "
              f"{m['rule_steps_s']:>5.0f} s ({m['rule_episodes_s']:.0f}, {m['rule_batch_s']:.0f}) | "
              f"{m['extrapolated']:>2} stages {m['extrapolated_s']:>6.0f} -> {m['extrapolated_rule_s']:.0f} s")  # fmt: skip
    print(f"training s (all seeds): {sum(train.values()):.0f}; datasets s: {args.dataset_s:.0f} + {args.dense_s:.0f}")
    for name, t in times.items():
        print(f"study {name:<9}: {t['single_core_s'] / 3600:.2f} single-core h, "
              f"{t['wall_2_cores_s'] / 3600:.2f} h wall on 2 cores")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--output_dir", default="outputs/heldout")
    ap.add_argument("--preset", default="heldout")
    ap.add_argument("--dataset_s", type=float, default=174.0, help="keyframe dataset, wall s (heldout_study_batch64)")
    ap.add_argument("--dense_s", type=float, default=630.0, help="dense recording, 1 worker (heldout_study_act)")
    ap.add_argument("--json", default=None, help="write the per-stage rows and the estimates here")
    ap.add_argument("--verify", default=None, help="METHOD/TAG/SUITE: fixed vs block-by-block run of that stage")
    args = ap.parse_args()
    cfg = StudyConfig(preset=args.preset, output_dir=args.output_dir)
    if args.verify:
        print(json.dumps(verify(cfg, StudyLayout(Path(args.output_dir)), args.verify)))
        return
    rows, train = collect(cfg, StudyLayout(Path(args.output_dir)))
    times, methods = estimate(rows, train, args.dataset_s, args.dense_s), per_method(rows)
    rule = cfg.episodes_rule
    _print(cfg, args, methods, train, times)
    if args.json:
        flat = [{"method": m, "tag": t, "suite": s, **r} for (m, t), suites in rows.items() for s, r in suites.items()]
        Path(args.json).write_text(json.dumps({"rule": rule.key() | {"fixed_methods": list(rule.fixed_methods)},
                                               "per_method": methods, "study": times, "stages": flat}, indent=1))  # fmt: skip


if __name__ == "__main__":
    main()
