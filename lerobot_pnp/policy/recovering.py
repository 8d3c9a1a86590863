"""The recovering planner network (``--policy.mode=recovering``): no clock, a learned PICK/PLACE switch.

The paper's clocked planner runs the PICK net on steps 0-4 and the PLACE net on steps 5-9 whatever happens,
so a missed grasp or a dropped object can never be retried. This network instead infers where it is in the
task from what it observes and remembers:

* one trunk over the whole (variable-length) episode: an LSTM whose state is carried across the pick -> place
  switch (``recurrent=True``), or, for the memoryless control, an MLP with about as many parameters as the
  LSTM trunk (a zero-state LSTM would leave its recurrent weights, ~90 % of them, unused);
* two action heads (PICK and PLACE behaviour) mixed by a subtask classifier: ``a = (1 - p) a_pick + p a_place``
  with ``p = P(place | history)``; the classifier is trained with cross-entropy on ``phase.subtask`` when the
  batch carries per-frame labels (the fast path, DAgger), and through the action loss alone otherwise;
* an auxiliary phase classifier (``phase.index``, 10 classes) that shapes the trunk's state to track the FSM
  phase; its prediction is exposed for diagnostics, never used to act.

The episode ends when the env says so (success or its step budget), not after 10 steps.
"""

from __future__ import annotations

import math
from typing import Any

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn

N_PHASES = 10
N_SUBTASKS = 2


def lstm_trunk_params(input_dim: int, hidden: int) -> int:
    """Parameter count of a one-layer LSTM trunk (``nn.LSTM``: two bias vectors)."""
    return 4 * hidden * (input_dim + hidden) + 8 * hidden


def matched_mlp_width(input_dim: int, hidden: int) -> int:
    """Width ``w`` of a two-layer MLP trunk (``D -> w -> w``) with about the LSTM trunk's parameter count."""
    target = lstm_trunk_params(input_dim, hidden)
    # w^2 + (D + 2) w - target = 0
    b = input_dim + 2
    return max(1, round((-b + math.sqrt(b * b + 4 * target)) / 2))


class RecoveringNet(nn.Module):
    """Trunk (LSTM or matched MLP) + PICK/PLACE action heads + subtask and phase classifiers."""

    def __init__(self, input_dim: int, hidden: int, action_dim: int, recurrent: bool = True, dropout: float = 0.0):
        super().__init__()
        self.recurrent = recurrent
        if recurrent:
            self.lstm = nn.LSTM(input_dim, hidden, num_layers=1, batch_first=True)
            width = hidden
        else:
            width = matched_mlp_width(input_dim, hidden)
            self.mlp = nn.Sequential(nn.Linear(input_dim, width), nn.Tanh(), nn.Linear(width, width), nn.Tanh())
        self.drop = nn.Dropout(dropout)
        self.action_heads = nn.Linear(width, N_SUBTASKS * action_dim)  # [pick | place]
        self.subtask_head = nn.Linear(width, N_SUBTASKS)
        self.phase_head = nn.Linear(width, N_PHASES)
        self.action_dim = action_dim

    def trunk_parameters(self) -> int:
        module = self.lstm if self.recurrent else self.mlp
        return sum(p.numel() for p in module.parameters())

    def _heads(self, h: Tensor) -> dict[str, Tensor]:
        h = self.drop(h)
        actions = self.action_heads(h).unflatten(-1, (N_SUBTASKS, self.action_dim))
        subtask_logits = self.subtask_head(h)
        p = subtask_logits.softmax(dim=-1)
        action = (p.unsqueeze(-1) * actions).sum(dim=-2)
        return {"action": action, "subtask_logits": subtask_logits, "phase_logits": self.phase_head(h)}

    def forward(self, x: Tensor) -> dict[str, Tensor]:
        """Whole episodes ``(B, T, D)`` from frame 0 -> heads ``(B, T, ·)``. Padding at the end is harmless:
        the LSTM is causal, so padded frames never influence the real ones."""
        h = self.lstm(x)[0] if self.recurrent else self.mlp(x)
        return self._heads(h)

    def step(self, x: Tensor, state: Any) -> tuple[dict[str, Tensor], Any]:
        """One inference step ``(B, D)``; the LSTM state is carried for the whole episode."""
        if not self.recurrent:
            return self._heads(self.mlp(x)), None
        lstm = self.lstm
        if state is None:
            zeros = x.new_zeros(x.shape[0], lstm.hidden_size)
            state = (zeros, zeros)
        h, c = torch.lstm_cell(x, state, lstm.weight_ih_l0, lstm.weight_hh_l0, lstm.bias_ih_l0, lstm.bias_hh_l0)
        return self._heads(h), (h, c)


def recovering_loss(
    out: dict[str, Tensor],
    target: Tensor,
    valid: Tensor,
    subtask: Tensor | None,
    phase: Tensor | None,
    subtask_weight: float,
    phase_weight: float,
) -> tuple[Tensor, Tensor, dict[str, float]]:
    """(mean loss, per-sample loss, info): action MSE + weighted cross-entropies over the valid frames."""
    validf = valid.to(target.dtype)
    n_valid = validf.sum(dim=1).clamp(min=1.0)
    err = F.mse_loss(out["action"], target, reduction="none").mean(dim=-1)  # (B, T)
    per_sample = (err * validf).sum(dim=1) / n_valid
    info: dict[str, float] = {"mse_action": float((err.detach() * validf).sum() / validf.sum().clamp(min=1.0))}
    for name, labels, logits, weight in (
        ("subtask", subtask, out["subtask_logits"], subtask_weight),
        ("phase", phase, out["phase_logits"], phase_weight),
    ):
        if labels is None or weight <= 0:
            continue
        ce = F.cross_entropy(logits.flatten(0, 1), labels.flatten().long(), reduction="none").view_as(err)
        per_sample = per_sample + weight * (ce * validf).sum(dim=1) / n_valid
        with torch.no_grad():
            acc = ((logits.argmax(dim=-1) == labels).to(validf.dtype) * validf).sum() / validf.sum().clamp(min=1.0)
        info[f"ce_{name}"] = float((ce.detach() * validf).sum() / validf.sum().clamp(min=1.0))
        info[f"acc_{name}"] = float(acc)
    weights = n_valid / n_valid.sum()
    return (per_sample * weights).sum(), per_sample, info


def late_observer(
    x: Tensor,
    valid: Tensor,
    prob: float,
    phase: Tensor | None = None,
    max_lag: int = 1,
    jitter: float = 0.0,
    stretch: bool = False,
) -> tuple[Tensor, Tensor, Tensor]:
    """Whole episodes ``(B, T, D)`` as an observer ``lag`` steps late sees them (the env's latency model: frame
    ``t`` shows the state of frame ``max(0, t - lag)``), each episode late with probability ``prob``.

    A late episode's lag is drawn uniformly in ``1..max_lag``, then redrawn in ``0..max_lag`` at each frame with
    probability ``jitter`` (the env's ``obs_latency_jitter``). Returns ``(x, valid, src)``: the inputs, the
    frames left in the loss, and ``src`` ``(B, T')``, the original frame whose action (and labels) each new frame
    is trained on. Out of the loss: the last real frame of a late episode (the hold after success, never
    executed) and, given the per-frame ``phase`` labels, every frame whose observation predates the start of a
    recovery (the phase goes back: the expert reacts to an event the late observer cannot see yet).

    ``stretch``: the demonstration is made consistent with what a late robot does. The expert reacts to a
    drop or a displacement at once; a robot that sees it ``lag`` steps late has by then commanded ``lag`` more
    steps of its old plan, and only then starts the recovery. So the first frame of each recovery is repeated
    ``lag`` times (its copies out of the loss), and the recovery's labels follow the late robot's timeline
    instead of the expert's, which is one step ahead: without it, a late observer is taught to skip the first
    recovery step (re-approaching the object) it has not yet commanded.
    """
    bsz, length = x.shape[:2]
    frames = torch.arange(length, device=x.device).expand(bsz, length)
    late = torch.rand(bsz, device=x.device) < prob
    if not bool(late.any()) or length < 2:
        return x, valid, frames
    lag_ep = torch.ones(bsz, dtype=torch.long, device=x.device)
    if max_lag > 1:
        lag_ep = torch.randint(1, max_lag + 1, (bsz,), device=x.device)
    lag_ep = lag_ep * late
    event = torch.zeros_like(valid)
    if phase is not None:
        event[:, 1:] = (phase[:, 1:] < phase[:, :-1]) & valid[:, 1:]
    pos = frames + (lag_ep.unsqueeze(1) * event.long().cumsum(dim=1) if stretch else 0)  # where frame i goes
    n_real = valid.sum(dim=1).clamp(min=1)
    new_len = pos.gather(1, (n_real - 1).unsqueeze(1)).squeeze(1) + 1
    j = torch.arange(int(new_len.max()), device=x.device).expand(bsz, -1)
    src = torch.searchsorted(pos.contiguous(), j.contiguous()).clamp(max=length - 1)  # new frame -> original
    copy = pos.gather(1, src) != j  # a repeated first frame of a recovery
    lag = lag_ep.unsqueeze(1).expand_as(j)
    if jitter > 0:
        redraw = (torch.rand(j.shape, device=x.device) < jitter) & late.unsqueeze(1)
        values = torch.randint(0, max_lag + 1, j.shape, device=x.device)
        last = torch.where(redraw, j, torch.full_like(j, -1)).cummax(dim=1).values
        lag = torch.where(last >= 0, values.gather(1, last.clamp(min=0)), lag)
    seen = (j - lag).clamp(min=0)  # the new frame whose state is observed
    x_new = x.gather(1, src.gather(1, seen).unsqueeze(-1).expand(-1, -1, x.shape[-1]))
    starts = event.gather(1, src) & ~copy
    starts_at = torch.where(starts, j - (lag_ep.unsqueeze(1) if stretch else 0), torch.full_like(j, -1))
    blind = seen < starts_at.cummax(dim=1).values
    blind |= (j == (new_len - 1).unsqueeze(1)) & (lag > 0)
    valid_new = valid.gather(1, src) & (j < new_len.unsqueeze(1)) & ~copy & ~blind
    return x_new, valid_new, src
