"""The study's cross-check: the first seeds of the nominal suite through the real `lerobot-eval` CLI,
compared episode by episode with the in-process evaluation (``cli_eval`` runs the CLI)."""

from __future__ import annotations

import time

from lerobot_pnp.cache import STAGE_FILE, Stage, code_versions
from lerobot_pnp.outputs import remove_path as remove
from lerobot_pnp.report import adapters, coverage
from lerobot_pnp.report.config import StudyConfig
from lerobot_pnp.report.job import train_context
from lerobot_pnp.report.methods import train_stage
from lerobot_pnp.report.schedule import Job
from lerobot_pnp.report.stages import EVAL_BATCH_SIZE_BEFORE


def _stage(text: str) -> None:
    print(f"\n=== {text} ===", flush=True)


def cli_check(cfg: StudyConfig, methods, results, where: tuple, timings: dict) -> dict | None:
    """The first seeds of the nominal suite through the `lerobot-eval` CLI, compared episode by episode
    (``where``: the output folder, the recordings' roots and keys); re-run when its checkpoint changed."""
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
    if not stage.done("lerobot-eval cross-check"):
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
