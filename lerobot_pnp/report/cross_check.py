"""The study's cross-check: the first seeds of the nominal suite through the real `lerobot-eval` CLI,
compared episode by episode with the in-process evaluation (``cli_eval`` runs the CLI).

In a pool of several processes the CLI runs as a job of its own (``cli_job``) once the nominal evaluation it is
compared with is recorded, beside the other jobs instead of after them on one core; the study's last step then
finds it done and compares."""

from __future__ import annotations

import time
from dataclasses import replace

from lerobot_pnp.cache import STAGE_FILE, Stage, code_versions
from lerobot_pnp.outputs import remove_path as remove
from lerobot_pnp.report import adapters, coverage
from lerobot_pnp.report.config import StudyConfig
from lerobot_pnp.report.cost import max_rss_mb
from lerobot_pnp.report.job import JobResult, run_job, train_context
from lerobot_pnp.report.methods import get_methods, train_stage
from lerobot_pnp.report.schedule import CLI_CHECK, Job
from lerobot_pnp.report.stages import EVAL_BATCH_SIZE_BEFORE


def _stage(text: str) -> None:
    print(f"\n=== {text} ===", flush=True)


def cli_job(cfg: StudyConfig, methods, study: int, jobs: list[Job]) -> Job | None:
    """The pool job of a study's cross-check: the first learned method's first seed, after its nominal
    evaluation (``Job.after``); None when the study has no cross-check, nothing to train, or no such evaluation
    among ``jobs`` (the study's last step then runs the CLI itself, as it does with one process)."""
    learned = [m for m in methods if m.learned]
    if not cfg.cli_check_episodes or not learned or cfg.report_only:
        return None
    job = Job(learned[0].name, str(cfg.train_seeds[0]), None, CLI_CHECK, study)
    return job if job.after() in {j.key for j in jobs} else None


def run_cli_job(job: Job, cfg: StudyConfig, layout, roots, base_env, keys) -> JobResult:
    """The cross-check's CLI run (``cli_job``), compared with the nominal evaluation it waited for (read from its
    record); the study's last step finds it done and compares again."""
    nominal = run_job(replace(job, part="nominal"), cfg, layout, roots, base_env, keys)  # recorded: read, not run
    timings: dict[str, float] = {}
    cli_check(cfg, get_methods(cfg.methods), {job.method: {job.tag: nominal.records}}, (layout, roots, keys), timings)
    return JobResult({}, timings, [], {"cli_checks": [int("cli_check" in timings), 1]}, max_rss_mb())


def cli_check(cfg: StudyConfig, methods, results, where: tuple, timings: dict) -> dict | None:
    """The first seeds of the nominal suite through the `lerobot-eval` CLI, compared episode by episode
    (``where``: the output folder, the recordings' roots and keys); re-run when its checkpoint changed. Its wall
    time goes into ``timings`` when the CLI ran now."""
    from lerobot_pnp.report.cli_eval import EvalSpec, run_eval

    learned = [m for m in methods if m.learned]
    if not cfg.cli_check_episodes or not learned:
        return None
    if "nominal" not in results.get(learned[0].name, {}).get(tag := str(cfg.train_seeds[0]), {}):
        planned = cfg.report_only and "nominal" in [s.name for s in cfg.suites]
        return {"left_out": f"{learned[0].name} seed {tag} on `nominal` is left out"} if planned else None
    layout, roots, keys = where
    n = min(cfg.cli_check_episodes, len(results[learned[0].name][tag]["nominal"]))
    cli_dir = layout.cli_check
    ctx = train_context(Job(learned[0].name, tag, None), learned[0], cfg, layout, roots, keys)
    stage = Stage(cli_dir / STAGE_FILE, {"stage": "cli_check", "train": train_stage(learned[0], ctx).key, "n": n,
                                         "eval_seed": cfg.eval_seed, "eval_batch_size": cfg.eval_batch_size,
                                         "versions": code_versions()}, added=EVAL_BATCH_SIZE_BEFORE)  # fmt: skip
    ran = not stage.done("lerobot-eval cross-check")
    if ran:
        if cfg.report_only:  # the report says it was left out, and why
            return {"left_out": coverage.left_out(learned[0].name, tag, "nominal", stage, None).why()}
        remove(cli_dir)
        _stage(f"3b cross-check: {n} nominal episodes of {learned[0].name} seed {tag} through the lerobot-eval CLI")
    t = time.perf_counter()
    cli = run_eval(
        adapters.checkpoint_of(layout.train(learned[0].name, tag)),
        cli_dir,
        EvalSpec("nominal", n),
        cfg.eval_seed,
        cfg.eval_batch_size,
    )
    stage.commit()
    if ran:
        timings["cli_check"] = time.perf_counter() - t
    ours = {r.seed: r.success for r in results[learned[0].name][tag]["nominal"] if r.seed < cfg.eval_seed + n}
    theirs = cli["per_episode"]
    agree = sum(ours.get(s) == v for s, v in theirs.items())
    return {
        "method": learned[0].name,
        "seed": tag,
        "n": len(theirs),
        "agree": agree,
        "cli_pc_success": cli["pc_success"],
        "in_process_successes": sum(ours.values()),
        "eval_info": cli["eval_info"],
    }
