"""LeRobot's ACT (``lerobot.policies.act``) as a method of the study: state-only, trained on dense demonstrations.

ACT predicts a chunk of joint targets at the control rate, so it is trained on the *dense* recording of the
same demonstrations as the keyframe dataset (same dataset seed and episode count: the same object positions,
the same 80/20 split) and evaluated in dense control mode on the same evaluation seeds as every other method.

Why not ``lerobot-train`` itself: its ``LeRobotDataset`` reads each sample's 20-step action chunk through the
HF dataset at ~7 ms per sample on this machine, so a batch of 64 costs ~0.45 s of loading and a budget of a few
thousand steps would take ~15-20 min per seed on 2 shared cores. The loop here reads the parquet columns once,
normalises them with the pre-processor ``lerobot-train`` would build (``make_pre_post_processors`` with the
dataset's stats), gathers chunks with LeRobot's padding rule (indices past the episode end repeat the last
frame and are flagged in ``action_is_pad``, which ACT's loss masks), and otherwise does what a
``lerobot-train`` step does: the same ``ACTPolicy.forward`` loss, ACT's AdamW preset (weight decay 1e-4,
gradient clipping at 10) with the peak learning rate of ``ActBudget`` under LeRobot's cosine schedule, and
LeRobot's ``save_checkpoint`` in ``lerobot-train``'s layout (``lerobot-eval --policy.path=.../pretrained_model``
loads it). Everything else (model, processors, inference with its action queue, evaluation through
``eval_policy``) is stock LeRobot.

On a task with perturbations (``full``) the dense recording draws the same episodes: the start, the events'
counts and moments within their windows and the latency are drawn at reset, before any step, so they are
the same in both control modes; what an event draws when it fires (a drop's landing point, a nudge's push)
comes after a different number of per-step observation-noise draws, so it is another draw from the same
distribution. The nudge is timed by an env step (``nudge_at_step``), so the recording pushes the object at
dense step 1, after the expert planned its first keyframe: the arm still goes to the hover point above where
the object was and corrects at the descent, the states that follow the evaluation's nudge (``dense_env``).

Tuning, measured on seed 1000 with 3000 steps x batch 64 (nominal success over 100 evaluation episodes):
constant lr 3e-4 with dropout 0.1: 32 % (of 200); peak lr 1e-3 with cosine decay and dropout 0.1: 59 %; the
same with dropout 0: 99 %. Dense joint targets move ~0.01 rad a step, so the regression must be precise to a
few hundredths of a standard deviation: dropout noise and an undecayed learning rate both cost grasps.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from lerobot_pnp.dataset.splits import recorded_split
from lerobot_pnp.errors import DatasetError
from lerobot_pnp.integration.recorded_task import copy_recorded
from lerobot_pnp.support.determinism import deterministic_training

# ACT sized to the task: an expert dense episode is ~140-160 steps (7-8 s at 20 fps) with a keyframe reached
# every ~15-20 steps. A 20-step chunk (1 s) spans about one keyframe; executing 10 of them re-plans every
# 0.5 s (closed loop at 2 Hz). The inputs are 8 + 3 numbers (+ 4 on ``full``: yaw and goal), so a 2-layer
# encoder of width 128 is ample
# (0.67 M parameters; LeRobot's default, 512 wide with 4 encoder layers, a VAE and a ResNet-18, has ~50 M
# and is built for images). No VAE: the expert is deterministic given the state (no multi-modal
# demonstrations to capture); ACT without it is the plain chunked transformer regressor (latent fixed at 0).
ACT_OVERRIDES: dict = {
    "chunk_size": 20,
    "n_action_steps": 10,
    "dim_model": 128,
    "n_heads": 4,
    "dim_feedforward": 512,
    "n_encoder_layers": 2,
    "n_decoder_layers": 1,
    "use_vae": False,
    "dropout": 0.0,  # 200 k frames of a deterministic expert: precision matters more than regularisation
    "pretrained_backbone_weights": None,  # no images: nothing to download
}


@dataclass
class ActBudget:
    """The training budget of one seed (stated in the method's description and the report)."""

    steps: int = 3000
    batch_size: int = 64
    lr: float = 1e-3  # peak; ACT's preset 1e-5 is for a ResNet-backed model at batch 8; this model is small
    warmup_steps: int = 100  # then cosine decay to lr / 100 (LeRobot's CosineDecayWithWarmupSchedulerConfig)
    overrides: dict = field(default_factory=dict)  # extra ACTConfig fields (on top of ACT_OVERRIDES)

    def describe(self) -> str:
        return f"{self.steps} steps x batch {self.batch_size}, AdamW peak lr {self.lr:g} with cosine decay"

    def identity(self) -> dict:
        """What makes two trainings the same (a finished one is reused only if this matches)."""
        return {**asdict(self), "overrides": {**ACT_OVERRIDES, **self.overrides}}

    def scheduler(self):
        from lerobot.optim.schedulers import CosineDecayWithWarmupSchedulerConfig

        return CosineDecayWithWarmupSchedulerConfig(self.warmup_steps, self.steps, self.lr, self.lr / 100)


@dataclass
class _Frames:
    """Per-frame columns of a dense dataset, sorted by episode then frame."""

    state: np.ndarray  # (N, 8)
    env_state: np.ndarray  # (N, D)
    action: np.ndarray  # (N, 8)
    episode: np.ndarray  # (N,)
    episode_end: np.ndarray  # (N,) index of the last frame of each frame's episode (exclusive end - 1)


def _read_frames(dataset_root: Path, episodes: range) -> _Frames:
    from lerobot_pnp.report.adapters import read_frames

    cols = read_frames(dataset_root, ["observation.state", "observation.environment_state", "action"])
    keep = np.isin(cols["episode_index"], episodes)
    ep = cols["episode_index"][keep]
    if not len(ep):
        raise DatasetError(f"{dataset_root}: none of the episodes {list(episodes[:5])}... are in the data")
    state, env_state, action = (
        cols[n][keep].astype(np.float32) for n in ("observation.state", "observation.environment_state", "action")
    )
    ends = np.searchsorted(ep, ep, side="right") - 1
    return _Frames(state, env_state, action, ep, ends)


class _ChunkBatches:
    """Normalised frames and the gather of ``(B, chunk)`` action windows with LeRobot's end-of-episode padding."""

    def __init__(self, frames: _Frames, preprocessor, chunk: int):
        from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE

        norm = preprocessor(
            {
                OBS_STATE: torch.from_numpy(frames.state),
                OBS_ENV_STATE: torch.from_numpy(frames.env_state),
                ACTION: torch.from_numpy(frames.action),
            }
        )
        self.state, self.env_state, self.action = (norm[k].float() for k in (OBS_STATE, OBS_ENV_STATE, ACTION))
        self.end = torch.from_numpy(frames.episode_end)
        self.offsets = torch.arange(chunk)
        self.n = len(frames.episode)
        self.keys = (OBS_STATE, OBS_ENV_STATE, ACTION)

    def batch(self, rows: torch.Tensor) -> dict[str, torch.Tensor]:
        idx = rows[:, None] + self.offsets[None, :]
        pad = idx > self.end[rows][:, None]
        idx = torch.minimum(idx, self.end[rows][:, None])
        s, e, a = self.keys
        return {s: self.state[rows], e: self.env_state[rows], a: self.action[idx], "action_is_pad": pad}


@torch.no_grad()
def _held_out_l1(policy, data: _ChunkBatches, n_max: int = 4096, batch: int = 512) -> float:
    policy.eval()
    rows = torch.linspace(0, data.n - 1, min(n_max, data.n)).long()
    losses = [float(policy.forward(data.batch(rows[i : i + batch]))[0]) for i in range(0, len(rows), batch)]
    policy.train()
    return float(np.mean(losses))


def _fit(policy, train: _ChunkBatches, budget: ActBudget, seed: int, opt_cfg):
    """``budget.steps`` optimiser steps on random frames of ``train``; returns (optimizer, scheduler config,
    scheduler, per-step losses, loop seconds), what the checkpoint saves. Leaves the policy in eval mode."""
    from tqdm.auto import tqdm

    optimizer = opt_cfg.build(policy.get_optim_params())
    sched_cfg = budget.scheduler()
    scheduler = sched_cfg.build(optimizer, budget.steps)
    gen = torch.Generator().manual_seed(seed)
    policy.train()
    losses: list[float] = []
    t_loop = time.perf_counter()
    for _ in tqdm(range(budget.steps), desc=f"ACT seed {seed}", unit="step", mininterval=10):
        rows = torch.randint(0, train.n, (budget.batch_size,), generator=gen)
        loss, _ = policy.forward(train.batch(rows))
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        if opt_cfg.grad_clip_norm:
            torch.nn.utils.clip_grad_norm_(policy.parameters(), opt_cfg.grad_clip_norm)
        optimizer.step()
        scheduler.step()
        losses.append(float(loss.detach()))
    loop_s = time.perf_counter() - t_loop
    policy.eval()
    return optimizer, sched_cfg, scheduler, losses, loop_s


def train_act(dataset_root: Path, output_dir: Path, seed: int, budget: ActBudget, n_demos: int | None = None) -> Path:
    """Train ACT on the training split of the dense dataset; returns the ``pretrained_model`` folder.

    Writes ``act_train.json`` (budget, wall time, train/held-out L1 on normalised actions) next to the
    checkpoints. ``n_demos`` keeps the first ``n_demos`` training episodes. The training runs seeded, on the
    trainers' fixed thread count and torch's deterministic algorithms (``deterministic_training``): the same
    seed and data give the same weights whatever thread count the caller runs with.
    """
    with deterministic_training(seed):
        return _train_act(dataset_root, output_dir, seed, budget, n_demos)


def _train_act(dataset_root: Path, output_dir: Path, seed: int, budget: ActBudget, n_demos: int | None) -> Path:
    from lerobot.common.train_utils import get_step_checkpoint_dir, save_checkpoint, update_last_checkpoint
    from lerobot.configs.default import DatasetConfig
    from lerobot.configs.train import TrainPipelineConfig
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.factory import make_policy, make_pre_post_processors

    t0 = time.perf_counter()
    repo_id = f"local/{dataset_root.name}"
    meta = LeRobotDatasetMetadata(repo_id, root=dataset_root)
    train_eps = recorded_split(dataset_root, "train")[:n_demos]
    test_eps = recorded_split(dataset_root, "test")

    policy_cfg = ACTConfig(**{**ACT_OVERRIDES, **budget.overrides}, device="cpu", push_to_hub=False)
    policy_cfg.optimizer_lr = budget.lr
    policy = make_policy(policy_cfg, ds_meta=meta)
    preprocessor, postprocessor = make_pre_post_processors(policy_cfg, dataset_stats=meta.stats)
    train = _ChunkBatches(_read_frames(dataset_root, train_eps), preprocessor, policy_cfg.chunk_size)
    test = _ChunkBatches(_read_frames(dataset_root, test_eps), preprocessor, policy_cfg.chunk_size)

    opt_cfg = policy_cfg.get_optimizer_preset()
    optimizer, sched_cfg, scheduler, losses, loop_s = _fit(policy, train, budget, seed, opt_cfg)

    train_cfg = TrainPipelineConfig(
        dataset=DatasetConfig(repo_id=repo_id, root=str(dataset_root), episodes=list(train_eps)),
        policy=policy.config,
        output_dir=output_dir,
        job_name="act_dense",
        seed=seed,
        num_workers=0,
        batch_size=budget.batch_size,
        steps=budget.steps,
        env_eval_freq=0,
        save_freq=budget.steps,
        optimizer=opt_cfg,
        scheduler=sched_cfg,
        use_policy_training_preset=False,
    )
    ckpt = get_step_checkpoint_dir(output_dir, budget.steps, budget.steps)
    save_checkpoint(ckpt, budget.steps, train_cfg, policy, optimizer, scheduler, preprocessor, postprocessor)
    # the dense task travels with the checkpoint (lerobot-eval --policy.path picks it up)
    copy_recorded(dataset_root, ckpt / "pretrained_model")
    update_last_checkpoint(ckpt)
    tail = losses[-max(1, len(losses) // 10) :]
    summary = {
        "budget": budget.describe(),
        "identity": budget.identity(),
        "steps": budget.steps,
        "batch_size": budget.batch_size,
        "lr": budget.lr,
        "policy": {k: getattr(policy.config, k) for k in ACT_OVERRIDES},
        "parameters": sum(p.numel() for p in policy.parameters()),
        "train_episodes": len(train_eps),
        "train_frames": train.n,
        "train_l1_last10pc": float(np.mean(tail)),
        "held_out_l1": _held_out_l1(policy, test),
        "loop_s": loop_s,
        "wall_s": time.perf_counter() - t0,
        "checkpoint": str(ckpt / "pretrained_model"),
    }
    (output_dir / "act_train.json").write_text(json.dumps(summary, indent=1))
    return ckpt / "pretrained_model"


_NUDGE_STEP: dict[str, int] = {}


def dense_nudge_step(dataset_root: Path) -> int:
    """The dense step at which the expert has reached its first keyframe (median over the training split).

    The nudge suites push the object "after the first keyframe, before the grasp": in keyframe mode that is
    env step 1; in dense mode step 1 is 50 ms after the reset (the arm has not moved, so a nudge there is only
    a different start). The dense equivalent is the step the first keyframe is reached, read from the
    demonstrations' ``phase.index`` (first frame of phase 1).
    """
    from lerobot_pnp.report.adapters import read_frames

    key = str(Path(dataset_root).resolve())
    if key not in _NUDGE_STEP:
        cols = read_frames(Path(dataset_root), ["phase.index"])
        ep, frame = cols["episode_index"], cols["frame_index"]
        phase = cols["phase.index"].reshape(len(ep))
        rows = np.isin(ep, recorded_split(dataset_root, "train")) & (phase >= 1)
        ep, frame = ep[rows], frame[rows]
        _, first = np.unique(ep, return_index=True)  # each episode's first frame in phase >= 1 (rows sorted)
        if not len(first):
            raise DatasetError(f"{dataset_root}: no training frame reaches phase 1")
        _NUDGE_STEP[key] = int(np.median(frame[first]))
    return _NUDGE_STEP[key]


def dense_env(env_cfg, dense_root: Path | None):
    """A suite's env config (the keyframe task with the suite's changes) in dense control mode.

    fps and episode length become the dense defaults (20 fps, 1 s per keyframe of the suite's budget: 200
    steps for the paper's 10 keyframes, 800 for the full task's 40). A nudge fires when the expert would have
    reached its first keyframe (``dense_nudge_step``). Observation latency counts env steps (50 ms here, one
    whole keyframe move in keyframe mode): the latency suites are not comparable across control modes.
    """
    changes: dict = {"control_mode": "dense"}
    if env_cfg.nudge_max > 0 and env_cfg.nudge_at_step == 1:
        if dense_root is None:
            raise DatasetError("a dense nudge suite needs the dense dataset to time the nudge")
        changes["nudge_at_step"] = dense_nudge_step(dense_root)
    return env_cfg.with_changes(**changes)
