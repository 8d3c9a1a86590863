"""The recovering planner (``--policy.mode=recovering``): no clock, a learned PICK/PLACE switch.

The paper's clocked planner runs the PICK net on steps 0-4 and the PLACE net on steps 5-9 whatever happens,
so a missed grasp or a dropped object can never be retried. This network instead infers where it is in the
task from what it observes and remembers:

* one trunk over the whole (variable-length) episode: an LSTM whose state is carried across the pick -> place
  switch (``recurrent=True``), or, for the memoryless control, an MLP with about as many parameters as the
  LSTM trunk (a zero-state LSTM would leave its recurrent weights, most of them, unused);
* two action heads (PICK and PLACE behaviour) mixed by a subtask classifier: ``a = (1 - p) a_pick + p a_place``
  with ``p = P(place | history)``; the classifier is trained with cross-entropy on ``phase.subtask`` when the
  batch carries per-frame labels (the fast path, DAgger), and through the action loss alone otherwise;
* an auxiliary phase classifier (``phase.index``, 10 classes) that shapes the trunk's state to track the FSM
  phase; its prediction is exposed for diagnostics, and with ``still_arm_phases`` it says which keyframes keep
  the last arm command where the network would move the arm by more than ``still_arm_tol`` (the FSM's open at
  the place, in the recipe).

The episode ends when the env says so (success or its step budget), not after 10 steps. With
``await_observation`` an observation gate (``observation_gate``) holds a commanded move until the observations
show it. ``planner.Planner`` is the interface it shares with the clocked planner.
"""

from __future__ import annotations

import math
from typing import Any

import torch
import torch.nn.functional as F  # noqa: N812
from lerobot.utils.constants import OBS_STATE
from torch import Tensor, nn

from lerobot_pnp.errors import DatasetError

from .configuration_pnp_lstm import PnpLstmConfig
from .observation_gate import ObservationGate
from .planner import PlannerState, lstm_step

N_PHASES = 10
N_SUBTASKS = 2
# A training batch's LSTM runs as up to this many groups of episodes of similar length, when that skips at least
# a fifth of the padded frames (GROUPING_MIN_SAVING: the grouped frames are at most this share of the padded
# ones); fewer, longer calls make better use of the CPU, so only padding worth skipping is skipped.
LENGTH_GROUPS = 3
GROUPING_MIN_SAVING = 0.8


def _pad_time(h: Tensor, length: int) -> Tensor:
    """``(B, T', H)`` padded with zeros at the end to ``(B, length, H)``."""
    return F.pad(h, (0, 0, 0, length - h.shape[1]))


def lstm_trunk_params(input_dim: int, hidden: int, layers: int = 1) -> int:
    """Parameter count of an LSTM trunk of ``layers`` stacked layers (``nn.LSTM``: two bias vectors each; a
    layer above the first reads the one below, ``hidden`` wide)."""
    return sum(4 * hidden * ((input_dim if k == 0 else hidden) + hidden) + 8 * hidden for k in range(layers))


def matched_mlp_width(input_dim: int, hidden: int, layers: int = 1) -> int:
    """Width ``w`` of a two-layer MLP trunk (``D -> w -> w``) with about the parameter count of the LSTM trunk
    it replaces (``layers`` stacked layers), so the memoryless control differs from it in memory, not size."""
    target = lstm_trunk_params(input_dim, hidden, layers)
    # w^2 + (D + 2) w - target = 0
    b = input_dim + 2
    return max(1, round((-b + math.sqrt(b * b + 4 * target)) / 2))


class RecoveringPlanner(nn.Module):
    """Trunk (LSTM or matched MLP) + PICK/PLACE action heads + subtask and phase classifiers (``planner.Planner``).

    Its weights are ``lstm.*`` (or ``mlp.*``), ``action_heads.*``, ``subtask_head.*`` and ``phase_head.*``
    (``model.`` in a checkpoint); ``num_layers`` stacks LSTM layers (the memoryless MLP is matched to the stacked trunk's size);
    ``shared_network``, ``carry_hidden_across_subtasks`` and the subtask structure fields are not used."""

    def __init__(self, config: PnpLstmConfig, input_dim: int, action_dim: int):
        super().__init__()
        self.config = config
        hidden, recurrent, dropout = config.hidden_size, config.recurrent, config.dropout
        self.recurrent = recurrent
        if recurrent:
            layers = config.num_layers
            self.lstm = nn.LSTM(input_dim, hidden, layers, batch_first=True, dropout=dropout if layers > 1 else 0.0)
            width = hidden
        else:
            width = matched_mlp_width(input_dim, hidden, config.num_layers)
            self.mlp = nn.Sequential(nn.Linear(input_dim, width), nn.Tanh(), nn.Linear(width, width), nn.Tanh())
        self.drop = nn.Dropout(dropout)
        self.action_heads = nn.Linear(width, N_SUBTASKS * action_dim)  # [pick | place]
        self.subtask_head = nn.Linear(width, N_SUBTASKS)
        self.phase_head = nn.Linear(width, N_PHASES)
        self.action_dim = action_dim

    @property
    def per_attempt(self) -> bool:
        """``memory_per_attempt`` on a trunk with memory (an MLP has none to restart); read from the config each
        time, as the gate's settings are, so that a changed config takes effect."""
        return self.recurrent and self.config.memory_per_attempt

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

    def forward(self, x: Tensor, lengths: Tensor | None = None) -> dict[str, Tensor]:
        """Whole episodes ``(B, T, D)`` from frame 0 -> heads ``(B, T, ·)``. Padding at the end is harmless:
        the LSTM is causal, so padded frames never influence the real ones.

        ``lengths`` ``(B,)``: the frames of each episode that matter (up to its last frame in the loss); the
        trunk skips the rest, whose outputs are zeros (``_trunk_by_length``). The frames that matter get the
        same outputs as without it."""
        if lengths is None:
            h = self.lstm(x)[0] if self.recurrent else self.mlp(x)
        else:
            h = self._trunk_by_length(x, lengths)
        return self._heads(h)

    def _trunk_by_length(self, x: Tensor, lengths: Tensor) -> Tensor:
        """The trunk over each episode's first ``lengths`` frames only. Episodes of variable length (the ``full``
        task's recoveries) pad a batch to its longest, about half of it padding: the MLP runs on the frames
        that matter; the LSTM runs on groups of episodes of similar length (``LENGTH_GROUPS``), each only as
        long as its longest, where that skips enough frames to pay for the extra calls (one call otherwise)."""
        bsz, length = x.shape[:2]
        lengths = lengths.clamp(0, length)
        if not self.recurrent:
            keep = torch.arange(length, device=x.device) < lengths[:, None]
            width = self.mlp[-2].out_features
            return x.new_zeros(bsz, length, width).index_put((keep,), self.mlp(x[keep]))
        order = lengths.argsort()
        groups = [g for g in order.tensor_split(min(LENGTH_GROUPS, bsz)) if len(g)]
        longest = [int(lengths[g].max()) for g in groups]
        grouped = sum(n * len(g) for n, g in zip(longest, groups, strict=True))
        if grouped > GROUPING_MIN_SAVING * bsz * max(longest):
            return _pad_time(self.lstm(x[:, : max(1, max(longest))])[0], length)
        parts = [
            _pad_time(self.lstm(x[g, :n])[0], length) if n else x.new_zeros(len(g), length, self.lstm.hidden_size)
            for g, n in zip(groups, longest, strict=True)
        ]
        return torch.cat(parts)[order.argsort()]

    # ---- planner.Planner ------------------------------------------------------------------------

    def loss(
        self, x: Tensor, y: Tensor, valid: Tensor, subtask: Tensor | None, phase: Tensor | None
    ) -> tuple[Tensor, Tensor, dict[str, float]]:
        cfg = self.config
        attempts = None
        if self.per_attempt:
            if subtask is None:
                raise DatasetError(
                    "policy.memory_per_attempt restarts the memory at the phase.subtask labels' switches back to "
                    "pick, and this batch carries none (a dataset without the phase.* columns): train on one "
                    "recorded by `lerobot-pnp generate` or set --policy.memory_per_attempt=false"
                )
            attempts = Attempts(subtask, valid)
            x, y, valid, subtask, phase = (
                None if v is None else attempts.split(v) for v in (x, y, valid, subtask, phase)
            )
        frames = torch.arange(1, valid.shape[1] + 1, device=valid.device)
        lengths = (valid * frames).amax(dim=1)  # up to the last frame in the loss: nothing after it matters
        out = self(x, lengths)
        loss, per_sample, info = recovering_loss(
            out, y, valid, subtask, phase, cfg.subtask_loss_weight, cfg.phase_loss_weight
        )
        if attempts is not None:  # one loss per episode again (LeRobot's per-sample hook): its attempts' frames
            per_sample = attempts.per_episode(per_sample, valid)
        return loss, per_sample, info

    def sequence(self, x: Tensor, subtask: Tensor | None = None) -> Tensor:
        """Teacher-forced actions of whole episodes; with ``memory_per_attempt`` and the ``subtask`` labels, the
        memory restarts at each switch back to pick, as in training (without labels it is carried)."""
        if self.per_attempt and subtask is not None:
            valid = torch.ones(x.shape[:2], dtype=torch.bool, device=x.device)
            attempts = Attempts(subtask, valid)
            return attempts.merge(self(attempts.split(x))["action"])
        return self(x)["action"]

    def act(self, x: Tensor, state: PlannerState | None) -> tuple[Tensor, PlannerState]:
        """One trunk step with the state carried since the reset, until the env ends the episode; with the gate,
        an env whose last move is not observed yet keeps its command and its network state."""
        memory = None if state is None else state.memory
        out, new_memory = self.step(x, memory)
        if self.per_attempt and state is not None and state.subtask_prob is not None:
            back = (state.subtask_prob >= 0.5) & (out["subtask_logits"].argmax(dim=-1) == 0)  # place -> pick
            if bool(back.any()):  # a new attempt: this step again from the zero state, as training restarts it
                fresh, fresh_memory = self.step(x, None)
                out = {k: torch.where(back.view(-1, *[1] * (v.dim() - 1)), fresh[k], v) for k, v in out.items()}
                new_memory = tuple(
                    torch.where(back[None, :, None], f, n) for f, n in zip(fresh_memory, new_memory, strict=True)
                )
        action = out["action"]
        phase = out["phase_logits"].argmax(dim=-1)
        if self.config.still_arm_phases and state is not None:  # keyframes the FSM sends without moving the arm
            still = torch.isin(phase, torch.tensor(self.config.still_arm_phases, device=phase.device))
            still &= (action[:, :-1] - state.action[:, :-1]).norm(dim=-1) > self.config.still_arm_tol
            arm = torch.where(still[:, None], state.action[:, :-1], action[:, :-1])
            action = torch.cat([arm, action[:, -1:]], dim=-1)
        gate = self._new_gate() if state is None else state.gate
        if gate is not None:  # hold the last command where its move has not been observed yet
            decided = gate.decide(x)
            old = None if state is None else state.action
            if old is not None and not bool(decided.all()):
                action = torch.where(decided[:, None], action, old)
                if new_memory is not None:
                    new_memory = tuple(
                        torch.where(decided[:, None], n, o) for n, o in zip(new_memory, memory, strict=True)
                    )
            gate.update(decided, action, old)
        subtask_prob = out["subtask_logits"].softmax(dim=-1)[:, 1]
        if gate is not None and state is not None and state.subtask_prob is not None:
            subtask_prob = torch.where(decided, subtask_prob, state.subtask_prob)  # held with the memory
        return action, PlannerState(
            step=1 if state is None else state.step + 1,
            action=action,
            memory=new_memory,
            gate=gate,
            subtask_prob=subtask_prob,
            phase=phase,
        )

    def check_episode_lengths(self, lengths: list[int]) -> None:
        """Every episode fits a training window: at most ``max_episode_length`` frames."""
        max_length = self.config.max_episode_length
        longer = sorted({int(n) for n in lengths if int(n) > int(max_length)})
        if longer:
            raise DatasetError(
                f"episodes of {longer[:5]} frames do not fit policy.max_episode_length={max_length}: "
                f"raise it to at least {longer[-1]}"
            )

    def _new_gate(self) -> ObservationGate | None:
        """A fresh observation gate for an episode (``await_observation``), else None; read from the config at
        each episode's first step, so that inference-time settings take effect at the next reset."""
        cfg = self.config
        if not cfg.await_observation:
            return None
        return ObservationGate(
            int(cfg.input_features[OBS_STATE].shape[0]),
            cfg.await_state_tol,
            cfg.await_action_tol,
            cfg.await_max_steps,
            cfg.in_flight_moves,
            cfg.await_past_states,
        )

    # ---- the network ----------------------------------------------------------------------------

    def step(self, x: Tensor, state: Any) -> tuple[dict[str, Tensor], Any]:
        """One inference step ``(B, D)``; the LSTM state is carried for the whole episode."""
        if not self.recurrent:
            return self._heads(self.mlp(x)), None
        h, state = lstm_step(self.lstm, x, state)
        return self._heads(h), state


class Attempts:
    """Episodes ``(B, T)`` cut into attempts (``memory_per_attempt``): a new one starts at frame 0 and wherever the
    ``phase.subtask`` labels of the frames in the loss switch from place (1) back to pick (0).

    The frame where the labels go back is the first of the new attempt and also the last of the one it ends: at
    inference the switch is recognised by the old attempt's memory (its classifier says pick) before the step is
    re-run from the zero state, so training must show it there too. ``split`` lays each attempt out as a row of
    its own, ``(A, T_a, ...)`` from its first frame, zero-padded (an attempt with no frame in the loss is left
    out); ``merge`` puts rows back, each frame from the attempt it starts or continues."""

    def __init__(self, subtask: Tensor, valid: Tensor):
        bsz, length = valid.shape
        frames = torch.arange(length, device=valid.device)
        # The label of the last frame in the loss before each frame: the frames out of the loss (a late observer's
        # blind frames, a retimed recovery's repeated first frame) are steps the late robot still spends on the
        # attempt it sees; the new one starts where it can see the event, its first frame in the loss.
        seen = torch.where(valid, frames, torch.full_like(frames, -1)).cummax(dim=1).values
        before = torch.cat([seen.new_full((bsz, 1), -1), seen[:, :-1]], dim=1)
        was_place = (before >= 0) & (subtask.gather(1, before.clamp(min=0)) == 1)
        back = valid & (subtask == 0) & was_place
        back[:, 0] = True
        index = back.long().cumsum(dim=1) - 1  # the attempt of each frame within its episode
        count = index[:, -1] + 1
        self.attempt = index + (count.cumsum(dim=0) - count)[:, None]  # (B, T): a global id
        self.pos = frames - torch.where(back, frames, torch.zeros_like(frames)).cummax(dim=1).values
        starts = back.nonzero()  # (n, 2) in attempt order: episode, first frame
        self.episode, self.start = starts[:, 0], starts[:, 1]
        following = torch.cat([self.start[1:], self.start.new_full((1,), length)])
        same = torch.cat([self.episode[1:] == self.episode[:-1], self.episode.new_zeros(1, dtype=torch.bool)])
        self.length = torch.where(same, following - self.start + 1, length - self.start)  # + the next one's first
        in_loss = self._rows(valid).any(dim=1)
        self.keep = in_loss.nonzero().squeeze(1)

    def _rows(self, v: Tensor) -> Tensor:
        """Every attempt as a row, those without a frame in the loss included."""
        width = int(self.length.max())
        steps = torch.arange(width, device=v.device)
        index = (self.start[:, None] + steps).clamp(max=v.shape[1] - 1)
        out = v[self.episode[:, None], index]
        inside = steps[None, :] < self.length[:, None]
        return out * inside.view(*inside.shape, *[1] * (v.dim() - 2)).to(out.dtype)

    def split(self, v: Tensor) -> Tensor:
        """``(B, T, ...)`` -> ``(A, T_a, ...)``."""
        return self._rows(v)[self.keep]

    def merge(self, v: Tensor) -> Tensor:
        """``(A, T_a, ...)`` (from ``split``) -> ``(B, T, ...)``; frames of an attempt left out are zeros."""
        full = v.new_zeros((len(self.episode), *v.shape[1:]))
        full[self.keep] = v
        return full[self.attempt, self.pos]

    def per_episode(self, per_attempt: Tensor, valid: Tensor) -> Tensor:
        """An attempt's mean loss over its frames in the loss -> its episode's, weighted by those frames."""
        weight = valid.sum(dim=1).to(per_attempt.dtype)
        episode = self.episode[self.keep]
        bsz = self.attempt.shape[0]
        total = per_attempt.new_zeros(bsz).index_add(0, episode, per_attempt * weight)
        frames = per_attempt.new_zeros(bsz).index_add(0, episode, weight)
        return total / frames.clamp(min=1.0)


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
