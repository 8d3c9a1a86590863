"""Fast training path for the ``pnp_lstm`` planner: whole keyframe episodes as tensors, no DataLoader.

A keyframe dataset is tiny (1400 episodes x 10 frames in the paper), so instead of ``lerobot-train``'s
per-frame windows this loads every episode once as ``(E, 10, D)`` tensors, normalises them with the same
LeRobot pre-processor, and trains the *same* ``PnpLstmPolicy`` on batches of whole episodes. It writes:

* ``<output_dir>/checkpoints/<step>/pretrained_model/`` in ``lerobot-train``'s layout (config.json,
  model.safetensors, train_config.json, policy_{pre,post}processor.json + stats), a ``training_state/``
  next to it and the ``checkpoints/last`` link, so ``lerobot-eval --policy.path=.../pretrained_model``
  loads it;
* ``loss_curve.csv`` and ``loss_curve.png``: train vs held-out MSE (normalised actions) per epoch, the
  paper's Fig. 4;
* ``test_keyframe_error.json``: per-joint held-out error of the predicted next keyframe, in degrees;
* ``train_fast_config.json``: the config of the run.

The train/test split is read from the dataset's ``meta/info.json`` ``splits`` (``{"train": "0:1120",
"test": "1120:1400"}``); without a test split the last 20 % of the episodes are held out.

Library use::

    from lerobot_pnp.train_fast import TrainFastConfig, train_fast
    result = train_fast(TrainFastConfig(dataset_root="data/keyframes", epochs=300))

Command line: ``python -m lerobot_pnp.train_fast --dataset_root=... --epochs=300 --policy.hidden_size=64``.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import os
import random
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import draccus
import numpy as np
import torch

from lerobot_pnp import robot
from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy

logger = logging.getLogger(__name__)

from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE  # noqa: E402

# The keyframe dataset's model features and their shapes (one source of truth: lerobot_pnp.robot).
KEYFRAME_FEATURES: dict[str, tuple[int, ...]] = {
    OBS_STATE: (robot.STATE_DIM,),
    OBS_ENV_STATE: (robot.OBJECT_DIM,),
    ACTION: (robot.ACTION_DIM,),
}
TEST_SPLIT_NAMES = ("test", "val", "validation", "eval")
FALLBACK_TEST_FRACTION = 0.2


@dataclass
class TrainFastConfig:
    """Configuration of :func:`train_fast`. Defaults live here; ``from_train_config`` reads a ``lerobot-train`` JSON."""

    dataset_repo_id: str = "local/baxter_pnp_keyframe"
    dataset_root: str | None = None  # local dataset folder; None: LeRobot's cache / the Hub
    policy: PnpLstmConfig = field(default_factory=PnpLstmConfig)
    epochs: int = 300
    steps: int | None = None  # total optimiser steps; overrides `epochs` when set
    batch_size: int = 64  # episodes per batch
    lr: float | None = None  # overrides policy.optimizer_lr when set
    seed: int = 1000
    output_dir: str = "outputs/train_fast/pnp_lstm"
    overwrite: bool = False  # allow an existing output_dir (its files are replaced)
    test_episodes: str | None = None  # "a:b" overrides the dataset's test split
    eval_every_epochs: int = 1
    save_every_epochs: int = 0  # extra checkpoints every N epochs; 0: only the final one
    num_threads: int | None = 1  # torch.set_num_threads; this model is far faster on 1 thread
    progress: bool = True  # tqdm progress bar

    @classmethod
    def from_train_config(cls, path: str | Path, **overrides: Any) -> TrainFastConfig:
        """Take dataset, policy, batch size, seed and output dir from a ``lerobot-train`` config JSON.

        ``steps`` is not taken over (a ``lerobot-train`` step is a batch of windows, a fast-path step a batch
        of whole episodes); the fast path trains for ``epochs`` unless ``steps`` is given in ``overrides``.
        """
        data = json.loads(Path(path).read_text())
        kwargs: dict[str, Any] = {}
        ds = data.get("dataset") or {}
        if ds.get("repo_id"):
            kwargs["dataset_repo_id"] = ds["repo_id"]
        if ds.get("root"):
            kwargs["dataset_root"] = ds["root"]
        if data.get("policy"):
            kwargs["policy"] = policy_config_from_dict(data["policy"])
        for key in ("batch_size", "seed"):
            if data.get(key) is not None:
                kwargs[key] = data[key]
        if data.get("output_dir"):
            kwargs["output_dir"] = str(data["output_dir"]) + "_fast"
        kwargs.update(overrides)
        return cls(**kwargs)


@dataclass
class KeyframeData:
    """All episodes of a keyframe dataset as tensors ``(E, T, D)`` (raw, unnormalised)."""

    state: torch.Tensor
    env_state: torch.Tensor
    action: torch.Tensor
    episode_index: torch.Tensor  # (E,)
    train_idx: torch.Tensor  # rows of the tensors above
    test_idx: torch.Tensor
    split_source: str  # where the split came from

    def batch(self, rows: torch.Tensor) -> dict[str, torch.Tensor]:
        return {OBS_STATE: self.state[rows], OBS_ENV_STATE: self.env_state[rows], ACTION: self.action[rows]}


@dataclass
class TrainFastResult:
    checkpoint_dir: Path  # .../checkpoints/<step>/pretrained_model
    steps: int
    final_train_mse: float
    final_test_mse: float
    test_keyframe_error: dict[str, Any]
    history: list[dict[str, float]]

    def summary(self) -> dict[str, Any]:
        """What a person wants printed: where the checkpoint is and how good it is."""
        return {
            "checkpoint": str(self.checkpoint_dir),
            "steps": self.steps,
            "final_train_mse": self.final_train_mse,
            "final_test_mse": self.final_test_mse,
            "mean_joint_mae_deg": self.test_keyframe_error.get("mean_joint_mae_deg"),
        }


def policy_config_from_dict(policy: dict[str, Any]) -> PnpLstmConfig:
    """Build a ``PnpLstmConfig`` from the ``policy`` block of a LeRobot config JSON (draccus decoding)."""
    policy = dict(policy)
    ptype = policy.pop("type", "pnp_lstm")
    if ptype != "pnp_lstm":
        raise ValueError(f"The fast path trains pnp_lstm only; the config's policy type is {ptype!r}.")
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(policy, f)
        tmp = f.name
    try:
        with draccus.config_type("json"):
            return draccus.parse(PnpLstmConfig, tmp, args=[])
    finally:
        os.unlink(tmp)


# ---- dataset ------------------------------------------------------------------------------------


def validate_keyframe_dataset(meta: Any, episode_length: int = robot.N_KEYFRAMES) -> None:
    """Raise ``ValueError`` unless ``meta`` (a ``LeRobotDatasetMetadata``) describes a keyframe dataset."""
    features = meta.features
    for key, shape in KEYFRAME_FEATURES.items():
        ft = features.get(key)
        if ft is None:
            raise ValueError(
                f"Dataset '{meta.repo_id}' has no '{key}' feature (expected float32, shape {shape}); "
                f"its features are {sorted(features)}."
            )
        if tuple(ft["shape"]) != shape:
            raise ValueError(
                f"Dataset '{meta.repo_id}': feature '{key}' has shape {tuple(ft['shape'])}, expected {shape}."
            )
        if ft.get("dtype") not in ("float32", "float64"):
            raise ValueError(
                f"Dataset '{meta.repo_id}': feature '{key}' has dtype {ft.get('dtype')}, expected float32."
            )
    lengths = [int(n) for n in meta.episodes["length"]]
    bad = sorted({n for n in lengths if n != episode_length})
    if bad:
        raise ValueError(
            f"Dataset '{meta.repo_id}' is not a keyframe dataset: every episode must have exactly {episode_length} "
            f"frames (one per FSM state), found episode lengths {bad[:10]}."
        )
    if not lengths:
        raise ValueError(f"Dataset '{meta.repo_id}' has no episodes.")


def _parse_range(spec: str, n_episodes: int) -> list[int]:
    try:
        a, b = (int(x) for x in str(spec).split(":"))
    except ValueError as e:
        raise ValueError(f"Episode range {spec!r} is not of the form 'start:stop'.") from e
    if not 0 <= a <= b <= n_episodes:
        raise ValueError(f"Episode range {spec!r} is outside 0:{n_episodes}.")
    return list(range(a, b))


def split_episodes(
    splits: dict[str, str] | None, n_episodes: int, test_override: str | None = None
) -> tuple[list[int], list[int], str]:
    """(train episodes, test episodes, source) from LeRobot's ``info.json`` ``splits`` or the 80/20 fallback."""
    splits = dict(splits or {})
    if test_override is not None:
        test = _parse_range(test_override, n_episodes)
        source = f"override test={test_override}"
    else:
        name = next((n for n in TEST_SPLIT_NAMES if n in splits), None)
        if name is not None:
            test = _parse_range(splits[name], n_episodes)
            source = f"meta/info.json splits {splits}"
        else:
            n_test = max(1, round(FALLBACK_TEST_FRACTION * n_episodes)) if n_episodes > 1 else 0
            test = list(range(n_episodes - n_test, n_episodes))
            source = f"fallback: last {n_test} of {n_episodes} episodes held out (no test split in meta/info.json)"
    test_set = set(test)
    if test_override is None and "train" in splits and any(n in splits for n in TEST_SPLIT_NAMES):
        train = [e for e in _parse_range(splits["train"], n_episodes) if e not in test_set]
    else:
        train = [e for e in range(n_episodes) if e not in test_set]
    if not train:
        raise ValueError(f"The split leaves no training episodes ({source}).")
    return train, test, source


def load_keyframe_data(
    repo_id: str, root: str | Path | None, test_override: str | None = None
) -> tuple[Any, KeyframeData]:
    """Load a keyframe LeRobotDataset into tensors. Returns ``(dataset, data)``."""
    from lerobot_pnp.dataset import open_local_dataset

    ds = open_local_dataset(repo_id, root)
    validate_keyframe_dataset(ds.meta)
    t_ep = robot.N_KEYFRAMES
    cols = [OBS_STATE, OBS_ENV_STATE, ACTION, "episode_index", "frame_index"]
    table = ds.hf_dataset.select_columns(cols).with_format("torch")[:]
    order = np.lexsort((table["frame_index"].numpy(), table["episode_index"].numpy()))
    order_t = torch.as_tensor(order)
    n_ep = len(order) // t_ep
    frame = table["frame_index"][order_t].reshape(n_ep, t_ep)
    ep = table["episode_index"][order_t].reshape(n_ep, t_ep)
    if not torch.equal(frame, torch.arange(t_ep).expand(n_ep, t_ep)) or not bool((ep == ep[:, :1]).all()):
        raise ValueError(
            f"Dataset '{repo_id}' is not a keyframe dataset: frame indices are not 0..{t_ep - 1} per episode."
        )

    def seq(key: str) -> torch.Tensor:
        return table[key][order_t].to(torch.float32).reshape(n_ep, t_ep, -1)

    episode_index = ep[:, 0].clone()
    train_eps, test_eps, source = split_episodes(ds.meta.info.splits, ds.meta.total_episodes, test_override)
    row_of = {int(e): i for i, e in enumerate(episode_index.tolist())}
    data = KeyframeData(
        state=seq(OBS_STATE),
        env_state=seq(OBS_ENV_STATE),
        action=seq(ACTION),
        episode_index=episode_index,
        train_idx=torch.tensor([row_of[e] for e in train_eps], dtype=torch.long),
        test_idx=torch.tensor([row_of[e] for e in test_eps], dtype=torch.long),
        split_source=source,
    )
    return ds, data


# ---- training -----------------------------------------------------------------------------------


def _seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


@torch.no_grad()
def _mse(policy: PnpLstmPolicy, batch: dict[str, torch.Tensor]) -> float:
    was_training = policy.training
    policy.eval()
    loss, _ = policy.forward(batch)
    policy.train(was_training)
    return float(loss)


def _action_names(meta: Any) -> list[str]:
    names = meta.features[ACTION].get("names")
    if isinstance(names, dict):  # {"motors": [...]}
        names = next(iter(names.values()), None)
    if not names or len(names) != robot.ACTION_DIM:
        names = list(robot.ACTION_NAMES)
    return [str(n) for n in names]


@torch.no_grad()
def keyframe_error(
    policy: PnpLstmPolicy,
    postprocessor: Any,
    norm_batch: dict[str, torch.Tensor],
    raw_action: torch.Tensor,
    names: list[str],
) -> dict[str, Any]:
    """Held-out error of the predicted next keyframe (teacher forcing: dataset states as inputs)."""
    policy.eval()
    pred = postprocessor(policy.predict_sequence(norm_batch)).to(torch.float32).cpu()
    err = pred - raw_action.cpu()
    nj = robot.N_JOINTS
    deg = err[..., :nj].abs() * (180.0 / math.pi)  # (E, T, 7)
    rmse = (err[..., :nj].pow(2).mean(dim=(0, 1)).sqrt()) * (180.0 / math.pi)
    gripper = err[..., nj:].abs()
    out: dict[str, Any] = {
        "n_episodes": int(raw_action.shape[0]),
        "mean_joint_mae_deg": float(deg.mean()),
        "per_joint_mae_deg": {names[j]: float(deg[..., j].mean()) for j in range(nj)},
        "per_joint_rmse_deg": {names[j]: float(rmse[j]) for j in range(nj)},
        "per_joint_max_deg": {names[j]: float(deg[..., j].max()) for j in range(nj)},
        "per_keyframe_mean_joint_mae_deg": {
            robot.PHASE_NAMES[k]: float(deg[:, k].mean()) for k in range(min(deg.shape[1], robot.N_KEYFRAMES))
        },
        "gripper_mae": float(gripper.mean()) if gripper.numel() else None,
        "note": "input at keyframe k = dataset state k; target = keyframe k+1 joint targets (action k)",
    }
    return out


def _write_curve(history: list[dict[str, float]], out_dir: Path) -> None:
    with open(out_dir / "loss_curve.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(history[0].keys()))
        w.writeheader()
        w.writerows(history)
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    ep = [h["epoch"] for h in history]
    ax.plot(ep, [h["train_mse"] for h in history], label="train")
    ax.plot(ep, [h["test_mse"] for h in history], label="test (held out)")
    ax.set_yscale("log")
    ax.set_xlabel("epoch")
    ax.set_ylabel("MSE (normalised actions)")
    ax.set_title("pnp_lstm loss (cf. de Magistris et al. 2016, Fig. 4)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / "loss_curve.png", dpi=120)
    plt.close(fig)


def _save(
    out_dir: Path,
    step: int,
    total_steps: int,
    cfg: TrainFastConfig,
    policy: PnpLstmPolicy,
    optimizer: Any,
    scheduler: Any,
    preprocessor: Any,
    postprocessor: Any,
    opt_cfg: Any,
    sched_cfg: Any,
) -> Path:
    from lerobot.common.train_utils import get_step_checkpoint_dir, save_checkpoint, update_last_checkpoint
    from lerobot.configs.default import DatasetConfig
    from lerobot.configs.train import TrainPipelineConfig

    train_cfg = TrainPipelineConfig(
        dataset=DatasetConfig(repo_id=cfg.dataset_repo_id, root=cfg.dataset_root, video_backend="pyav"),
        policy=policy.config,
        output_dir=out_dir,
        job_name="pnp_lstm_train_fast",
        seed=cfg.seed,
        num_workers=0,
        batch_size=cfg.batch_size,
        steps=total_steps,
        env_eval_freq=0,
        save_freq=step,
        optimizer=opt_cfg,
        scheduler=sched_cfg,
    )
    ckpt = get_step_checkpoint_dir(out_dir, total_steps, step)
    save_checkpoint(
        checkpoint_dir=ckpt,
        step=step,
        cfg=train_cfg,
        policy=policy,
        optimizer=optimizer,
        scheduler=scheduler,
        preprocessor=preprocessor,
        postprocessor=postprocessor,
        batch_size=cfg.batch_size,
    )
    update_last_checkpoint(ckpt)
    return ckpt / "pretrained_model"


def train_fast(cfg: TrainFastConfig) -> TrainFastResult:
    """Train ``pnp_lstm`` on whole keyframe episodes; see the module docstring for what is written."""
    from lerobot.policies.factory import make_policy, make_pre_post_processors

    if cfg.num_threads is not None:
        torch.set_num_threads(cfg.num_threads)
    if cfg.batch_size < 1 or cfg.epochs < 1 or (cfg.steps is not None and cfg.steps < 1):
        raise ValueError("batch_size, epochs and steps must be >= 1.")
    if cfg.policy.episode_length != robot.N_KEYFRAMES:
        raise ValueError(
            f"policy.n_subtasks x policy.steps_per_subtask = {cfg.policy.episode_length}, but a keyframe episode "
            f"has {robot.N_KEYFRAMES} frames."
        )
    out_dir = Path(cfg.output_dir)
    if out_dir.exists() and any(out_dir.iterdir()) and not cfg.overwrite:
        raise FileExistsError(f"Output directory {out_dir} already exists; pass overwrite=True or choose another.")
    _seed_everything(cfg.seed)

    ds, data = load_keyframe_data(cfg.dataset_repo_id, cfg.dataset_root, cfg.test_episodes)
    logger.info(
        "Keyframe dataset %s: %d train / %d test episodes (%s)",
        cfg.dataset_repo_id,
        len(data.train_idx),
        len(data.test_idx),
        data.split_source,
    )

    policy_cfg = cfg.policy
    policy_cfg.input_features = {}  # derived from the dataset, as in lerobot-train
    policy_cfg.output_features = {}
    policy: PnpLstmPolicy = make_policy(policy_cfg, ds_meta=ds.meta)  # type: ignore[assignment]
    preprocessor, postprocessor = make_pre_post_processors(policy_cfg, dataset_stats=ds.meta.stats)
    device = next(policy.parameters()).device

    # Normalise everything once with the same pre-processor lerobot-train uses.
    def prep(rows: torch.Tensor) -> dict[str, torch.Tensor]:
        out = preprocessor(data.batch(rows))
        return {k: out[k].to(device) for k in (OBS_STATE, OBS_ENV_STATE, ACTION)}

    train_all = prep(data.train_idx)
    test_all = prep(data.test_idx) if len(data.test_idx) else None

    opt_cfg = policy_cfg.get_optimizer_preset()
    if cfg.lr is not None:
        opt_cfg.lr = cfg.lr
    sched_cfg = policy_cfg.get_scheduler_preset()
    n_train = len(data.train_idx)
    steps_per_epoch = math.ceil(n_train / cfg.batch_size)
    total_steps = cfg.steps if cfg.steps is not None else cfg.epochs * steps_per_epoch
    n_epochs = math.ceil(total_steps / steps_per_epoch)
    optimizer = opt_cfg.build(policy.get_optim_params())
    scheduler = sched_cfg.build(optimizer, total_steps) if sched_cfg is not None else None

    out_dir.mkdir(parents=True, exist_ok=True)
    with open(out_dir / "train_fast_config.json", "w") as f, draccus.config_type("json"):
        draccus.dump(cfg, f, indent=4)

    history: list[dict[str, float]] = []
    test0 = _mse(policy, test_all) if test_all is not None else float("nan")
    history.append(
        {
            "epoch": 0,
            "step": 0,
            "train_mse": _mse(policy, train_all),
            "test_mse": test0,
            "lr": optimizer.param_groups[0]["lr"],
            "time_s": 0.0,
        }
    )

    gen = torch.Generator().manual_seed(cfg.seed)
    step = 0
    t0 = time.perf_counter()
    ckpt_dir: Path | None = None
    pbar = None
    if cfg.progress:
        from tqdm.auto import tqdm

        pbar = tqdm(total=n_epochs, desc="pnp_lstm (fast)", unit="epoch")
    policy.train()
    for epoch in range(1, n_epochs + 1):
        perm = torch.randperm(n_train, generator=gen).to(device)
        losses: list[float] = []
        for i in range(0, n_train, cfg.batch_size):
            rows = perm[i : i + cfg.batch_size]
            batch = {k: v[rows] for k, v in train_all.items()}
            loss, _ = policy.forward(batch)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            if opt_cfg.grad_clip_norm and opt_cfg.grad_clip_norm > 0:
                torch.nn.utils.clip_grad_norm_(policy.parameters(), opt_cfg.grad_clip_norm)
            optimizer.step()
            if scheduler is not None:
                scheduler.step()
            losses.append(float(loss.detach()))
            step += 1
            if step >= total_steps:
                break
        last = epoch == n_epochs
        if last or epoch % max(1, cfg.eval_every_epochs) == 0:
            test = _mse(policy, test_all) if test_all is not None else float("nan")
            history.append(
                {
                    "epoch": epoch,
                    "step": step,
                    "train_mse": float(np.mean(losses)),
                    "test_mse": test,
                    "lr": optimizer.param_groups[0]["lr"],
                    "time_s": time.perf_counter() - t0,
                }
            )
            if pbar is not None:
                pbar.set_postfix(train=f"{history[-1]['train_mse']:.4g}", test=f"{test:.4g}")
        if pbar is not None:
            pbar.update(1)
        if cfg.save_every_epochs > 0 and epoch % cfg.save_every_epochs == 0 and not last:
            _save(
                out_dir,
                step,
                total_steps,
                cfg,
                policy,
                optimizer,
                scheduler,
                preprocessor,
                postprocessor,
                opt_cfg,
                sched_cfg,
            )
            policy.train()
    if pbar is not None:
        pbar.close()
    policy.eval()
    ckpt_dir = _save(
        out_dir, step, total_steps, cfg, policy, optimizer, scheduler, preprocessor, postprocessor, opt_cfg, sched_cfg
    )

    final_train = _mse(policy, train_all)
    final_test = _mse(policy, test_all) if test_all is not None else float("nan")
    names = _action_names(ds.meta)
    if test_all is not None:
        err = keyframe_error(policy, postprocessor, test_all, data.action[data.test_idx], names)
    else:
        err = {"n_episodes": 0}
    err.update(
        {
            "split": data.split_source,
            "n_train_episodes": n_train,
            "n_test_episodes": len(data.test_idx),
            "final_train_mse": final_train,
            "final_test_mse": final_test,
            "steps": step,
            "checkpoint": str(ckpt_dir),
        }
    )
    (out_dir / "test_keyframe_error.json").write_text(json.dumps(err, indent=2))
    _write_curve(history, out_dir)
    logger.info(
        "pnp_lstm fast training done: train MSE %.4g, test MSE %.4g, test joint MAE %.3f deg -> %s",
        final_train,
        final_test,
        err.get("mean_joint_mae_deg", float("nan")),
        ckpt_dir,
    )
    return TrainFastResult(
        checkpoint_dir=ckpt_dir,
        steps=step,
        final_train_mse=final_train,
        final_test_mse=final_test,
        test_keyframe_error=err,
        history=history,
    )


def main() -> None:
    logging.basicConfig(level=logging.INFO)
    cfg = draccus.parse(TrainFastConfig)
    print(json.dumps(train_fast(cfg).summary(), indent=2))


if __name__ == "__main__":
    main()
