"""The study's only calls into the dataset generator and the fast trainer.

Kept in one place on purpose: when the generator's or the trainer's config changes, only this module changes. Everything else in ``lerobot_pnp.report`` talks to these functions and to
LeRobot's own dataset/policy APIs.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_pnp.dataset.layout import read_info
from lerobot_pnp.dataset.splits import recorded_splits
from lerobot_pnp.errors import DatasetError, PnPError

BATCH_SIZE = 64  # episodes per batch (the fast trainer's default)
# the generator's advice to its own command; in a study, rerunning the study's command resumes the generation
_GENERATE_RESUME = re.compile(r"rerun (the same command )?with --resume")


def generate_dataset(
    root: Path,
    num_episodes: int,
    seed: int,
    workers: int = 0,
    preset: str = "paper",
    control_mode: str = "keyframe",
    env_changes: dict | None = None,
) -> dict:
    """Generate (or finish, or verify and reuse) an expert dataset of ``num_episodes`` in ``root``; returns
    its summary.

    ``control_mode="dense"`` records the same demonstrations (same seeds, same object positions) at the
    control rate (ACT's training data); ``env_changes`` sets env fields on top of the preset (e.g.
    ``observe_phase``: the same demonstrations with the phase one-hot observed; a ``control_mode`` there wins).
    """
    from lerobot_pnp.dataset import generate

    # an existing dataset is resumed or, when complete, verified against its record of how it was made (an
    # OtherSettingsError names the setting that differs)
    try:
        return generate(dataset_config(root, num_episodes, seed, workers, preset, control_mode, env_changes))
    except DatasetError as err:
        if isinstance(err.__context__, KeyboardInterrupt):  # the study says how it continues (run.run_study)
            raise KeyboardInterrupt from None
        if not _GENERATE_RESUME.search(str(err)):
            raise
        # the study passes --resume itself (``dataset_config``): its own command is what continues
        raise DatasetError(_GENERATE_RESUME.sub("run the same study command again", str(err))) from None


def dataset_config(
    root: Path,
    num_episodes: int,
    seed: int,
    workers: int = 0,
    preset: str = "paper",
    control_mode: str = "keyframe",
    env_changes: dict | None = None,
):
    """The generator's config of ``generate_dataset`` (a ConfigError for an invalid value, before any file is
    touched)."""
    from lerobot_pnp.dataset import GenerateConfig
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    return GenerateConfig(
        repo_id=f"local/{root.name}",
        root=str(root),
        num_episodes=num_episodes,
        seed=seed,
        workers=workers,
        resume=root.exists(),
        progress=True,
        env=BaxterPnPEnvConfig(preset=preset, **{"control_mode": control_mode, **(env_changes or {})}),
    )


def train_pnp_lstm(
    dataset_root: Path,
    output_dir: Path,
    seed: int,
    epochs: int,
    policy_overrides: dict,
    n_demos: int | None = None,
    batch_size: int = BATCH_SIZE,
) -> Path:
    """Train ``pnp_lstm`` with the fast trainer; returns the ``pretrained_model`` folder (lerobot-eval loads it).

    ``n_demos`` trains on the first ``n_demos`` episodes only: the trainer's test-split override holds out
    every later episode (so the held-out loss is measured on more episodes, never on training ones).
    """
    from lerobot_pnp.dagger.config import RECOVERING_CURVE_EVERY
    from lerobot_pnp.policy import PnpLstmConfig
    from lerobot_pnp.train_fast import TrainFastConfig, train_fast

    # the paper's planner: a held-out loss every epoch (its loss-curve figure); the recovering planners less often
    every = 1 if policy_overrides.get("mode", "clocked") != "recovering" else RECOVERING_CURVE_EVERY
    test_episodes, steps = None, None
    if n_demos is not None:
        total = int(read_info(dataset_root)["total_episodes"])
        if not 1 <= n_demos < total:
            raise PnPError(f"n_demos must be in [1, {total - 1}] for {dataset_root}, got {n_demos}")
        test_episodes = f"{n_demos}:{total}"
        # the same number of optimiser steps as a run on the whole training split (not the same epochs)
        n_full = len(recorded_splits(dataset_root).get("train", range(total)))
        steps = epochs * math.ceil(n_full / batch_size)
        every = heldout_every_epochs(n_demos, n_full, batch_size)

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
            batch_size=batch_size,
            eval_every_epochs=every,
        )
    )
    return checkpoint_of(output_dir)


def heldout_every_epochs(n_demos: int, n_full: int, batch_size: int = BATCH_SIZE) -> int:
    """Epochs between two held-out losses of a run on ``n_demos`` of ``n_full`` training episodes: about one
    per epoch of the whole split (the same optimiser-step cadence, so about as many points as a full run). Every
    epoch would cost more than the training itself on a few demonstrations: the held-out episodes are then
    nearly the whole dataset, and a run of the same steps has one or two batches per epoch."""
    return max(1, round(math.ceil(n_full / batch_size) / math.ceil(n_demos / batch_size)))


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


def read_frames(dataset_root: Path, columns: list[str]) -> dict[str, np.ndarray]:
    """The named per-frame columns of a dataset, rows sorted by episode then frame (vector columns as
    ``(N, D)``), plus ``episode_index`` and ``frame_index``.

    The data files of a LeRobotDataset v3 are plain parquet: reading the columns in one go takes well under
    a second, where LeRobotDataset's row access takes minutes.
    """
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.dataset as pads

    files = sorted((Path(dataset_root) / "data").rglob("*.parquet"))
    if not files:
        raise DatasetError(f"{dataset_root}: no data/*.parquet files")
    names = list(dict.fromkeys(["episode_index", "frame_index", *columns]))
    table = pads.dataset([str(f) for f in files], format="parquet").to_table(columns=names)
    order = np.lexsort((table["frame_index"].to_numpy(), table["episode_index"].to_numpy()))
    out = {}
    for name in names:
        col = table[name]
        if pa.types.is_list(col.type) or pa.types.is_fixed_size_list(col.type):
            out[name] = pc.list_flatten(col).to_numpy().reshape(len(table), -1)[order]
        else:
            out[name] = col.to_numpy()[order]
    return out


def load_train_episodes(dataset_root: Path, split: str = "train", limit: int | None = None) -> Episodes:
    """Episodes of ``split`` (meta/info.json ``splits``; all episodes if absent), read with LeRobot's dataset.

    ``limit`` keeps the first ``limit`` episodes of the split (the data-efficiency study).
    """
    frames = read_frames(dataset_root, ["observation.environment_state", "action"])
    ep = frames["episode_index"]
    env_state = frames["observation.environment_state"].astype(np.float32)
    action = frames["action"].astype(np.float32)
    recorded = recorded_splits(dataset_root).get(split)
    if recorded is None:
        if split != "train":
            raise DatasetError(f"{dataset_root}: no {split!r} split in meta/info.json")
        wanted = np.unique(ep)
    else:
        wanted = np.arange(recorded.start, recorded.stop)
    if limit is not None:
        wanted = wanted[:limit]
    starts = np.searchsorted(ep, wanted, side="left")
    stops = np.searchsorted(ep, wanted, side="right")
    firsts, actions = [], []
    for a, b in zip(starts, stops, strict=True):
        if b > a:
            firsts.append(env_state[a])
            actions.append(action[a:b])
    if not actions:
        raise DatasetError(f"{dataset_root}: split {split!r} has no episodes")
    return Episodes(np.asarray(wanted), np.stack(firsts), actions)


def check_same_demonstrations(root: Path, other: Path) -> int:
    """Raise DatasetError unless both recordings hold the same episodes (seeds, split); return the count.

    The study records its demonstrations once more for a method that needs another view of them (the dense
    control rate for ACT, the phase one-hot for the phase-told control); this is what makes them "the same data".

    Episode slot ``i`` of a generation uses seed ``seed + i`` unless the expert failed and reseeded, so equal
    ``episode.seed`` per episode means the same object positions in both recordings.
    """
    seeds, splits = [], []
    for path in (root, other):
        cols = read_frames(Path(path), ["episode.seed"])
        ep, seed = cols["episode_index"], cols["episode.seed"].reshape(len(cols["episode_index"]))
        _, first = np.unique(ep, return_index=True)
        seeds.append(seed[first])
        splits.append(read_info(path).get("splits"))
    if len(seeds[0]) != len(seeds[1]) or not np.array_equal(seeds[0], seeds[1]) or splits[0] != splits[1]:
        differ = np.flatnonzero(seeds[0][: len(seeds[1])] != seeds[1][: len(seeds[0])])[:5].tolist()
        raise DatasetError(
            f"{other} does not hold the demonstrations of {root}: {len(seeds[1])} vs {len(seeds[0])} "
            f"episodes, splits {splits[1]} vs {splits[0]}, first differing episodes {differ}"
        )
    return len(seeds[0])
