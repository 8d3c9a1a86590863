"""One episode slot: the seeds it tries, the expert run, and the dataset frames it becomes.

Episode slot ``i`` (0 <= i < N) is simulated with seed ``seed + i``; when the expert fails on it, retry
``r`` uses ``seed + i + N * r`` (disjoint from every other slot's first try). The content of slot ``i``
therefore depends on (seed, N, i) only, never on how slots are grouped into shards or run in parallel.
"""

from __future__ import annotations

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import DatasetError, ExpertFailure, UnreachableError


def slot_seed(base_seed: int, num_episodes: int, slot: int, retry: int) -> int:
    """Seed of episode slot ``slot`` on its ``retry``-th attempt (disjoint across slots and retries)."""
    return base_seed + slot + num_episodes * retry


class PixelRecorder:
    """Keeps the camera images of every observation the expert sees (reset + each step).

    A plain gymnasium wrapper, created lazily so importing this module does not import gymnasium."""

    def __new__(cls, env):
        import gymnasium as gym

        class _Recorder(gym.Wrapper):
            def reset(self, **kwargs):
                obs, info = self.env.reset(**kwargs)
                self.pixels = [obs["pixels"]]
                return obs, info

            def step(self, action):
                out = self.env.step(action)
                self.pixels.append(out[0]["pixels"])
                return out

        return _Recorder(env)


def make_recording_env(env_cfg):
    """The env for ``env_cfg`` (built by the one factory), recording camera frames when it renders any."""
    from lerobot_pnp.env_config import make_env

    env = make_env(env_cfg)
    return PixelRecorder(env) if env_cfg.cameras else env


def simulate_slot(env, base_seed: int, num_episodes: int, slot: int, max_retries: int, failures: list):
    """Run the expert on slot ``slot`` until it succeeds; append each failure (a dict) to ``failures``.

    Returns the ExpertEpisode. Raises DatasetError when ``max_retries + 1`` seeds in a row fail.
    """
    from lerobot_pnp.expert import failure_cause, run_expert_episode

    for retry in range(max_retries + 1):
        seed = slot_seed(base_seed, num_episodes, slot, retry)
        try:
            # Episodes with recoveries (re-approach after a miss, re-pick after a drop) are longer than the paper's
            # 10 keyframes and are kept: they are the demonstrations of feedback. The paper's task cannot produce
            # them (its 10-step budget leaves no room), so its datasets keep exactly 10 frames per episode.
            ep = run_expert_episode(env, seed)
        except (UnreachableError, ExpertFailure) as err:
            failures.append({"slot": slot, "seed": seed, "cause": failure_cause(err), "message": str(err)})
            continue
        return ep
    raise DatasetError(
        f"episode slot {slot}: the expert failed on {max_retries + 1} seeds in a row "
        f"(last: {failures[-1]['message']}); check the task configuration"
    )


def episode_frames(ep, pixels=None, cameras=()) -> list[dict]:
    """The LeRobot frames (``add_frame`` dicts) of one expert episode, in the layout of ``dataset_features``."""
    T = ep.num_frames
    if cameras and len(pixels) != T:
        raise DatasetError(f"seed {ep.seed}: {len(pixels)} camera frames for {T} states (bug)")
    frames = []
    for i in range(T):
        last = i == T - 1
        frame = {
            "observation.state": ep.states[i].astype(np.float32),
            "observation.environment_state": ep.object_positions[i].astype(np.float32),
            "action": ep.actions[i].astype(np.float32),
            "next.done": np.array([last]),
            "next.success": np.array([last and ep.success]),
            "phase.index": np.array([ep.phases[i]], dtype=np.int64),
            "phase.subtask": np.array([ep.phases[i] // robot.N_PHASES_PER_SUBTASK], dtype=np.int64),
            "episode.seed": np.array([ep.seed], dtype=np.int64),
            "task": robot.TASK,
        }
        for cam in cameras:
            frame[f"observation.images.{cam}"] = pixels[i][cam]
        frames.append(frame)
    return frames
