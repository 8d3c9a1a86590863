"""What the fast path reports besides checkpoints: held-out keyframe error and the loss curve (paper Fig. 4)."""

from __future__ import annotations

import csv
import io
import math
from typing import Any

import torch
from lerobot.utils.constants import ACTION

from lerobot_pnp import robot
from lerobot_pnp.outputs import OutputFolder
from lerobot_pnp.policy import PnpLstmPolicy


def action_names(meta: Any) -> list[str]:
    """The action's joint names from the dataset metadata (the robot's, if the dataset has none)."""
    names = meta.features[ACTION].get("names")
    if isinstance(names, dict):  # {"motors": [...]}
        names = next(iter(names.values()), None)
    if not names or len(names) != robot.ACTION_DIM:
        names = list(robot.ACTION_NAMES)
    return [str(n) for n in names]


CHUNK_EPISODES = 256  # episodes per forward pass over a whole split (its loss, its keyframe error)


@torch.no_grad()
def keyframe_error(
    policy: PnpLstmPolicy,
    postprocessor: Any,
    norm_batch: dict[str, torch.Tensor],
    raw_action: torch.Tensor,
    names: list[str],
    pad: torch.Tensor | None = None,
) -> dict[str, Any]:
    """Held-out error of the predicted next keyframe (teacher forcing: dataset states as inputs).

    ``pad`` ``(E, T)``: padded frames of variable-length episodes, left out of every statistic."""
    policy.eval()
    n = len(raw_action)
    parts = [  # a few episodes at a time: a camera split's activations at once are many GB
        policy.predict_sequence({k: v[i : i + CHUNK_EPISODES] for k, v in norm_batch.items()})
        for i in range(0, n, CHUNK_EPISODES)
    ]
    pred = postprocessor(torch.cat(parts)).to(torch.float32).cpu()
    err = pred - raw_action.cpu()
    n_episodes = int(raw_action.shape[0])
    if pad is not None:
        err = err[~pad.cpu()].unsqueeze(1)  # (frames, 1, A): the real frames only
    nj = robot.N_JOINTS
    deg = err[..., :nj].abs() * (180.0 / math.pi)  # (E, T, 7)
    rmse = (err[..., :nj].pow(2).mean(dim=(0, 1)).sqrt()) * (180.0 / math.pi)
    gripper = err[..., nj:].abs()
    out: dict[str, Any] = {
        "n_episodes": n_episodes,
        "mean_joint_mae_deg": float(deg.mean()),
        "per_joint_mae_deg": {names[j]: float(deg[..., j].mean()) for j in range(nj)},
        "per_joint_rmse_deg": {names[j]: float(rmse[j]) for j in range(nj)},
        "per_joint_max_deg": {names[j]: float(deg[..., j].max()) for j in range(nj)},
        "per_keyframe_mean_joint_mae_deg": {
            robot.PHASE_NAMES[k]: float(deg[:, k].mean()) for k in range(min(deg.shape[1], robot.N_KEYFRAMES))
        }
        if pad is None
        else None,
        "gripper_mae": float(gripper.mean()) if gripper.numel() else None,
        "note": "input at keyframe k = dataset state k; target = keyframe k+1 joint targets (action k)",
    }
    return out


def write_curve(history: list[dict[str, float]], folder: OutputFolder) -> None:
    """``loss_curve.csv`` and ``loss_curve.png`` (train vs held-out MSE per epoch), written together."""
    text = io.StringIO()
    w = csv.DictWriter(text, fieldnames=list(history[0].keys()), lineterminator="\r\n")
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
    png = io.BytesIO()
    fig.savefig(png, format="png", dpi=120)
    plt.close(fig)
    folder.write_set({"loss_curve.csv": text.getvalue().encode(), "loss_curve.png": png.getvalue()})
