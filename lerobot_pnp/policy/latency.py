"""Training-time latency augmentation: whole episodes as an observer some steps late sees them.

The env's observation latency (``obs_latency``, ``obs_latency_jitter``) shows the policy a past state. A planner
trained on current observations only loses sync with its own history when they arrive late; ``late_observer``
shows some training episodes late, as the env draws it (``latency_augment_*`` in the config). ``PnpLstmPolicy``
applies it to every planner's batches, before the input noise.
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor


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


def latency_rules(c: Any) -> list[tuple[bool, str]]:
    """The rules of the config's ``latency_augment_*`` options: (condition, the one-line message naming the option
    and its value)."""
    return [
        (
            0.0 <= c.latency_augment_prob <= 1.0,
            f"latency_augment_prob must be in [0, 1], got {c.latency_augment_prob}",
        ),
        (
            c.latency_augment_max >= 1 and 0.0 <= c.latency_augment_jitter <= 1.0,
            f"latency_augment_max must be >= 1 and latency_augment_jitter in [0, 1], got "
            f"{c.latency_augment_max} and {c.latency_augment_jitter}",
        ),
    ]
