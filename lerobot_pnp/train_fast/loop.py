"""The fast path's training loop: whole episodes as preloaded tensors, the same policy, loss and checkpoints.

The data are normalised once with the same LeRobot pre-processor ``lerobot-train`` uses; each step is one
batch of whole episodes (what a ``lerobot-train`` step sees too, with this policy's windows), without a
DataLoader. Checkpoints are written with LeRobot's own ``save_checkpoint`` in ``lerobot-train``'s layout.
"""

from __future__ import annotations

import io
import json
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import draccus
import numpy as np
import torch
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.integration.registration import register_task_record
from lerobot_pnp.outputs import OutputFolder
from lerobot_pnp.policy import PnpLstmPolicy, PnpPixelsConfig
from lerobot_pnp.support.determinism import deterministic_training
from lerobot_pnp.support.progress import log_friendly_tqdm

from .checkpoints import TrainingRun
from .config import TrainFastConfig
from .data import load_keyframe_data
from .output import CONFIG_FILE, clear_previous_run, run_folder
from .summary import CHUNK_EPISODES, action_names, keyframe_error, write_curve

logger = logging.getLogger(__name__)


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


@torch.no_grad()
def _mse(policy: PnpLstmPolicy, batch: dict[str, torch.Tensor] | None) -> float:
    """The policy's loss over every episode of ``batch``, in chunks of ``CHUNK_EPISODES`` episodes: each chunk's mean
    weighted by its real frames, which is the whole split's mean (the loss is a mean over real frames)."""
    if batch is None:
        return float("nan")
    was_training = policy.training
    policy.eval()
    n = len(batch[ACTION])
    total, frames = 0.0, 0
    for start in range(0, n, CHUNK_EPISODES):
        part = {k: v[start : start + CHUNK_EPISODES] for k, v in batch.items()}
        loss, _ = policy.forward(part)
        pad = part.get(f"{ACTION}_is_pad")
        real = int((~pad).sum()) if pad is not None else part[ACTION].shape[0] * part[ACTION].shape[1]
        total += float(loss) * real
        frames += real
    policy.train(was_training)
    return total / max(frames, 1)


def _rows(values: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
    """``values[rows]``, as a view where ``rows`` are consecutive (the usual split): camera frames are the bulk
    of the fast path's memory and the training split would otherwise hold a second copy of most of them."""
    if len(rows) and bool((rows.diff() == 1).all()):
        first = int(rows[0])
        return values[first : first + len(rows)]
    return values[rows]


def _normalised(preprocessor, data, rows: torch.Tensor, device) -> dict[str, torch.Tensor] | None:
    """The episodes ``rows`` normalised once, with the same pre-processor lerobot-train uses (None if empty)."""
    if not len(rows):
        return None
    images = {k: _rows(v, rows) for k, v in (data.images or {}).items()}  # uint8, not normalised: the encoder scales
    out = preprocessor({**data.batch(rows), **images})
    out = {k: out[k].to(device) for k in (OBS_STATE, OBS_ENV_STATE, ACTION, *images)}
    return {**out, **{k: v.to(device) for k, v in data.extras(rows).items()}}


def _optimisation(cfg: TrainFastConfig, folder: OutputFolder, policy, preprocessor, postprocessor, n_train: int):
    """The optimiser and scheduler of the policy's presets (``cfg.lr`` overrides the rate) over the run's
    steps (``cfg.steps``, else ``cfg.epochs`` whole epochs); returns ``(TrainingRun, epochs)``."""
    opt_cfg = cfg.policy.get_optimizer_preset()
    if cfg.lr is not None:
        opt_cfg.lr = cfg.lr
    sched_cfg = cfg.policy.get_scheduler_preset()
    steps_per_epoch = math.ceil(n_train / cfg.batch_size)
    total_steps = cfg.steps if cfg.steps is not None else cfg.epochs * steps_per_epoch
    n_epochs = math.ceil(total_steps / steps_per_epoch)
    optimizer = opt_cfg.build(policy.get_optim_params())
    scheduler = sched_cfg.build(optimizer, total_steps) if sched_cfg is not None else None
    run = TrainingRun(
        cfg, folder, total_steps, policy, optimizer, scheduler, preprocessor, postprocessor, opt_cfg, sched_cfg
    )
    return run, n_epochs


def _epoch(
    run: TrainingRun, train_all: dict[str, torch.Tensor], perm: torch.Tensor, step: int
) -> tuple[list[float], int]:
    """One pass over the training episodes in the order ``perm`` (stops at the run's last step); returns the
    batch losses and the step count after it."""
    policy, optimizer, scheduler, opt_cfg = run.policy, run.optimizer, run.scheduler, run.opt_cfg
    losses: list[float] = []
    for i in range(0, len(perm), run.cfg.batch_size):
        rows = perm[i : i + run.cfg.batch_size]
        loss, _ = policy.forward({k: v[rows] for k, v in train_all.items()})
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        if opt_cfg.grad_clip_norm and opt_cfg.grad_clip_norm > 0:
            torch.nn.utils.clip_grad_norm_(policy.parameters(), opt_cfg.grad_clip_norm)
        optimizer.step()
        if scheduler is not None:
            scheduler.step()
        losses.append(float(loss.detach()))
        step += 1
        if step >= run.total_steps:
            break
    return losses, step


def _final_report(
    run: TrainingRun, ds, data, train_all, test_all, step: int, ckpt_dir: Path, history: list
) -> TrainFastResult:
    """The final MSEs and the held-out keyframe error (``test_keyframe_error.json``), the loss curve."""
    cfg, policy = run.cfg, run.policy
    final_train = _mse(policy, train_all)
    final_test = _mse(policy, test_all)
    if test_all is not None:
        pad = data.pad[data.test_idx] if cfg.policy.recovering else None
        err = keyframe_error(
            policy, run.postprocessor, test_all, data.action[data.test_idx], action_names(ds.meta), pad
        )
    else:
        err = {"n_episodes": 0}
    err.update(
        {
            "split": data.split_source,
            "n_train_episodes": len(data.train_idx),
            "n_test_episodes": len(data.test_idx),
            "final_train_mse": final_train,
            "final_test_mse": final_test,
            "steps": step,
            "checkpoint": str(ckpt_dir),
        }
    )
    run.folder.write_text("test_keyframe_error.json", json.dumps(err, indent=2))
    write_curve(history, run.folder)
    logger.info(
        "pnp_lstm fast training done: train MSE %.4g, test MSE %.4g, test joint MAE %.3f deg -> %s",
        final_train,
        final_test,
        err.get("mean_joint_mae_deg", float("nan")),
        ckpt_dir,
    )
    return TrainFastResult(ckpt_dir, step, final_train, final_test, err, history)


def _continue_from(policy: PnpLstmPolicy, ckpt: Path) -> tuple:
    """Load ``ckpt``'s weights into ``policy`` and return its pre- and post-processors, which hold the
    normalisation statistics those weights were trained with (``TrainFastConfig.init_from``); a checkpoint of
    another architecture is one ConfigError."""
    from lerobot_pnp.evaluation.checkpoints import load_policy

    loaded = load_policy(ckpt)
    try:
        policy.load_state_dict(loaded.policy.state_dict())
    except RuntimeError as err:
        first = str(err).strip().splitlines()[-1].strip()
        raise ConfigError(f"init_from {ckpt}: its weights do not fit this policy config ({first})") from None
    return loaded.preprocessor, loaded.postprocessor


def train_fast(cfg: TrainFastConfig) -> TrainFastResult:
    """Train ``pnp_lstm`` on whole keyframe episodes; see the package docstring for what is written.

    The output folder is held for the whole run (``output.run_folder``: a second run into it fails at once) and
    a previous run there is deleted once the data and the policy are ready (``--overwrite``). The training runs
    seeded, on ``cfg.num_threads`` threads and torch's deterministic algorithms
    (``support.determinism.deterministic_training``): the same seed and data give the same weights."""
    register_task_record()  # its checkpoints record the dataset's task, as under stock lerobot-train
    with run_folder(Path(cfg.output_dir), cfg.overwrite) as folder, deterministic_training(cfg.seed, cfg.num_threads):
        return _train(cfg, folder)


def _policy_and_processors(cfg: TrainFastConfig, ds) -> tuple[PnpLstmPolicy, Any, Any]:
    """The policy built from the dataset's features (as in lerobot-train) and its pre- and post-processors:
    of the dataset's statistics, or of the checkpoint it continues (``init_from``)."""
    from lerobot.policies.factory import make_policy, make_pre_post_processors

    policy_cfg = cfg.policy
    policy_cfg.input_features = {}  # derived from the dataset, as in lerobot-train
    policy_cfg.output_features = {}
    policy: PnpLstmPolicy = make_policy(policy_cfg, ds_meta=ds.meta)  # type: ignore[assignment]
    if cfg.init_from is None:
        preprocessor, postprocessor = make_pre_post_processors(policy_cfg, dataset_stats=ds.meta.stats)
    else:
        preprocessor, postprocessor = _continue_from(policy, Path(cfg.init_from))
    return policy, preprocessor, postprocessor


def _train(cfg: TrainFastConfig, folder: OutputFolder) -> TrainFastResult:
    max_length = cfg.policy.max_episode_length if cfg.policy.recovering else None
    with_images = isinstance(cfg.policy, PnpPixelsConfig)
    ds, data = load_keyframe_data(cfg.dataset_repo_id, cfg.dataset_root, cfg.test_episodes, max_length, with_images)
    logger.info(
        "Keyframe dataset %s: %d train / %d test episodes (%s)",
        cfg.dataset_repo_id,
        len(data.train_idx),
        len(data.test_idx),
        data.split_source,
    )
    policy, preprocessor, postprocessor = _policy_and_processors(cfg, ds)
    device = next(policy.parameters()).device
    train_all = _normalised(preprocessor, data, data.train_idx, device)
    test_all = _normalised(preprocessor, data, data.test_idx, device)
    assert train_all is not None  # train_test guarantees training episodes
    run, n_epochs = _optimisation(cfg, folder, policy, preprocessor, postprocessor, len(data.train_idx))

    clear_previous_run(folder)
    text = io.StringIO()
    with draccus.config_type("json"):
        draccus.dump(cfg, text, indent=4)
    folder.write_text(CONFIG_FILE, text.getvalue())
    folder.claim("checkpoints")  # before the first checkpoint is written into it
    history, step = _fit(run, train_all, test_all, n_epochs, device)
    policy.eval()
    ckpt_dir = run.save(step)
    if cfg.policy.push_to_hub:
        run.push(step)
    return _final_report(run, ds, data, train_all, test_all, step, ckpt_dir, history)


def _fit(
    run: TrainingRun, train_all: dict, test_all: dict | None, n_epochs: int, device
) -> tuple[list[dict[str, float]], int]:
    """The epochs of the run: the loss curve's points (before the first epoch, every ``eval_every_epochs`` and
    after the last) and the extra checkpoints; returns the curve and the step count."""
    cfg, policy, optimizer = run.cfg, run.policy, run.optimizer
    n_train = len(train_all[OBS_STATE])  # training episodes

    def point(epoch: int, step: int, train_mse: float, elapsed: float) -> dict[str, float]:
        lr = optimizer.param_groups[0]["lr"]
        return {
            "epoch": epoch,
            "step": step,
            "train_mse": train_mse,
            "test_mse": _mse(policy, test_all),
            "lr": lr,
            "time_s": elapsed,
        }

    history = [point(0, 0, _mse(policy, train_all), 0.0)]
    gen = torch.Generator().manual_seed(cfg.seed)
    step = 0
    t0 = time.perf_counter()
    pbar = None
    if cfg.progress:  # redrawn twice a second on a terminal, every 15 s into a log (progress.py)
        pbar = log_friendly_tqdm(total=n_epochs, desc=f"{cfg.policy.type} (fast)", unit="epoch")
    policy.train()
    for epoch in range(1, n_epochs + 1):
        perm = torch.randperm(n_train, generator=gen).to(device)
        losses, step = _epoch(run, train_all, perm, step)
        last = epoch == n_epochs
        if last or epoch % cfg.eval_every_epochs == 0:
            history.append(point(epoch, step, float(np.mean(losses)), time.perf_counter() - t0))
            if pbar is not None:
                pbar.set_postfix(
                    train=f"{history[-1]['train_mse']:.4g}", test=f"{history[-1]['test_mse']:.4g}", refresh=False
                )
        if pbar is not None:
            pbar.update(1)
        if cfg.save_every_epochs > 0 and epoch % cfg.save_every_epochs == 0 and not last:
            run.save(step)
            policy.train()
    if pbar is not None:
        pbar.close()
    return history, step
