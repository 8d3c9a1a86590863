"""A keyframe dataset's camera images as ``(E, T, 3, H, W)`` uint8 tensors, for the fast path's image policies.

The generator stores each camera as video (LeRobot v3: many episodes per file, an episode at
``videos/<key>/from_timestamp`` in its file). Each episode's frames are decoded once, in one call per episode
(LeRobot's own decoder, PyAV), and kept as uint8: a few hundred 64x64 episodes are tens of megabytes; the encoder
scales them to [0, 1] per batch.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from lerobot_pnp.errors import DatasetError


def camera_keys(meta: Any) -> list[str]:
    """The dataset's camera features (``observation.images.<camera>``), in a fixed order."""
    return sorted(k for k, ft in meta.features.items() if ft.get("dtype") in ("video", "image"))


def episode_images(ds: Any, key: str, episodes: np.ndarray, counts: np.ndarray, t_max: int) -> torch.Tensor:
    """``(E, t_max, 3, H, W)`` uint8 frames of camera ``key`` for ``episodes`` (``counts`` frames each), each
    padded at the end with its last frame (as the fast path pads every feature)."""
    from lerobot.datasets.video_utils import decode_video_frames

    meta = ds.meta
    if meta.features[key].get("dtype") != "video":
        raise DatasetError(f"dataset '{meta.repo_id}': camera {key} is not stored as video; regenerate it")
    fps = float(meta.fps)
    out: torch.Tensor | None = None  # filled in place: a list of episodes then stacked would hold every frame twice
    for row, (ep, n) in enumerate(zip(episodes.tolist(), counts.tolist(), strict=True)):
        start = float(meta.episodes[int(ep)][f"videos/{key}/from_timestamp"])
        path = ds.root / meta.get_video_file_path(int(ep), key)
        stamps = [start + k / fps for k in range(int(n))]
        frames = decode_video_frames(path, stamps, 0.5 / fps, backend="pyav", return_uint8=True)
        if frames.shape[0] != n:
            raise DatasetError(f"dataset '{meta.repo_id}': episode {ep} of {key} decodes to {frames.shape[0]} frames")
        if out is None:
            out = torch.empty((len(episodes), t_max, *frames.shape[1:]), dtype=frames.dtype)
        out[row, : int(n)] = frames
        out[row, int(n) :] = frames[-1:]
    if out is None:
        raise DatasetError(f"dataset '{meta.repo_id}': no episode to decode for {key}")
    return out
