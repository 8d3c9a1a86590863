"""One stock multi-suite ``lerobot-eval`` against the study's in-process evaluations of the same suites.

Side by side, on the same checkpoint, suites, seeds and batch:

- ``stock``: ``lerobot-eval --env.task=<suites>`` as a user runs it: one process, its start-up, the policy loaded
  once, LeRobot's videos (up to 10 episodes per suite);
- ``stock_no_videos`` (``--without_videos``): the same ``eval_policy_all`` over the env config's ``create_envs`` in this process with no
  video (what the videos cost);
- ``study``: the study's evaluator per suite (``load_policy`` with the suite's env config, then
  ``eval_lerobot_policy``: ``report.methods._checkpoint_eval``), its evaluation times summed.

It checks that ``stock`` and ``study`` give the same outcome episode by episode on every suite and writes the times,
their ratios and each suite's success to ``--out``. Target: stock / study <= 1.2, and stock <= 6 min for the 18
held-out suites x 100 keyframe episodes on 2 cores.

    OMP_NUM_THREADS=1 MUJOCO_GL=egl python benchmarks/bench_stock_suites.py [--checkpoint PATH] \\
        [--task heldout] [--n_episodes 100] [--batch 50] [--repeats 2] [--without_videos] [--keep DIR] [--out FILE]

Without ``--checkpoint`` it builds an untrained tiny pnp_lstm recording the ``full`` task (the held-out protocol's
training task): it fails every episode, so every episode runs to its suite's budget, the most steps a suite costs.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SEED = 100_000  # the study's first evaluation seed


def tiny_checkpoint(path: Path) -> Path:
    """An untrained pnp_lstm (hidden size 8) recording the ``full`` task, in LeRobot's pretrained_model layout."""
    import torch
    from lerobot.configs import FeatureType, PolicyFeature

    from lerobot_pnp.integration.recorded_task import write_checkpoint_task
    from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy, make_pnp_lstm_pre_post_processors
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    task = BaxterPnPEnvConfig(preset="full")
    width = len(task.environment_state_names)
    cfg = PnpLstmConfig(
        hidden_size=8,
        input_features={
            "observation.state": PolicyFeature(FeatureType.STATE, (8,)),
            "observation.environment_state": PolicyFeature(FeatureType.ENV, (width,)),
        },
        output_features={"action": PolicyFeature(FeatureType.ACTION, (8,))},
    )

    def unit(n: int) -> dict:
        return {"mean": torch.zeros(n), "std": torch.ones(n), "min": -torch.ones(n), "max": torch.ones(n)}

    torch.manual_seed(0)
    PnpLstmPolicy(cfg).save_pretrained(path)
    stats = {"observation.state": unit(8), "observation.environment_state": unit(width), "action": unit(8)}
    for proc in make_pnp_lstm_pre_post_processors(cfg, stats):
        proc.save_pretrained(path)
    write_checkpoint_task({"type": "baxter_pnp", **task.to_dict()}, path)
    return path


def run_stock(ckpt: Path, task: str, n: int, batch: int, out: Path) -> tuple[float, dict[str, list[bool]]]:
    """The lerobot-eval command, timed from launch to exit; its per-suite successes."""
    cmd = [str(Path(sys.executable).with_name("lerobot-eval")), f"--policy.path={ckpt}", "--env.type=baxter_pnp",
           f"--env.task={task}", f"--eval.n_episodes={n}", f"--eval.batch_size={batch}", f"--seed={SEED}",
           "--policy.device=cpu", f"--output_dir={out}"]  # fmt: skip
    print(" ".join(cmd), flush=True)
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
    wall = time.perf_counter() - t
    if proc.returncode != 0:
        sys.exit(f"lerobot-eval failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    info = json.loads((out / "eval_info.json").read_text())
    return wall, {t["task_group"]: t["metrics"]["successes"] for t in info["per_task"]}


def run_stock_no_videos(ckpt: Path, task: str, n: int, batch: int) -> float:
    """``eval_policy_all`` over ``create_envs`` in this process, no videos: the evaluation alone."""
    import torch
    from lerobot.envs.factory import make_env_pre_post_processors
    from lerobot.scripts.lerobot_eval import eval_policy_all

    from lerobot_pnp.evaluation.checkpoints import load_policy
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    cfg = BaxterPnPEnvConfig.from_source(str(ckpt), task=task)
    t = time.perf_counter()
    loaded = load_policy(ckpt, env_cfg=cfg)
    envs = cfg.create_envs(n_envs=batch)
    env_pre, env_post = make_env_pre_post_processors(cfg, loaded.policy.config)
    with torch.no_grad():
        eval_policy_all(
            envs, loaded.policy, env_pre, env_post, loaded.preprocessor, loaded.postprocessor, n, start_seed=SEED
        )
    return time.perf_counter() - t


def run_study(ckpt: Path, task: str, n: int, batch: int) -> tuple[dict[str, float], dict[str, list[bool]]]:
    """The study's evaluator on each suite (``_checkpoint_eval``): its wall time and outcomes per suite."""
    from lerobot_pnp.evaluation.checkpoints import load_policy
    from lerobot_pnp.evaluation.closed_loop import eval_lerobot_policy
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.sim.stock_suites import suite_configs

    times, outcomes = {}, {}
    for suite, env_cfg in suite_configs(BaxterPnPEnvConfig.from_source(str(ckpt), task=task)).items():
        t = time.perf_counter()
        lp = load_policy(ckpt, env_cfg=env_cfg)
        records = eval_lerobot_policy(lp.policy, lp.preprocessor, lp.postprocessor, env_cfg, n, SEED, batch)
        times[suite] = time.perf_counter() - t
        outcomes[suite] = [r.success for r in records]
        print(f"  study {suite:<24} {times[suite]:6.1f} s  {sum(outcomes[suite])}/{n}", flush=True)
    return times, outcomes


def measure(args, ckpt: Path, tmp: Path) -> dict:
    """Rounds of (stock, study), alternated so that drift on a shared machine hits both; the fastest of each."""
    batch = min(args.batch, args.n_episodes)
    stock_s, study_s, differ = [], [], set()
    for r in range(args.repeats):
        out = args.keep if (args.keep and r == 0) else tmp / f"eval{r}"
        wall, stock = run_stock(ckpt, args.task, args.n_episodes, batch, out)
        stock_s.append(wall)
        print(f"stock lerobot-eval: {wall:.1f} s", flush=True)
        times, study = run_study(ckpt, args.task, args.n_episodes, batch)
        study_s.append(times)
        differ |= {s for s in study if stock.get(s) != study[s]}
    quiet_s = run_stock_no_videos(ckpt, args.task, args.n_episodes, batch) if args.without_videos else None
    best = min(study_s, key=lambda t: sum(t.values()))
    return {
        "task": args.task, "suites": len(best), "episodes_per_suite": args.n_episodes, "batch": batch,
        "checkpoint": str(args.checkpoint or "untrained tiny pnp_lstm, full task"), "cpus": os.cpu_count(),
        "load_average_after": os.getloadavg(), "stock_s": stock_s, "study_sum_s": [sum(t.values()) for t in study_s],
        "ratio": min(stock_s) / sum(best.values()), "stock_no_videos_s": quiet_s, "study_s": best,
        "success": {s: sum(v) / len(v) for s, v in study.items()}, "outcomes_differ": sorted(differ),
    }  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--checkpoint", type=Path, default=None, help="default: an untrained tiny pnp_lstm (full task)")
    ap.add_argument("--task", default="heldout", help="--env.task: suites, axes or aliases")
    ap.add_argument("--n_episodes", type=int, default=100)
    ap.add_argument("--batch", type=int, default=50)
    ap.add_argument("--repeats", type=int, default=1, help="rounds of (stock, study); the fastest of each is compared")
    ap.add_argument("--without_videos", action="store_true", help="also time eval_policy_all with no video")
    ap.add_argument("--keep", type=Path, default=None, help="keep the first stock run's output folder here")
    ap.add_argument("--out", type=Path, default=Path("bench_stock_suites.json"))
    args = ap.parse_args()
    from lerobot_pnp.integration.registration import register_all

    register_all()
    import torch

    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory(prefix="bench_stock_suites_") as tmp:
        ckpt = args.checkpoint or tiny_checkpoint(Path(tmp) / "pretrained_model")
        result = measure(args, ckpt, Path(tmp))
    args.out.write_text(json.dumps(result, indent=2))
    print(f"stock {min(result['stock_s']):.1f} s, study (sum of suites) {min(result['study_sum_s']):.1f} s: ratio "
          f"{result['ratio']:.2f}; outcomes differ on {result['outcomes_differ'] or 'no suite'}")  # fmt: skip
    if result["outcomes_differ"]:
        sys.exit(1)


if __name__ == "__main__":
    main()
