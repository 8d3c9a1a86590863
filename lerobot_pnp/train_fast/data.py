"""A keyframe dataset as tensors ``(E, T, D)`` for the fast path: load, check, split.

A keyframe dataset is tiny (1400 episodes x 10 frames in the paper), so it is read once, whole, with
LeRobot's loader. The checks say what is wrong in terms of the dataset (which feature, which episode and
frame) before any training starts; they raise ``DatasetError`` (``ConfigError`` for a bad split request).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE

from lerobot_pnp import robot
from lerobot_pnp.dataset.splits import train_test
from lerobot_pnp.errors import DatasetError

SUBTASK_KEY = "phase.subtask"
PHASE_KEY = "phase.index"

# The keyframe dataset's model features and their shapes (one source of truth: lerobot_pnp.robot).
KEYFRAME_FEATURES: dict[str, tuple[int, ...]] = {
    OBS_STATE: (robot.STATE_DIM,),
    OBS_ENV_STATE: (robot.OBJECT_DIM,),
    ACTION: (robot.ACTION_DIM,),
}


@dataclass
class KeyframeData:
    """All episodes of a keyframe dataset as tensors ``(E, T, D)`` (raw, unnormalised).

    Variable-length episodes (the ``full`` task's recoveries) are padded at the end to the longest one by
    repeating the last frame; ``pad`` marks the padding (``(E, T)`` bool, all False for fixed 10-frame
    episodes) and travels as ``action_is_pad`` so the policy masks those frames out of the loss.
    ``subtask`` / ``phase`` are the per-frame ``phase.subtask`` / ``phase.index`` labels when the dataset has them.
    """

    state: torch.Tensor
    env_state: torch.Tensor
    action: torch.Tensor
    episode_index: torch.Tensor  # (E,)
    train_idx: torch.Tensor  # rows of the tensors above
    test_idx: torch.Tensor
    split_source: str  # where the split came from
    pad: torch.Tensor | None = None  # (E, T) bool
    subtask: torch.Tensor | None = None  # (E, T) long
    phase: torch.Tensor | None = None  # (E, T) long
    images: dict[str, torch.Tensor] | None = None  # camera key -> (E, T, 3, H, W) uint8 (image policies)

    def batch(self, rows: torch.Tensor) -> dict[str, torch.Tensor]:
        return {OBS_STATE: self.state[rows], OBS_ENV_STATE: self.env_state[rows], ACTION: self.action[rows]}

    def extras(self, rows: torch.Tensor) -> dict[str, torch.Tensor]:
        """The pad mask and labels of ``rows`` (not normalised; added after the pre-processor)."""
        out = {}
        if self.pad is not None and bool(self.pad.any()):
            out[f"{ACTION}_is_pad"] = self.pad[rows]
        if self.subtask is not None:
            out[SUBTASK_KEY] = self.subtask[rows]
        if self.phase is not None:
            out[PHASE_KEY] = self.phase[rows]
        return out


def validate_keyframe_dataset(
    meta: Any, episode_length: int = robot.N_KEYFRAMES, max_length: int | None = None
) -> None:
    """Raise ``DatasetError`` unless ``meta`` (a ``LeRobotDatasetMetadata``) describes a keyframe dataset.

    ``max_length`` set: variable-length episodes of at most that many frames are allowed (recovering mode).
    The environment state may carry yaw / goal dimensions after the object position (the ``full`` task).
    """
    features = meta.features
    for key, shape in KEYFRAME_FEATURES.items():
        ft = features.get(key)
        if key == OBS_ENV_STATE and ft is not None and len(ft["shape"]) == 1 and ft["shape"][0] >= shape[0]:
            shape = tuple(ft["shape"])  # object xyz [+ yaw features] [+ goal xy]
        if ft is None:
            raise DatasetError(
                f"dataset '{meta.repo_id}' has no '{key}' feature (expected float32, shape {shape}); "
                f"its features are {sorted(features)}"
            )
        if tuple(ft["shape"]) != shape:
            raise DatasetError(
                f"dataset '{meta.repo_id}': feature '{key}' has shape {tuple(ft['shape'])}, expected {shape}"
            )
        if ft.get("dtype") not in ("float32", "float64"):
            raise DatasetError(
                f"dataset '{meta.repo_id}': feature '{key}' has dtype {ft.get('dtype')}, expected float32"
            )
    lengths = [int(n) for n in meta.episodes["length"]]
    if not lengths:
        raise DatasetError(f"dataset '{meta.repo_id}' has no episodes")
    if max_length is not None:
        bad = sorted({n for n in lengths if n > max_length})
    else:
        bad = sorted({n for n in lengths if n != episode_length})
    if int(meta.fps) != robot.KEYFRAME_FPS or bad:
        what = f"fps {meta.fps}" + (f", episodes of {bad[:5]} frames" if bad else "")
        if max_length is not None and int(meta.fps) == robot.KEYFRAME_FPS:
            raise DatasetError(
                f"dataset '{meta.repo_id}' has episodes of {bad[:5]} frames, longer than "
                f"policy.max_episode_length={max_length}"
            )
        hint = (
            "; a keyframe dataset with recoveries (the `full` task: episodes of varying length) trains with "
            "--policy.mode=recovering"
            if int(meta.fps) == robot.KEYFRAME_FPS
            else ""
        )
        raise DatasetError(
            f"dataset '{meta.repo_id}' is not a keyframe dataset ({what}): the pnp_lstm trainer needs one frame per "
            f"FSM state ({episode_length} per episode, fps {robot.KEYFRAME_FPS}); a dense dataset (--env.control_mode "
            f"dense) cannot train it{hint}"
        )


def load_keyframe_data(
    repo_id: str,
    root: str | Path | None,
    test_override: str | None = None,
    max_length: int | None = None,
    with_images: bool = False,
) -> tuple[Any, KeyframeData]:
    """Load a keyframe LeRobotDataset into tensors. Returns ``(dataset, data)``.

    ``max_length`` None: every episode must have the paper's 10 frames (clocked mode); set: episodes of any
    length up to it, padded at the end (recovering mode). ``with_images``: its cameras' frames too (``images``).
    """
    from lerobot_pnp.dataset import open_local_dataset

    ds = open_local_dataset(repo_id, root)
    validate_keyframe_dataset(ds.meta, max_length=max_length)
    labels = [k for k in (SUBTASK_KEY, PHASE_KEY) if k in ds.meta.features]
    cols = [OBS_STATE, OBS_ENV_STATE, ACTION, "episode_index", "frame_index", *labels]
    table = ds.hf_dataset.select_columns(cols).with_format("torch")[:]
    ep_all = table["episode_index"].numpy()
    frame_all = table["frame_index"].numpy()
    order = torch.as_tensor(np.lexsort((frame_all, ep_all)))
    episodes, starts, counts = np.unique(ep_all[order.numpy()], return_index=True, return_counts=True)
    n_ep, t_max = len(episodes), int(counts.max())
    if max_length is None and t_max != robot.N_KEYFRAMES:
        raise DatasetError(f"dataset '{repo_id}' is not a keyframe dataset: episodes of {t_max} frames")
    # (E, T) row index into the sorted table; padding repeats the episode's last frame.
    pos = np.minimum(np.arange(t_max)[None, :], counts[:, None] - 1)
    rows = order[torch.as_tensor(starts[:, None] + pos)]
    pad = torch.as_tensor(np.arange(t_max)[None, :] >= counts[:, None])
    frame = table["frame_index"][rows]
    if not bool((frame[~pad] == torch.as_tensor(pos)[~pad]).all()):
        raise DatasetError(
            f"dataset '{repo_id}' is not a keyframe dataset: frame indices are not 0..length-1 per episode"
        )

    def seq(key: str) -> torch.Tensor:
        values = table[key][rows].to(torch.float32).reshape(n_ep, t_max, -1)
        bad = ~torch.isfinite(values).all(dim=-1) & ~pad
        if bool(bad.any()):
            row, k = (int(i) for i in bad.nonzero()[0])
            raise DatasetError(
                f"dataset '{repo_id}': {key} contains NaN or inf in episode {int(episodes[row])}, frame {k} "
                f"({int(bad.sum())} frame(s) in all); fix or regenerate the dataset"
            )
        return values

    def label(key: str) -> torch.Tensor | None:
        return table[key][rows].reshape(n_ep, t_max).long() if key in labels else None

    episode_index = torch.as_tensor(episodes)
    train_eps, test_eps, source = train_test(ds.meta.info.splits, ds.meta.total_episodes, test_override)
    row_of = {int(e): i for i, e in enumerate(episode_index.tolist())}
    data = KeyframeData(
        state=seq(OBS_STATE),
        env_state=seq(OBS_ENV_STATE),
        action=seq(ACTION),
        episode_index=episode_index,
        train_idx=torch.tensor([row_of[e] for e in train_eps], dtype=torch.long),
        test_idx=torch.tensor([row_of[e] for e in test_eps], dtype=torch.long),
        split_source=source,
        pad=pad,
        subtask=label(SUBTASK_KEY),
        phase=label(PHASE_KEY),
    )
    if with_images:
        from .images import camera_keys, episode_images

        if not camera_keys(ds.meta):
            raise DatasetError(
                f"dataset '{repo_id}' records no camera: generate it with --env.cameras (e.g. '[front]') for an "
                "image policy"
            )
        data.images = {k: episode_images(ds, k, episodes, counts, t_max) for k in camera_keys(ds.meta)}
    return ds, data
