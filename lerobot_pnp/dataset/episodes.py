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
    """Keeps the camera images (when the env renders any) and the ``info`` of every observation (reset + each
    step): the frames a dataset records, and what the viewer shows of a run (cameras, perturbations, failure).

    A plain gymnasium wrapper, created lazily so importing this module does not import gymnasium."""

    def __new__(cls, env):
        import gymnasium as gym

        class _Recorder(gym.Wrapper):
            def reset(self, **kwargs):
                obs, info = self.env.reset(**kwargs)
                self.pixels, self.infos = [obs.get("pixels")], [info]
                return obs, info

            def step(self, action):
                out = self.env.step(action)
                self.pixels.append(out[0].get("pixels"))
                self.infos.append(out[4])
                return out

        return _Recorder(env)


def make_recording_env(env_cfg):
    """The env for ``env_cfg`` (built by the one factory), recording camera frames when it renders any."""
    from lerobot_pnp.sim.env_config import make_env

    env = make_env(env_cfg)
    return PixelRecorder(env) if env_cfg.cameras else env


def simulate_slot(env, base_seed: int, num_episodes: int, slot: int, max_retries: int, failures: list):
    """Run the expert on slot ``slot`` until it succeeds; append each failure (a dict) to ``failures``.

    Returns the ExpertEpisode. Raises DatasetError when ``max_retries + 1`` seeds in a row fail.
    """
    from lerobot_pnp.sim.expert import failure_cause, run_expert_episode

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
    if cameras and len(pixels) != ep.num_frames:
        raise DatasetError(f"seed {ep.seed}: {len(pixels)} camera frames for {ep.num_frames} states (bug)")
    frames = frames_from_arrays(ep.states, ep.env_states, ep.actions, ep.phases, ep.seed, ep.success)
    for frame, images in zip(frames, pixels if cameras else [], strict=False):
        for cam in cameras:
            frame[f"observation.images.{cam}"] = images[cam]
    return frames


def frames_from_arrays(states, env_states, actions, phases, seed: int, success: bool) -> list[dict]:
    """``add_frame`` dicts of one episode from its per-frame arrays (expert demonstrations, DAgger episodes).

    The last frame carries ``next.done`` (and ``next.success`` when the episode succeeded); ``phase.subtask``
    is derived from the phase (0 pick, 1 place). ``phases`` holds ``robot.Phase`` values; they are stored as
    plain int64.
    """
    n = len(actions)
    return [
        {
            "observation.state": states[i].astype(np.float32),
            "observation.environment_state": env_states[i].astype(np.float32),
            "action": actions[i].astype(np.float32),
            "next.done": np.array([i == n - 1]),
            "next.success": np.array([i == n - 1 and success]),
            "phase.index": np.array([int(phases[i])], dtype=np.int64),
            "phase.subtask": np.array([int(phases[i]) // robot.N_PHASES_PER_SUBTASK], dtype=np.int64),
            "episode.seed": np.array([seed], dtype=np.int64),
            "task": robot.TASK,
        }
        for i in range(n)
    ]
