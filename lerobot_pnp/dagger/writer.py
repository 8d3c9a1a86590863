"""Labelled episodes -> a LeRobotDataset (LeRobot's writer), in the layout of ``lerobot_pnp.dataset``.

The features are ``lerobot_pnp.dataset.dataset_features`` with ``observation.environment_state`` sized and
named from the env config (object xyz [+ yaw features] [+ goal xy]), so expert demonstrations and DAgger
episodes of one task aggregate into one dataset. The env config is recorded (``meta/baxter_pnp_env.json``).
A dataset is written into ``<root>.tmp`` and renamed when finalized: a folder without the suffix is whole.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lerobot_pnp import robot


@dataclass
class LabelledEpisode:
    """One episode: what the policy observed at each step and the expert's label for that state."""

    seed: int
    states: np.ndarray  # (T, 8) observed joints + gripper
    env_states: np.ndarray  # (T, De) observed object [+ yaw] [+ goal]
    actions: np.ndarray  # (T, 8) the expert's next keyframe from each state
    phases: np.ndarray  # (T,) the expert's phase label
    success: bool = True  # did the episode (expert or policy) succeed
    suite: str = ""
    info: dict = field(default_factory=dict)


def features_for(env_cfg) -> dict:
    """``dataset_features`` with the environment state of ``env_cfg`` (e.g. 7 dims in the ``full`` task)."""
    from lerobot_pnp.dataset import dataset_features

    features = dataset_features(None)
    names = list(env_cfg.environment_state_names)
    features["observation.environment_state"] = {"dtype": "float32", "shape": (len(names),), "names": names}
    return features


def write_episodes(
    root: Path, repo_id: str, env_cfg, episodes: list[LabelledEpisode], splits: dict | None = None
) -> Path:
    """Write ``episodes`` as a finalized LeRobotDataset at ``root`` (replaced atomically if it exists)."""
    from lerobot.datasets.io_utils import load_info, write_info
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_pnp.dataset.schema import ROBOT_TYPE
    from lerobot_pnp.env_config import write_recorded

    root = Path(root)
    tmp = root.with_name(root.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    ds = LeRobotDataset.create(
        repo_id=repo_id,
        fps=env_cfg.fps,
        features=features_for(env_cfg),
        root=tmp,
        robot_type=ROBOT_TYPE,
        use_videos=False,
        metadata_buffer_size=max(10, len(episodes)),
    )
    for ep in episodes:
        n = len(ep.actions)
        for i in range(n):
            last = i == n - 1
            ds.add_frame(
                {
                    "observation.state": ep.states[i].astype(np.float32),
                    "observation.environment_state": ep.env_states[i].astype(np.float32),
                    "action": ep.actions[i].astype(np.float32),
                    "next.done": np.array([last]),
                    "next.success": np.array([last and ep.success]),
                    "phase.index": np.array([ep.phases[i]], dtype=np.int64),
                    "phase.subtask": np.array([ep.phases[i] // robot.N_PHASES_PER_SUBTASK], dtype=np.int64),
                    "episode.seed": np.array([ep.seed], dtype=np.int64),
                    "task": robot.TASK,
                }
            )
        ds.save_episode()
    ds.finalize()
    if splits:
        info = load_info(tmp)
        info.splits = dict(splits)
        write_info(info, tmp)
    write_recorded(env_cfg, tmp)
    if root.exists():
        shutil.rmtree(root)
    tmp.rename(root)
    return root


def aggregate(roots: list[Path], repo_ids: list[str], out_root: Path, repo_id: str, env_cfg, splits: dict) -> Path:
    """Merge datasets with LeRobot's ``aggregate_datasets`` into ``out_root`` (replaced atomically)."""
    from lerobot.datasets.aggregate import aggregate_datasets
    from lerobot.datasets.io_utils import load_info, write_info

    from lerobot_pnp.env_config import write_recorded

    out_root = Path(out_root)
    tmp = out_root.with_name(out_root.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    aggregate_datasets(repo_ids=repo_ids, aggr_repo_id=repo_id, roots=[Path(r) for r in roots], aggr_root=tmp)
    info = load_info(tmp)
    info.splits = dict(splits)
    write_info(info, tmp)
    write_recorded(env_cfg, tmp)
    if out_root.exists():
        shutil.rmtree(out_root)
    tmp.rename(out_root)
    return out_root
