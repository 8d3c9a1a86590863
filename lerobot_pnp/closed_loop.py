"""The evaluators: a policy run closed-loop in the env, episode by episode or with stock LeRobot ``eval_policy``.

``run_episode`` runs one seeded episode of a ``LoadedPolicy`` in one env and keeps the trajectory
(``evaluate_serial`` runs it on a list of seeds and keeps a record of each: DAgger's evaluation). It mirrors
the per-step pipeline of ``lerobot-eval``'s rollout (gym observation -> ``preprocess_observation`` -> task ->
policy pre-processor -> ``select_action`` -> post-processor -> ``env.step``), so the viewer (``lerobot_pnp.viz``)
watches exactly what ``lerobot-eval`` would run. Set ``env.unwrapped.physics.on_control_tick`` before it to
observe the continuous motion between steps.

The study runs a learned policy (a ``lerobot-train`` checkpoint) or an in-memory policy (the lookup table) with
``lerobot.scripts.lerobot_eval.eval_policy`` -- the function ``lerobot-eval`` itself calls -- in this process,
on the ``SyncVectorEnv`` that ``BaxterPnPEnvConfig.create_envs`` builds (the env config's own factory), with
``start_seed`` so that every method meets exactly the same episodes (``eval_lerobot_policy``). Running it
in-process instead of as the ``lerobot-eval`` CLI changes nothing in the rollout; it lets a thin gymnasium
wrapper (``EpisodeRecorder``) around each sub-env keep the final ``info`` of every episode (seed, failure
cause, furthest FSM phase, perturbations applied, start position), so failures break down by cause and phase
and successes can be mapped over the workspace. The recorded successes are checked against ``eval_policy``'s
own.

The expert is evaluated on the same seeds with its own loop (it is privileged: it reads the simulator).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
import torch

from lerobot_pnp import robot
from lerobot_pnp.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.errors import ConfigError, ExpertFailure, PnPError, UnreachableError
from lerobot_pnp.evaluation.checkpoints import IncompatiblePolicyError, LoadedPolicy, policy_action
from lerobot_pnp.evaluation.records import EpisodeRecord

NEW_ROLLOUT_OPTION = "lerobot_new_rollout"  # what lerobot's rollout passes on a genuine reset


class EpisodeRecorder(gym.Wrapper):
    """Appends an ``EpisodeRecord`` to ``sink`` when an episode started by a seeded reset first ends.

    Gymnasium's autoreset (a reset without seed or LeRobot's new-rollout option) starts nothing: the
    rollout ignores those episodes, and so does the recorder. It also does not simulate them: LeRobot's
    rollout steps every sub-env until the last one of the batch is done, and masks what a sub-env returns
    after the step that follows its end (the autoreset). Until the next seeded reset, a step of this sub-env
    repeats the autoreset's observation instead of running the physics, so a batch costs the sum of its
    episodes' lengths, not its longest episode times its size; the recorded episodes are the same.
    """

    def __init__(self, env: gym.Env, sink: list[EpisodeRecord]):
        super().__init__(env)
        self.sink = sink
        self._current: dict | None = None
        self._idle: tuple | None = None  # (obs, info) of the autoreset after a recorded episode ended

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        if seed is not None or (options or {}).get(NEW_ROLLOUT_OPTION):
            pos, _ = self.env.unwrapped.physics.object_pose()
            self._current = {"seed": -1 if seed is None else int(seed), "steps": 0, "xy": pos[:2].copy()}
            self._idle = None
        elif self._current is None:
            self._idle = (obs, info)
        return obs, info

    def step(self, action):
        if self._idle is not None:
            obs, info = self._idle
            return obs, 0.0, False, False, info
        obs, reward, terminated, truncated, info = self.env.step(action)
        cur = self._current
        if cur is not None:
            cur["steps"] += 1
            if terminated or truncated:
                self.sink.append(EpisodeRecord.from_info(cur["seed"], info, cur["steps"], cur["xy"]))
                self._current = None
        return obs, reward, terminated, truncated, info


def eval_lerobot_policy(
    policy, preprocessor, postprocessor, env_cfg: BaxterPnPEnvConfig, n_episodes: int, start_seed: int, batch_size: int
) -> list[EpisodeRecord]:
    """Run ``n_episodes`` (seeds ``start_seed ..``) with stock ``eval_policy``; one record per episode."""
    from lerobot.envs.factory import make_env_pre_post_processors
    from lerobot.scripts.lerobot_eval import eval_policy

    from lerobot_pnp.progress import quiet_rollout_bars

    if not batch_size >= 1:
        raise ConfigError(f"eval batch_size must be >= 1 (sub-envs evaluated at a time), got {batch_size!r}")
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


@dataclass
class PolicyEpisode:
    """One closed-loop episode. Row ``k`` of ``states``/``env_states`` is the observation the policy saw
    at step ``k``; ``actions[k]`` is what it answered. The last row of ``states`` is the final observation."""

    seed: int
    states: np.ndarray  # (T+1, 8)
    env_states: np.ndarray  # (T+1, E) observed environment state (object xyz [+ yaw] [+ goal] [+ phase])
    actions: np.ndarray  # (T, 8)
    successes: np.ndarray  # (T,) env success flag after each step
    success: bool
    phases: np.ndarray | None = None  # (T+1,) FSM phase of each observation, where the env reports info["phase"]
    info: dict = field(default_factory=dict)

    @property
    def num_steps(self) -> int:
        return len(self.actions)


def run_episode(
    env: Any,
    loaded: LoadedPolicy,
    seed: int,
    *,
    max_steps: int | None = None,
    reset_options: dict | None = None,
    on_step: Callable[[int, dict, np.ndarray], None] | None = None,
) -> PolicyEpisode:
    """Reset ``env`` with ``seed`` and run the policy until success or ``max_steps`` (default: the env's limit).

    ``on_step(k, obs, action)`` is called before each step is applied.
    """
    base = env.unwrapped
    if max_steps is None:
        max_steps = base.config.episode_length
    loaded.reset()
    obs, info = env.reset(seed=seed, options=reset_options)
    phases = [info.get("phase")]
    states = [np.asarray(obs["agent_pos"], np.float32)]
    objects = [np.asarray(obs["environment_state"], np.float32)]
    actions, successes = [], []
    task = getattr(base, "task_description", robot.TASK)
    for k in range(max_steps):
        action = policy_action(loaded, obs, task)
        if action.shape != (robot.ACTION_DIM,) or not np.all(np.isfinite(action)):
            raise IncompatiblePolicyError(f"policy returned an invalid action at step {k}: {action.tolist()}")
        if on_step is not None:
            on_step(k, obs, action)
        obs, _, terminated, truncated, info = env.step(action)
        actions.append(action)
        successes.append(bool(info.get("is_success", False)))
        phases.append(info.get("phase"))
        states.append(np.asarray(obs["agent_pos"], np.float32))
        objects.append(np.asarray(obs["environment_state"], np.float32))
        if terminated or truncated:
            break
    return PolicyEpisode(
        seed=seed,
        states=np.stack(states),
        env_states=np.stack(objects),
        actions=np.stack(actions) if actions else np.zeros((0, robot.ACTION_DIM), np.float32),
        successes=np.asarray(successes, dtype=bool),
        success=bool(successes and successes[-1]),
        phases=np.asarray(phases, dtype=np.int64) if all(p is not None for p in phases) else None,
        info=info,
    )


def evaluate_serial(
    loaded: LoadedPolicy, env_cfg: BaxterPnPEnvConfig, seeds: list[int], progress: Any = None
) -> list[EpisodeRecord]:
    """``loaded`` on ``seeds`` in one env built from ``env_cfg``: seeded resets, each episode until the env ends
    it (success or its step limit), one record per episode (``progress.update(1)`` after each). DAgger's
    evaluation: a ``LoadedPolicy`` episode by episode, where the study runs stock ``eval_policy``."""
    env = make_env(env_cfg)
    records = []
    start: dict[str, np.ndarray] = {}

    def keep_start(k: int, obs: dict, action: np.ndarray) -> None:
        if k == 0:  # before the first step: the true start position of the object
            start["xy"] = env.unwrapped.physics.object_pose()[0][:2].copy()

    try:
        for seed in seeds:
            ep = run_episode(env, loaded, seed, on_step=keep_start)
            records.append(EpisodeRecord.from_info(seed, ep.info, ep.num_steps, start["xy"]))
            if progress is not None:
                progress.update(1)
    finally:
        env.close()
    return records
