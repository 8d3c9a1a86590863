"""Measure the scripted expert: success rate over seeded episodes and failures grouped by cause."""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass, field

from tqdm import tqdm

from lerobot_pnp.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.errors import ConfigError, ExpertFailure, UnreachableError
from lerobot_pnp.expert import failure_cause, run_expert_episode


@dataclass
class ExpertEvalConfig:
    """``lerobot-pnp expert``: run the FSM expert on seeds ``seed .. seed + n_episodes - 1``."""

    n_episodes: int = 1000  # number of seeded episodes
    seed: int = 0  # first seed
    env: BaxterPnPEnvConfig = field(default_factory=BaxterPnPEnvConfig)  # the task (``--env.<field>``)
    progress: bool = True  # a tqdm progress bar

    def __post_init__(self):
        if not (isinstance(self.n_episodes, int) and self.n_episodes >= 1):
            raise ConfigError(f"n_episodes must be an integer >= 1, got {self.n_episodes!r}")
        if not (isinstance(self.seed, int) and 0 <= self.seed < 2**63 - self.n_episodes):
            raise ConfigError(f"seed must be an integer in [0, 2**63 - n_episodes), got {self.seed!r}")


def evaluate_expert(cfg: ExpertEvalConfig) -> dict:
    """Success rate and failures by cause of the expert on ``cfg.env``."""
    env = make_env(cfg.env, render_mode=None)
    causes: collections.Counter = collections.Counter()
    phases: collections.Counter = collections.Counter()
    recoveries: collections.Counter = collections.Counter()
    failed_seeds: dict[str, list[int]] = collections.defaultdict(list)
    start = time.perf_counter()
    seeds = range(cfg.seed, cfg.seed + cfg.n_episodes)
    for seed in tqdm(seeds, desc="expert episodes", unit="ep", disable=not cfg.progress, mininterval=1.0):
        try:
            recoveries.update(run_expert_episode(env, seed).info["recoveries"])
        except (ExpertFailure, UnreachableError) as err:
            cause = failure_cause(err)
            causes[cause] += 1
            phases[getattr(err, "phase", None) or "unknown"] += 1
            failed_seeds[cause].append(seed)
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
    }
