"""Measure the scripted expert: success rate over seeded episodes and failures grouped by cause."""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass

import gymnasium as gym
from tqdm import tqdm

from lerobot_pnp import robot
from lerobot_pnp.env import CONTROL_MODES, DEFAULT_MAX_STEPS
from lerobot_pnp.env_config import GYM_ID
from lerobot_pnp.errors import ConfigError, ExpertFailure, UnreachableError
from lerobot_pnp.expert import failure_cause, run_expert_episode


@dataclass
class ExpertEvalConfig:
    n_episodes: int = 1000
    seed: int = 0
    control_mode: str = "keyframe"
    fps: int = 20  # dense mode only

    def __post_init__(self):
        if self.control_mode not in CONTROL_MODES:
            raise ConfigError(f"control_mode must be one of {CONTROL_MODES}, got {self.control_mode!r}")
        if self.n_episodes < 1:
            raise ConfigError(f"n_episodes must be >= 1, got {self.n_episodes}")


def evaluate_expert(cfg: ExpertEvalConfig) -> dict:
    """Run the FSM expert on seeds ``seed .. seed + n_episodes - 1``; return the rate and failures by cause."""
    env = gym.make(GYM_ID, control_mode=cfg.control_mode,
                   fps=cfg.fps if cfg.control_mode == "dense" else robot.KEYFRAME_FPS,
                   max_episode_steps=DEFAULT_MAX_STEPS[cfg.control_mode])
    causes: collections.Counter = collections.Counter()
    failed_seeds: dict[str, list[int]] = collections.defaultdict(list)
    start = time.perf_counter()
    for seed in tqdm(range(cfg.seed, cfg.seed + cfg.n_episodes), desc="expert episodes", unit="ep"):
        try:
            run_expert_episode(env, seed)
        except (ExpertFailure, UnreachableError) as err:
            cause = failure_cause(err)
            causes[cause] += 1
            failed_seeds[cause].append(seed)
    elapsed = time.perf_counter() - start
    env.close()
    n_fail = sum(causes.values())
    return {
        "n_episodes": cfg.n_episodes,
        "control_mode": cfg.control_mode,
        "success_rate": 1 - n_fail / cfg.n_episodes,
        "failures_by_cause": dict(causes),
        "failed_seeds": {k: v[:20] for k, v in failed_seeds.items()},
        "episodes_per_s": cfg.n_episodes / elapsed,
    }
