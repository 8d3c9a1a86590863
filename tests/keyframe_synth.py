"""A small synthetic keyframe dataset (LeRobotDataset v3) for the policy and training tests.

40 episodes x 10 frames with learnable dynamics stand in for the simulator's data: the next keyframe is a
deterministic function of the object position and the phase, so the planner must know the phase (memory /
subtask net) to predict it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from lerobot.datasets import LeRobotDataset
from lerobot.datasets.io_utils import write_info

OBS_STATE, OBS_ENV, ACTION = "observation.state", "observation.environment_state", "action"
STATE_NAMES = ["left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2", "gripper"]
N_EPISODES, N_TRAIN = 40, 32
T = 10
REPO_ID = "test/pnp_synth"


def features(state_dim: int = 8, action_dim: int = 8, with_action: bool = True) -> dict:
    feats = {
        OBS_STATE: {"dtype": "float32", "shape": (state_dim,), "names": STATE_NAMES[:state_dim]},
        OBS_ENV: {"dtype": "float32", "shape": (3,), "names": ["object_x", "object_y", "object_z"]},
        "phase.index": {"dtype": "int64", "shape": (1,), "names": None},
        "phase.subtask": {"dtype": "int64", "shape": (1,), "names": None},
        "next.done": {"dtype": "bool", "shape": (1,), "names": None},
        "next.success": {"dtype": "bool", "shape": (1,), "names": None},
    }
    if with_action:
        feats[ACTION] = {"dtype": "float32", "shape": (action_dim,), "names": STATE_NAMES[:action_dim]}
    return feats


def synthetic_episode(rng: np.random.Generator):
    """10 keyframes: states, object positions and actions (= next keyframe's joint targets + gripper)."""
    place = np.array([0.75, 0.0, -0.13])
    obj0 = np.array([rng.uniform(0.55, 0.85), rng.uniform(-0.25, 0.25), -0.13])
    w = np.linspace(-1.0, 1.0, 21).reshape(7, 3)

    def joints(o, k):
        return np.tanh(w @ (o - place) * (1 + 0.3 * k) + 0.1 * k)

    lift = np.array([0.0, 0.0, 0.1])
    q = [rng.uniform(-0.6, 0.6, 7), joints(obj0 + lift, 1), joints(obj0, 2)]
    q += [q[2].copy(), joints(obj0 + lift, 1)]  # close, retract
    q += [q[4].copy(), joints(place + lift, 3) + 0.3 * q[4], joints(place, 4) + 0.3 * q[4]]
    q += [q[7].copy(), joints(place + lift, 5)]
    grip = [1, 1, 1, 0, 0, 0, 0, 0, 1, 1]
    objs = [obj0] * 4 + [obj0 + lift] * 2 + [place + lift, place, place, place]
    states = [np.concatenate([q[k] + rng.normal(0, 0.005, 7), [grip[k]]]) for k in range(T)]
    acts = [np.concatenate([q[k + 1], [grip[k + 1]]]) for k in range(T - 1)]
    acts[4] = np.concatenate([q[4], [grip[4]]])  # pick retract holds (place start == pick retract)
    acts.append(np.concatenate([q[9], [grip[9]]]))  # place retract holds
    return states, objs, acts


def make_keyframe_dataset(
    root: Path,
    n_episodes: int = N_EPISODES,
    seed: int = 0,
    splits: dict | None = None,
    episode_len: int = T,
    state_dim: int = 8,
    with_action: bool = True,
    repo_id: str = REPO_ID,
    fps: int = 1,
    nan_at: tuple[int, int] | None = None,
) -> LeRobotDataset:
    """Write the dataset; ``nan_at=(episode, frame)`` puts a NaN into that frame's object position."""
    rng = np.random.default_rng(seed)
    ds = LeRobotDataset.create(
        repo_id,
        fps=fps,
        features=features(state_dim, with_action=with_action),
        root=root,
        robot_type="baxter",
        use_videos=False,
        video_backend="pyav",
    )
    for e in range(n_episodes):
        states, objs, acts = synthetic_episode(rng)
        for k in range(episode_len):
            frame = {
                OBS_STATE: states[k % T][:state_dim].astype(np.float32),
                OBS_ENV: objs[k % T].astype(np.float32) * (np.nan if (e, k) == nan_at else 1.0),
                "phase.index": np.array([k % T]),
                "phase.subtask": np.array([(k % T) // 5]),
                "next.done": np.array([k == episode_len - 1]),
                "next.success": np.array([k == episode_len - 1]),
                "task": "Pick the cube and place it on the target.",
            }
            if with_action:
                frame[ACTION] = acts[k % T].astype(np.float32)
            ds.add_frame(frame)
        ds.save_episode()
    ds.finalize()
    if splits is not None:
        ds.meta.info.splits = dict(splits)
        write_info(ds.meta.info, ds.root)
    return ds
