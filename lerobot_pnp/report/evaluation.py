"""Closed-loop evaluation: stock LeRobot ``eval_policy`` on the env, plus a per-episode record of what happened.

A learned policy (a ``lerobot-train`` checkpoint) or an in-memory policy (the lookup table) is run with
``lerobot.scripts.lerobot_eval.eval_policy`` -- the function ``lerobot-eval`` itself calls -- in this process,
on the ``SyncVectorEnv`` that ``BaxterPnPEnvConfig.create_envs`` builds (the env config's own factory), with
``start_seed`` so that every method meets exactly the same episodes. Running it in-process instead of as the
``lerobot-eval`` CLI changes nothing in the rollout; it lets a thin gymnasium wrapper (``EpisodeRecorder``)
around each sub-env keep the final ``info`` of every episode (seed, failure cause, furthest FSM phase,
perturbations applied, start position), so failures break down by cause and phase and successes can be
mapped over the workspace. The recorded successes are checked against ``eval_policy``'s own.

The expert is evaluated on the same seeds with its own loop (it is privileged: it reads the simulator).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

import gymnasium as gym
import torch

from lerobot_pnp import robot
from lerobot_pnp.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.errors import ExpertFailure, PnPError, UnreachableError

NEW_ROLLOUT_OPTION = "lerobot_new_rollout"  # what lerobot's rollout passes on a genuine reset


@dataclass
class EpisodeRecord:
    """What one evaluation episode ended with (one line of the per-episode table)."""

    seed: int
    success: bool
    failure_cause: str  # "" on success (task.FAILURE_CAUSES, or the expert's cause)
    furthest_phase: int  # index into robot.PHASE_NAMES; -1 if unknown
    perturbations: str  # comma-separated names of the perturbations that fired
    steps: int
    object_x: float  # true start position of the object (m, base frame)
    object_y: float


class EpisodeRecorder(gym.Wrapper):
    """Appends an ``EpisodeRecord`` to ``sink`` when an episode started by a seeded reset first ends.

    Gymnasium's autoreset (a reset without seed or LeRobot's new-rollout option) starts nothing: the
    rollout ignores those episodes, and so does the recorder.
    """

    def __init__(self, env: gym.Env, sink: list[EpisodeRecord]):
        super().__init__(env)
        self.sink = sink
        self._current: dict | None = None

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        if seed is not None or (options or {}).get(NEW_ROLLOUT_OPTION):
            pos, _ = self.env.unwrapped.physics.object_pose()
            self._current = {"seed": -1 if seed is None else int(seed), "steps": 0, "xy": pos[:2].copy()}
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        cur = self._current
        if cur is not None:
            cur["steps"] += 1
            if terminated or truncated:
                success = bool(info.get("is_success", False))
                self.sink.append(
                    EpisodeRecord(
                        seed=cur["seed"],
                        success=success,
                        failure_cause="" if success else (info.get("failure_cause") or "truncated"),
                        furthest_phase=int(info.get("furthest_phase", -1)),
                        perturbations=str(info.get("perturbations", "")),
                        steps=cur["steps"],
                        object_x=float(cur["xy"][0]),
                        object_y=float(cur["xy"][1]),
                    )
                )
                self._current = None
        return obs, reward, terminated, truncated, info


def load_checkpoint(path: Path, env_cfg: BaxterPnPEnvConfig):
    """A ``lerobot-train`` checkpoint as (policy, preprocessor, postprocessor), the way ``lerobot-eval`` loads it."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import make_policy, make_pre_post_processors

    if not (Path(path) / "config.json").is_file():
        raise PnPError(f"{path} is not a policy checkpoint (no config.json)")
    cfg = PreTrainedConfig.from_pretrained(str(path))
    cfg.pretrained_path = Path(path)
    cfg.device = "cpu"
    policy = make_policy(cfg=cfg, env_cfg=env_cfg)
    pre, post = make_pre_post_processors(
        policy_cfg=cfg, pretrained_path=str(path), preprocessor_overrides={"device_processor": {"device": "cpu"}}
    )
    return policy, pre, post


def eval_lerobot_policy(
    policy, preprocessor, postprocessor, env_cfg: BaxterPnPEnvConfig, n_episodes: int, start_seed: int, batch_size: int
) -> list[EpisodeRecord]:
    """Run ``n_episodes`` (seeds ``start_seed ..``) with stock ``eval_policy``; one record per episode."""
    from lerobot.envs.factory import make_env_pre_post_processors
    from lerobot.scripts.lerobot_eval import eval_policy

    from lerobot_pnp.progress import quiet_rollout_bars

    batch_size = max(1, min(batch_size, n_episodes))
    vec = env_cfg.create_envs(n_envs=batch_size, use_async_envs=False)[env_cfg.type][0]
    sink: list[EpisodeRecord] = []
    vec.envs = [EpisodeRecorder(e, sink) for e in vec.envs]
    env_pre, env_post = make_env_pre_post_processors(env_cfg=env_cfg, policy_cfg=policy.config)
    try:
        with torch.no_grad(), quiet_rollout_bars():  # one aggregated bar, none in a log
            info = eval_policy(
                env=vec,
                policy=policy,
                env_preprocessor=env_pre,
                env_postprocessor=env_post,
                preprocessor=preprocessor,
                postprocessor=postprocessor,
                n_episodes=n_episodes,
                start_seed=start_seed,
            )
    finally:
        vec.close()
    wanted = set(range(start_seed, start_seed + n_episodes))
    records = sorted((r for r in sink if r.seed in wanted), key=lambda r: r.seed)
    theirs = {int(e["seed"]): bool(e["success"]) for e in info["per_episode"] if e["seed"] in wanted}
    ours = {r.seed: r.success for r in records}
    if ours != theirs:
        diff = sorted(s for s in wanted if ours.get(s) != theirs.get(s))[:10]
        raise PnPError(f"episode recorder disagrees with eval_policy on seeds {diff}")
    return records


def eval_expert(env_cfg: BaxterPnPEnvConfig, n_episodes: int, start_seed: int) -> list[EpisodeRecord]:
    """The scripted expert on seeds ``start_seed ..`` (its own loop; same env config, same seeds)."""
    from lerobot_pnp.expert import failure_cause, run_expert_episode

    env = make_env(env_cfg, render_mode=None)
    records = []
    try:
        for seed in range(start_seed, start_seed + n_episodes):
            cause, phase, steps = "", robot.N_KEYFRAMES - 1, 0
            try:
                ep = run_expert_episode(env, seed)
                steps = ep.num_frames - 1
            except (ExpertFailure, UnreachableError) as err:
                cause = failure_cause(err)
                name = getattr(err, "phase", None)
                phase = robot.PHASE_NAMES.index(name) if name in robot.PHASE_NAMES else -1
                steps = env_cfg.episode_length
            perturbations = ",".join(env.unwrapped.pnp_task.perturbations_fired)
            env.reset(seed=seed)  # the start position, read back from the same seed
            pos, _ = env.unwrapped.physics.object_pose()
            records.append(
                EpisodeRecord(seed, not cause, cause, phase, perturbations, steps, float(pos[0]), float(pos[1]))
            )
    finally:
        env.close()
    return records


def summarize(records: list[EpisodeRecord]) -> dict:
    """Counts for a table: successes, failures by cause and by furthest phase."""
    fails = [r for r in records if not r.success]
    by_cause: dict[str, int] = {}
    by_phase: dict[str, int] = {}
    for r in fails:
        by_cause[r.failure_cause] = by_cause.get(r.failure_cause, 0) + 1
        name = robot.PHASE_NAMES[r.furthest_phase] if 0 <= r.furthest_phase < len(robot.PHASE_NAMES) else "unknown"
        by_phase[name] = by_phase.get(name, 0) + 1
    return {"n": len(records), "successes": len(records) - len(fails), "by_cause": by_cause, "by_phase": by_phase}


def records_to_json(records: list[EpisodeRecord], wall_s: float) -> dict:
    return {"wall_s": wall_s, "episodes": [asdict(r) for r in records]}


def records_from_json(data: dict) -> list[EpisodeRecord]:
    return [EpisodeRecord(**e) for e in data["episodes"]]


class Timer:
    def __enter__(self):
        self.start = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.seconds = time.perf_counter() - self.start
