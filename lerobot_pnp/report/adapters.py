"""The study's only calls into the dataset generator and the fast trainer (both being restructured).

Kept in one place on purpose: when ``GenerateConfig`` takes an ``env`` field, or the trainer's config moves,
only this module changes. Everything else in ``lerobot_pnp.report`` talks to these three functions and to
LeRobot's own dataset/policy APIs.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_pnp.errors import DatasetError, PnPError

BATCH_SIZE = 64  # episodes per batch (the fast trainer's default)


def generate_dataset(root: Path, num_episodes: int, seed: int, workers: int = 0, preset: str = "paper") -> dict:
    """Generate (or finish, or reuse) an expert dataset of ``num_episodes`` in ``root``; returns its summary."""
    from lerobot_pnp.dataset import GenerateConfig, generate, validate_dataset

    if preset != "paper":
        raise PnPError(f"the dataset generator on this branch only generates the 'paper' task, not {preset!r}")
    if root.exists() and (root / "meta" / "info.json").exists():
        try:
            validate_dataset(root)
            return {"root": str(root), "status": "reused"}
        except PnPError:
            pass
    cfg = GenerateConfig(
        repo_id=f"local/{root.name}",
        root=str(root),
        num_episodes=num_episodes,
        seed=seed,
        workers=workers,
        resume=root.exists(),
        progress=True,
    )
    return generate(cfg)


def train_pnp_lstm(
    dataset_root: Path, output_dir: Path, seed: int, epochs: int, policy_overrides: dict, n_demos: int | None = None
) -> Path:
    """Train ``pnp_lstm`` with the fast trainer; returns the ``pretrained_model`` folder (lerobot-eval loads it).

    ``n_demos`` trains on the first ``n_demos`` episodes only: the trainer's test-split override holds out
    every later episode (so the held-out loss is measured on more episodes, never on training ones).
    """
    from lerobot_pnp.policy import PnpLstmConfig
    from lerobot_pnp.train_fast import TrainFastConfig, train_fast

    test_episodes, steps = None, None
    if n_demos is not None:
        info = json.loads((dataset_root / "meta" / "info.json").read_text())
        total = int(info["total_episodes"])
        if not 1 <= n_demos < total:
            raise PnPError(f"n_demos must be in [1, {total - 1}] for {dataset_root}, got {n_demos}")
        test_episodes = f"{n_demos}:{total}"
        # the same number of optimiser steps as a run on the whole training split (not the same epochs)
        n_full = len(range(*(int(v) for v in info.get("splits", {}).get("train", f"0:{total}").split(":"))))
        steps = epochs * math.ceil(n_full / BATCH_SIZE)

    train_fast(
        TrainFastConfig(
            dataset_repo_id=f"local/{dataset_root.name}",
            dataset_root=str(dataset_root),
            policy=PnpLstmConfig(**policy_overrides),
            epochs=epochs,
            seed=seed,
            output_dir=str(output_dir),
            overwrite=True,
            progress=False,
            test_episodes=test_episodes,
            steps=steps,
            batch_size=BATCH_SIZE,
        )
    )
    return checkpoint_of(output_dir)


def checkpoint_of(train_dir: Path) -> Path:
    return train_dir / "checkpoints" / "last" / "pretrained_model"


def loss_history(train_dir: Path) -> list[dict[str, float]]:
    """Per-epoch train and held-out MSE written by the fast trainer (``loss_curve.csv``)."""
    path = train_dir / "loss_curve.csv"
    if not path.is_file():
        return []
    with open(path) as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


@dataclass
class Episodes:
    """The training episodes of a dataset, as the lookup table needs them."""

    index: np.ndarray  # (E,) episode indices
    first_env_state: np.ndarray  # (E, D) observation.environment_state at the first frame
    actions: list[np.ndarray]  # E arrays (T_e, action_dim)


def load_train_episodes(dataset_root: Path, split: str = "train", limit: int | None = None) -> Episodes:
    """Episodes of ``split`` (meta/info.json ``splits``; all episodes if absent), read with LeRobot's dataset.

    ``limit`` keeps the first ``limit`` episodes of the split (the data-efficiency study).
    """
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    info = json.loads((dataset_root / "meta" / "info.json").read_text())
    ds = LeRobotDataset(f"local/{dataset_root.name}", root=dataset_root)
    table = ds.hf_dataset.with_format("numpy")
    ep = np.asarray(table["episode_index"]).reshape(-1)
    frame = np.asarray(table["frame_index"]).reshape(-1)
    env_state = np.stack(table["observation.environment_state"]).astype(np.float32)
    action = np.stack(table["action"]).astype(np.float32)
    spec = (info.get("splits") or {}).get(split)
    if spec:
        a, b = (int(v) for v in str(spec).split(":"))
        wanted = np.arange(a, b)
    elif split == "train":
        wanted = np.unique(ep)
    else:
        raise DatasetError(f"{dataset_root}: no {split!r} split in meta/info.json")
    if limit is not None:
        wanted = wanted[:limit]
    firsts, actions = [], []
    for e in wanted:
        rows = np.flatnonzero(ep == e)
        rows = rows[np.argsort(frame[rows])]
        firsts.append(env_state[rows[0]])
        actions.append(action[rows])
    if not actions:
        raise DatasetError(f"{dataset_root}: split {split!r} has no episodes")
    return Episodes(np.asarray(wanted), np.stack(firsts), actions)
