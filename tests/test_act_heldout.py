"""ACT in the held-out study: the evaluation's idle sub-envs, the dense task of the `full` suites."""

from __future__ import annotations

import numpy as np

from lerobot_pnp.closed_loop import EpisodeRecorder
from lerobot_pnp.env_config import BaxterPnPEnvConfig, make_env


def test_recorder_does_not_simulate_the_autoreset_episode_after_a_recorded_one():
    """After its seeded episode ended, a sub-env's steps repeat the autoreset observation (the rollout masks
    them) without running the physics, until the next seeded reset."""
    sink: list = []
    env = EpisodeRecorder(make_env(BaxterPnPEnvConfig(preset="paper")), sink)
    base = env.unwrapped
    calls = []
    real_step = base.step
    base.step = lambda action: calls.append(1) or real_step(action)
    obs, _ = env.reset(seed=3)
    hold = np.append(np.asarray(obs["agent_pos"])[:7], 0.0).astype(np.float32)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(hold)
        done = terminated or truncated
    assert len(sink) == 1 and sink[0].seed == 3 and len(calls) == sink[0].steps
    reset_obs, _ = env.reset()  # gymnasium's autoreset: no seed
    n = len(calls)
    for _ in range(3):
        obs, reward, terminated, truncated, _ = env.step(hold)
        assert np.array_equal(obs["agent_pos"], reset_obs["agent_pos"]) and not (terminated or truncated)
    assert len(calls) == n and len(sink) == 1  # nothing simulated, nothing recorded
    env.reset(seed=4)
    env.step(hold)
    assert len(calls) == n + 1  # a seeded reset simulates again


def test_dense_recording_of_full_draws_the_same_episode_schedule():
    """What makes the dense recording of `full` the same demonstrations as the keyframe one: per seed, the
    start and every perturbation's count, moment in its window and the latency are drawn at reset, alike in
    both control modes (what an event draws when it fires is another draw of the same distribution)."""
    envs = [make_env(BaxterPnPEnvConfig(preset="full", control_mode=mode)) for mode in ("keyframe", "dense")]
    for seed in range(12):
        drawn = []
        for env in envs:
            env.reset(seed=seed)
            d, physics = env.unwrapped.pnp_task.disturbances, env.unwrapped.physics
            drawn.append((repr(d.pending), d.latency, d.nudge_step, np.round(physics.object_pose()[0], 6).tolist()))
        assert drawn[0] == drawn[1], seed
    assert envs[1].unwrapped.config.episode_length == 20 * envs[0].unwrapped.config.keyframe_budget
