"""Measure the scripted expert: success rate over seeded episodes and failures grouped by cause.

On the default task it runs ``n_episodes`` seeds of ``cfg.env``. With ``--env.task`` naming evaluation suites (the
names stock ``lerobot-eval`` takes: ``heldout``, an axis, suites; ``evaluation.stock_suites``) it runs every suite
as ``lerobot-eval`` does: each suite's env config is ``Suite.env_configs`` of the resolved task, and episode ``i``
of every suite is seed ``seed + i``. Each suite runs through the study's own expert evaluator
(``closed_loop.eval_expert``), so a suite's outcomes are the study's. With ``output_dir`` it writes an
``eval_info.json`` in ``lerobot-eval``'s layout (``per_task`` with per-episode successes, plus their seeds and
failure causes; ``per_group``; ``overall``), which ``lerobot-pnp compare`` and the leaderboard read like any
``lerobot-eval`` output (written through ``lerobot_pnp.outputs``: atomically, and only over a file this command
wrote). The expert is privileged (it reads the simulator), so it is no policy of observations and
no checkpoint: this command is its evaluator.
"""

from __future__ import annotations

import collections
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from lerobot_pnp.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.errors import ConfigError, ExpertFailure, UnreachableError
from lerobot_pnp.expert import failure_cause, run_expert_episode
from lerobot_pnp.outputs import OutputFolder, read_record

COMMAND = "lerobot-pnp expert"  # its name in an output folder's manifest
EVAL_INFO = "eval_info.json"


@dataclass
class ExpertEvalConfig:
    """``lerobot-pnp expert``: run the FSM expert on seeds ``seed .. seed + n_episodes - 1`` (of every suite)."""

    n_episodes: int = 1000  # number of seeded episodes (per suite when --env.task names suites)
    seed: int = 0  # first seed (of every suite)
    env: BaxterPnPEnvConfig = field(default_factory=BaxterPnPEnvConfig)  # the task (``--env.<field>``)
    progress: bool = True  # a tqdm progress bar
    output_dir: str | None = None  # write eval_info.json there, in lerobot-eval's layout (None: print only)

    def __post_init__(self):
        if not (isinstance(self.n_episodes, int) and self.n_episodes >= 1):
            raise ConfigError(f"n_episodes must be an integer >= 1, got {self.n_episodes!r}")
        if not (isinstance(self.seed, int) and 0 <= self.seed < 2**63 - self.n_episodes):
            raise ConfigError(f"seed must be an integer in [0, 2**63 - n_episodes), got {self.seed!r}")


def evaluate_expert(cfg: ExpertEvalConfig) -> dict:
    """The expert on ``cfg.env``'s task, or on each suite ``cfg.env.task`` names; ``eval_info.json`` with
    ``output_dir``."""
    from lerobot_pnp.evaluation.stock_suites import suite_configs

    suites = suite_configs(cfg.env)  # the names checked before any episode runs
    if cfg.output_dir is not None:  # an eval_info.json of the user's there is refused before any episode runs
        with OutputFolder(Path(cfg.output_dir), COMMAND) as folder:
            if _written_before_the_manifest(folder):
                folder.adopt(EVAL_INFO)
            folder.claim(EVAL_INFO)
    if suites is None:
        result = _evaluate_task(cfg)
        groups = {cfg.env.type: result.pop("_records")}
    else:
        result, groups = _evaluate_suites(cfg, suites)
    if cfg.output_dir is not None:
        with OutputFolder(Path(cfg.output_dir), COMMAND) as folder:
            text = json.dumps(stock_eval_info(groups, result["wall_s"]), indent=2)
            result["eval_info"] = str(folder.write_text(EVAL_INFO, text))
    return result


def _written_before_the_manifest(folder: OutputFolder) -> bool:
    """Whether the folder's ``eval_info.json`` is one this command wrote before manifests existed: nothing is
    recorded there, and every task of the file has the failure causes only this command writes."""
    info = read_record(folder.path / EVAL_INFO)
    if folder.owners or not isinstance(info, dict):
        return False
    tasks = info.get("per_task")
    if not (isinstance(tasks, list) and tasks):
        return False
    return all(isinstance(t, dict) and "failure_causes" in (t.get("metrics") or {}) for t in tasks)


def _evaluate_suites(cfg: ExpertEvalConfig, suites: dict[str, BaxterPnPEnvConfig]) -> tuple[dict, dict]:
    from lerobot_pnp.closed_loop import eval_expert
    from lerobot_pnp.evaluation.records import summarize

    groups, start = {}, time.perf_counter()
    for name, env_cfg in tqdm(suites.items(), desc="expert suites", unit="suite", disable=not cfg.progress):
        groups[name] = eval_expert(env_cfg, cfg.n_episodes, cfg.seed)
    wall = time.perf_counter() - start
    per_suite = {}
    for name, records in groups.items():
        counts = summarize(records)
        per_suite[name] = {"success_rate": counts["successes"] / counts["n"], "failures_by_cause": counts["by_cause"]}
    n = sum(len(r) for r in groups.values())
    summary = {
        "suites": per_suite,
        "n_episodes": n,
        "success_rate": sum(r.success for rs in groups.values() for r in rs) / n,
        "wall_s": wall,
    }
    return summary, groups


def stock_eval_info(groups: dict, wall_s: float) -> dict:
    """``{suite: [EpisodeRecord]}`` as ``lerobot-eval`` writes its ``eval_info.json`` (one task, id 0, per suite;
    the env's reward is 1 on the step that succeeds, so an episode's sum and max reward are its success), with each
    episode's seed and failure cause beside its success, and no videos."""
    per_task, per_group = [], {}
    for name, records in groups.items():
        successes = [bool(r.success) for r in records]
        rewards = [float(s) for s in successes]
        per_task.append(
            {
                "task_group": name,
                "task_id": 0,
                "metrics": {
                    "sum_rewards": rewards,
                    "max_rewards": rewards,
                    "successes": successes,
                    "seeds": [int(r.seed) for r in records],
                    "failure_causes": [r.failure_cause for r in records],
                    "video_paths": [],
                },
            }
        )
        per_group[name] = _aggregate(rewards)
    every = [float(r.success) for records in groups.values() for r in records]
    overall = _aggregate(every) | {"eval_s": wall_s, "eval_ep_s": wall_s / max(1, len(every))}
    return {"per_task": per_task, "per_group": per_group, "overall": overall}


def _aggregate(rewards: list[float]) -> dict:
    mean = sum(rewards) / len(rewards) if rewards else float("nan")
    return {
        "avg_sum_reward": mean,
        "avg_max_reward": mean,
        "pc_success": 100 * mean,
        "n_episodes": len(rewards),
        "video_paths": [],
    }


def _evaluate_task(cfg: ExpertEvalConfig) -> dict:
    """Success rate and failures by cause of the expert on ``cfg.env`` (its one task)."""
    from lerobot_pnp.evaluation.records import EpisodeRecord

    env = make_env(cfg.env, render_mode=None)
    causes: collections.Counter = collections.Counter()
    phases: collections.Counter = collections.Counter()
    recoveries: collections.Counter = collections.Counter()
    failed_seeds: dict[str, list[int]] = collections.defaultdict(list)
    records = []
    start = time.perf_counter()
    seeds = range(cfg.seed, cfg.seed + cfg.n_episodes)
    for seed in tqdm(seeds, desc="expert episodes", unit="ep", disable=not cfg.progress, mininterval=1.0):
        cause = ""
        try:
            recoveries.update(run_expert_episode(env, seed).info["recoveries"])
        except (ExpertFailure, UnreachableError) as err:
            cause = failure_cause(err)
            causes[cause] += 1
            phases[getattr(err, "phase", None) or "unknown"] += 1
            failed_seeds[cause].append(seed)
        records.append(EpisodeRecord(seed, not cause, cause, -1, "", 0, float("nan"), float("nan")))
    elapsed = time.perf_counter() - start
    env.close()
    n_fail = sum(causes.values())
    return {
        "n_episodes": cfg.n_episodes,
        "env": cfg.env.to_dict(),
        "success_rate": 1 - n_fail / cfg.n_episodes,
        "failures_by_cause": dict(causes),
        "failures_by_furthest_phase": dict(phases),
        "recoveries": dict(recoveries),
        "failed_seeds": {k: v[:20] for k, v in failed_seeds.items()},
        "episodes_per_s": cfg.n_episodes / elapsed,
        "wall_s": elapsed,
        "_records": records,
    }
