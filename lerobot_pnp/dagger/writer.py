"""Labelled episodes -> a LeRobotDataset (LeRobot's writer), in the layout of ``lerobot_pnp.dataset``.

The features are ``lerobot_pnp.dataset.dataset_features`` with ``observation.environment_state`` sized and
named from the env config (object xyz [+ yaw features] [+ goal xy]), so expert demonstrations and DAgger
episodes of one task aggregate into one dataset. The env config is recorded (``meta/baxter_pnp_env.json``).
A dataset is written into ``<root>.tmp`` and renamed when finalized: a folder without the suffix is whole. The
caller's folder holds ``root`` as its own (a DAgger round); a link there is unlinked, never followed.
"""

from __future__ import annotations

import contextlib
import functools
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from unittest import mock

import numpy as np

from lerobot_pnp.dataset.episodes import frames_from_arrays
from lerobot_pnp.dataset.merge import fix_index_stats
from lerobot_pnp.outputs import remove_path


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
    """``dataset_features`` of ``env_cfg`` (e.g. a 7-dim environment state in the ``full`` task), without
    camera images: labelled episodes are state-only."""
    from lerobot_pnp.dataset import dataset_features

    return {k: v for k, v in dataset_features(env_cfg).items() if not k.startswith("observation.images.")}


def write_episodes(
    root: Path, repo_id: str, env_cfg, episodes: list[LabelledEpisode], splits: dict | None = None
) -> Path:
    """Write ``episodes`` as a finalized LeRobotDataset at ``root`` (replaced atomically if it exists)."""
    import datasets
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_pnp.dataset.schema import ROBOT_TYPE, saves_without_image_embedding

    datasets.disable_progress_bars()  # one "Map" bar per saved episode would flood the terminal
    root = Path(root)
    tmp = root.with_name(root.name + ".tmp")
    remove_path(tmp)
    features = features_for(env_cfg)
    ds = LeRobotDataset.create(
        repo_id=repo_id,
        fps=env_cfg.fps,
        features=features,
        root=tmp,
        robot_type=ROBOT_TYPE,
        use_videos=False,
        metadata_buffer_size=max(10, len(episodes)),
    )
    with saves_without_image_embedding(features):
        for ep in episodes:
            for frame in frames_from_arrays(ep.states, ep.env_states, ep.actions, ep.phases, ep.seed, ep.success):
                ds.add_frame(frame)
            ds.save_episode()
    ds.finalize()
    return _commit(tmp, root, env_cfg, dict(splits) if splits else None)


def aggregate(
    roots: list[Path], repo_ids: list[str], out_root: Path, repo_id: str, env_cfg, splits: dict, progress: bool = True
) -> Path:
    """Merge datasets with LeRobot's ``aggregate_datasets`` into ``out_root`` (replaced atomically). With
    ``progress=False`` its two progress bars are off (the study runs DAgger rounds without bars)."""
    from lerobot.datasets import aggregate as lerobot_aggregate

    out_root = Path(out_root)
    tmp = out_root.with_name(out_root.name + ".tmp")
    remove_path(tmp)
    with _bars_of(lerobot_aggregate, progress):
        lerobot_aggregate.aggregate_datasets(
            repo_ids=repo_ids, aggr_repo_id=repo_id, roots=[Path(r) for r in roots], aggr_root=tmp
        )
    fix_index_stats(tmp)
    return _commit(tmp, out_root, env_cfg, dict(splits))


@contextlib.contextmanager
def _bars_of(module, progress: bool):
    """``module``'s ``tqdm.tqdm`` bars, off unless ``progress`` (LeRobot's aggregate has no switch for them)."""
    if progress:
        yield
        return
    import tqdm

    with mock.patch.object(module, "tqdm", SimpleNamespace(tqdm=functools.partial(tqdm.tqdm, disable=True))):
        yield


def _commit(tmp: Path, root: Path, env_cfg, splits: dict | None) -> Path:
    """Finish a dataset written in ``tmp`` (the split, the recorded env config) and move it to ``root``."""
    from lerobot.datasets.io_utils import load_info, write_info

    from lerobot_pnp.recorded_files import write_recorded

    if splits is not None:
        info = load_info(tmp)
        info.splits = splits
        write_info(info, tmp)
    write_recorded(env_cfg, tmp)
    remove_path(root)  # a link is unlinked, never followed
    tmp.rename(root)
    return root
