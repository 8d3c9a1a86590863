"""The DAgger rounds: demonstrations -> train -> (roll out, label, aggregate, retrain) x N, evaluated each round.

Retraining is **from scratch** on the aggregate each round: the normalisation statistics change with the
data (DAgger adds the policy's off-distribution states), a fresh policy is a function of its dataset and seed
only (deterministic, reproducible on its own), and the recovering planner trains in about a minute, so a warm
start would save little.

Layout of ``output_dir``::

    demos/                 round-0 expert demonstrations (LeRobotDataset), unless --base_root is given
    round_01/rollouts/     the round-1 policy rollouts labelled by the expert (LeRobotDataset)
    round_01/data/         demos + rollouts of rounds 1..r, merged with aggregate_datasets
    round_XX/train/        fast-path training run (checkpoints/last/pretrained_model)
    round_XX/eval.json     success per suite on the evaluation seeds
    table.md / table.json  success per round and suite with Wilson 95 % intervals
"""

from __future__ import annotations

import copy
import json
import logging
import time
from pathlib import Path

from lerobot_pnp.rollout import load_policy

from .config import DaggerConfig
from .rollouts import evaluate, expert_episode, labelled_rollout, suite_env
from .stats import rate_cell, wilson
from .writer import aggregate, write_episodes

logger = logging.getLogger(__name__)
ROUND_SEED_STRIDE = 1_000_000


def _tqdm(total: int, desc: str, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, disable=not enabled, leave=False)


def _base_env_cfg(cfg: DaggerConfig):
    from lerobot_pnp.env_config import BaxterPnPEnvConfig

    if cfg.base_root:
        return BaxterPnPEnvConfig(task_source=cfg.base_root, **cfg.env_changes)
    return BaxterPnPEnvConfig(preset=cfg.preset, **cfg.env_changes)


def _demos(cfg: DaggerConfig, out: Path, env_cfg) -> tuple[Path, str, str]:
    """(root, repo_id, test range) of the round-0 data, written once."""
    if cfg.base_root:
        from lerobot.datasets.io_utils import load_info

        info = load_info(Path(cfg.base_root))
        n = int(info.total_episodes)
        test = (info.splits or {}).get("test") or f"{n - max(1, round(cfg.test_fraction * n))}:{n}"
        return Path(cfg.base_root), cfg.base_repo_id, test
    root, repo_id = out / "demos", f"{cfg.base_repo_id}_demos"
    n = cfg.num_demos
    test = f"{n - max(1, round(cfg.test_fraction * n))}:{n}"
    if not root.is_dir():
        env = suite_env(env_cfg, "full")
        episodes, seed = [], cfg.seed
        with _tqdm(n, "expert demos", cfg.progress) as bar:
            while len(episodes) < n:
                ep = expert_episode(env, seed, "full")
                seed += 1
                if ep is not None:
                    episodes.append(ep)
                    bar.update(1)
        env.close()
        write_episodes(root, repo_id, env_cfg, episodes, {"test": test})
    return root, repo_id, test


def _rollouts(cfg: DaggerConfig, rnd: int, ckpt: Path, out: Path, env_cfg) -> tuple[Path, str, dict]:
    root, repo_id = out / f"round_{rnd:02d}" / "rollouts", f"{cfg.base_repo_id}_dagger{rnd:02d}"
    summary_file = root.parent / "rollouts.json"
    if root.is_dir() and summary_file.is_file():
        return root, repo_id, json.loads(summary_file.read_text())
    policy = load_policy(ckpt)
    envs = {s: suite_env(env_cfg, s) for s in cfg.rollout_suites}
    episodes = []
    with _tqdm(cfg.rollouts_per_round, f"round {rnd} rollouts", cfg.progress) as bar:
        for i in range(cfg.rollouts_per_round):
            suite = cfg.rollout_suites[i % len(cfg.rollout_suites)]
            seed = cfg.seed + ROUND_SEED_STRIDE * rnd + i
            episodes.append(labelled_rollout(envs[suite], policy, seed, suite))
            bar.update(1)
    for env in envs.values():
        env.close()
    write_episodes(root, repo_id, env_cfg, episodes)
    summary = {
        "episodes": len(episodes),
        "frames": int(sum(len(e.actions) for e in episodes)),
        "policy_successes": int(sum(e.success for e in episodes)),
    }
    summary_file.write_text(json.dumps(summary, indent=2))
    return root, repo_id, summary


def _train(cfg: DaggerConfig, root: Path, repo_id: str, test: str, out_dir: Path) -> Path:
    from lerobot_pnp.train_fast import TrainFastConfig, train_fast

    done = out_dir / "done.json"
    if done.is_file():
        return Path(json.loads(done.read_text())["checkpoint"])
    policy_cfg = copy.deepcopy(cfg.policy)
    result = train_fast(
        TrainFastConfig(
            dataset_repo_id=repo_id,
            dataset_root=str(root),
            policy=policy_cfg,
            epochs=cfg.epochs,
            batch_size=cfg.batch_size,
            seed=cfg.seed,
            output_dir=str(out_dir),
            overwrite=True,
            test_episodes=test,
            progress=cfg.progress,
        )
    )
    done.write_text(json.dumps({**result.summary(), "checkpoint": str(result.checkpoint_dir)}, indent=2))
    return result.checkpoint_dir


def evaluate_checkpoint(cfg: DaggerConfig, ckpt: Path, env_cfg, out_file: Path) -> dict:
    """Success per eval suite on seeds ``eval_seed + i`` (the same for every round); cached in ``out_file``."""
    if out_file.is_file():
        return json.loads(out_file.read_text())
    policy = load_policy(ckpt)
    seeds = [cfg.eval_seed + i for i in range(cfg.eval_episodes)]
    results = {}
    with _tqdm(len(seeds) * len(cfg.eval_suites), f"eval {out_file.parent.name}", cfg.progress) as bar:
        for suite in cfg.eval_suites:
            results[suite] = evaluate(policy, env_cfg, suite, seeds, bar)
    out_file.write_text(json.dumps(results, indent=2))
    return results


def write_table(rows: list[tuple[str, dict]], suites: list[str], out: Path) -> str:
    """Markdown table: one row per policy, success and Wilson 95 % interval per suite."""
    lines = ["| policy | " + " | ".join(suites) + " |", "|---" * (len(suites) + 1) + "|"]
    data = []
    for name, res in rows:
        cells = [rate_cell(res[s]["successes"], res[s]["n"]) if s in res else "-" for s in suites]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
        data.append(
            {
                "policy": name,
                **{
                    s: {
                        **res[s],
                        "rate": res[s]["successes"] / max(res[s]["n"], 1),
                        "wilson95": wilson(res[s]["successes"], res[s]["n"]),
                    }
                    for s in suites
                    if s in res
                },
            }
        )
    table = "\n".join(lines) + "\n"
    (out / "table.md").write_text(table)
    (out / "table.json").write_text(json.dumps(data, indent=2))
    return table


def run_dagger(cfg: DaggerConfig) -> dict:
    """``lerobot-pnp dagger``: see ``DaggerConfig`` and the module docstring. Returns the summary table."""
    import torch

    torch.set_num_threads(1)
    out = Path(cfg.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    env_cfg = _base_env_cfg(cfg)
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    demo_root, demo_repo, test = _demos(cfg, out, env_cfg)
    timings["demos_s"] = time.perf_counter() - t0

    rows, roots, repos = [], [demo_root], [demo_repo]
    data_root, data_repo = demo_root, demo_repo
    ckpt = None
    rollout_summaries = {}
    for rnd in range(cfg.rounds + 1):
        rdir = out / f"round_{rnd:02d}"
        rdir.mkdir(exist_ok=True)
        t = time.perf_counter()
        if rnd > 0:
            root, repo, summary = _rollouts(cfg, rnd, ckpt, out, env_cfg)
            rollout_summaries[rnd] = summary
            roots.append(root)
            repos.append(repo)
            data_root, data_repo = rdir / "data", f"{cfg.base_repo_id}_aggregate{rnd:02d}"
            if not (data_root / "meta" / "info.json").is_file():
                aggregate(roots, repos, data_root, data_repo, env_cfg, {"test": test})
        timings[f"round{rnd}_data_s"] = time.perf_counter() - t
        t = time.perf_counter()
        if rnd == 0 and cfg.round0_checkpoint:
            ckpt = Path(cfg.round0_checkpoint)
        else:
            ckpt = _train(cfg, data_root, data_repo, test, rdir / "train")
        timings[f"round{rnd}_train_s"] = time.perf_counter() - t
        if cfg.eval_episodes > 0:
            rows.append((f"round {rnd}", evaluate_checkpoint(cfg, ckpt, env_cfg, rdir / "eval.json")))
            write_table(rows, cfg.eval_suites, out)
    table = write_table(rows, cfg.eval_suites, out) if rows else ""
    summary = {"output_dir": str(out), "final_checkpoint": str(ckpt), "rollouts": rollout_summaries,
               "timings_s": {k: round(v, 1) for k, v in timings.items()}, "table": table}  # fmt: skip
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary
