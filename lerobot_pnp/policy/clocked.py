"""The paper's clocked planner (``--policy.mode=clocked``, the default): two LSTMs on a fixed clock.

The PICK net maps keyframes 0..4 to the next keyframe, the PLACE net, from a zero hidden state, keyframes
5..9 (de Magistris et al. 2016); ``shared_network`` makes it one LSTM told the subtask (one-hot). At inference
the clock is the step count since the reset: steps ``0..4`` run the PICK net, ``5..9`` the PLACE net (its hidden
state zeroed at step 5); afterwards the planner keeps returning the last action it predicted (the hold of the
place-retract state). ``recovering.py`` is the unclocked planner; ``planner.Planner`` is the interface of both.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from typing import Any

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn

from lerobot_pnp.errors import DatasetError

from .configuration_pnp_lstm import PnpLstmConfig
from .planner import PlannerState, lstm_step

logger = logging.getLogger(__name__)


class SubtaskLSTM(nn.Module):
    """One subtask network: LSTM (batch first) followed by a Linear head on every step's output."""

    def __init__(self, input_dim: int, hidden_size: int, num_layers: int, dropout: float, output_dim: int):
        super().__init__()
        self.lstm = nn.LSTM(
            input_size=input_dim,
            hidden_size=hidden_size,
            num_layers=num_layers,
            batch_first=True,
            dropout=dropout if num_layers > 1 else 0.0,
        )
        self.dropout = nn.Dropout(dropout)
        self.head = nn.Linear(hidden_size, output_dim)

    def forward(self, x: Tensor, state: tuple[Tensor, Tensor] | None = None) -> tuple[Tensor, tuple[Tensor, Tensor]]:
        out, state = self.lstm(x, state)
        return self.head(self.dropout(out)), state

    def step(self, x: Tensor, state: tuple[Tensor, Tensor] | None) -> tuple[Tensor, tuple[Tensor, Tensor]]:
        """One time step ``(B, D) -> (B, A)`` in eval mode (``planner.lstm_step``)."""
        h, state = lstm_step(self.lstm, x, state)
        return self.head(h), state


class ClockedPlanner(nn.Module):
    """One ``SubtaskLSTM`` per subtask, or one shared net told the subtask (one-hot), on the clock (``planner.Planner``).

    Its weights are ``subtask_nets.*`` (``model.subtask_nets.*`` in a checkpoint)."""

    def __init__(self, config: PnpLstmConfig, input_dim: int, action_dim: int):
        super().__init__()
        self.config = config
        extra = config.n_subtasks if config.shared_network else 0
        n_nets = 1 if config.shared_network else config.n_subtasks
        self.subtask_nets = nn.ModuleList(
            SubtaskLSTM(input_dim + extra, config.hidden_size, config.num_layers, config.dropout, action_dim)
            for _ in range(n_nets)
        )

    def forward(self, x: Tensor) -> Tensor:
        """Predict ``(B, T, A)`` from inputs ``(B, T, D)`` whose position ``k`` is episode frame ``k``."""
        s = self.config.steps_per_subtask
        outs: list[Tensor] = []
        state = None
        for sub in range(self.config.n_subtasks):
            seg = x[:, sub * s : (sub + 1) * s]
            if seg.shape[1] == 0:
                break
            if not self.config.carry_hidden_across_subtasks:
                state = None
            y, state = self._run(sub, seg, state)
            outs.append(y)
        return torch.cat(outs, dim=1)

    # ---- planner.Planner ------------------------------------------------------------------------

    def loss(
        self, x: Tensor, y: Tensor, valid: Tensor, subtask: Tensor | None, phase: Tensor | None
    ) -> tuple[Tensor, Tensor, dict[str, float]]:
        """MSE over each episode's real frames, and its value per subtask (``mse_pick`` / ``mse_place``) to log;
        the clock tells the subtask, so the labels are not used."""
        err = F.mse_loss(self(x), y, reduction="none").mean(dim=-1)  # (B, T)
        validf = valid.to(err.dtype)
        per_sample = (err * validf).sum(dim=1) / validf.sum(dim=1).clamp(min=1.0)
        loss = (err * validf).sum() / validf.sum().clamp(min=1.0)
        info: dict[str, float] = {}
        with torch.no_grad():
            s = self.config.steps_per_subtask
            for sub, name in enumerate(_subtask_names(self.config.n_subtasks)):
                m = validf[:, sub * s : (sub + 1) * s]
                if m.numel() and float(m.sum()) > 0:
                    info[f"mse_{name}"] = float((err[:, sub * s : (sub + 1) * s] * m).sum() / m.sum())
        return loss, per_sample, info

    def sequence(self, x: Tensor) -> Tensor:
        return self(x)

    def act(self, x: Tensor, state: PlannerState | None) -> tuple[Tensor, PlannerState]:
        """The step of the clock's subtask net; after the last keyframe, the last action again (the same tensor)."""
        cfg = self.config
        step = 0 if state is None else state.step
        if state is not None and step >= cfg.clock_frames:
            if step == 4 * cfg.clock_frames:
                _warn_long_episode(cfg, step)
            return state.action, replace(state, step=step + 1)
        subtask, k = divmod(step, cfg.steps_per_subtask)
        memory = None if state is None else state.memory
        if k == 0 and not (cfg.carry_hidden_across_subtasks and subtask > 0):
            memory = None  # entering a subtask: its net starts from a zero hidden state (the paper)
        action, memory = self.step(x, subtask, memory)
        return action, PlannerState(step + 1, action, memory)

    def check_episode_lengths(self, lengths: list[int]) -> None:
        """Every episode has exactly ``clock_frames`` frames (one per FSM state)."""
        frames = self.config.clock_frames
        bad = sorted({int(n) for n in lengths if int(n) != frames})
        if bad:
            raise DatasetError(
                f"not a keyframe dataset: pnp_lstm needs every episode to have exactly {frames} frames "
                f"(one per FSM state), found episode lengths {bad[:10]}; a dataset with recoveries (the `full` task) "
                "trains with --policy.mode=recovering"
            )

    # ---- the network ----------------------------------------------------------------------------

    def step(self, x: Tensor, subtask: int, state: tuple[Tensor, Tensor] | None) -> tuple[Tensor, Any]:
        """One inference step of ``subtask``'s net: ``(B, D) -> (B, A)`` and the new LSTM state."""
        net = self.subtask_nets[0 if self.config.shared_network else subtask]
        if self.config.shared_network:
            x = torch.cat([x, self._onehot(subtask, x.shape[:1], x)], dim=-1)
        if not self.config.recurrent:
            state = None  # memoryless ablation: a zero state before every step
        return net.step(x, state)

    def _run(self, subtask: int, x: Tensor, state: tuple[Tensor, Tensor] | None) -> tuple[Tensor, Any]:
        net = self.subtask_nets[0 if self.config.shared_network else subtask]
        bsz, t, _ = x.shape
        if self.config.shared_network:
            x = torch.cat([x, self._onehot(subtask, (bsz, t), x)], dim=-1)
        if self.config.recurrent:
            return net(x, state)
        # Memoryless ablation: same layers, hidden state reset to zero before every step.
        y, _ = net(x.reshape(bsz * t, 1, x.shape[-1]), None)
        return y.reshape(bsz, t, -1), None

    def _onehot(self, subtask: int, lead: tuple[int, ...], like: Tensor) -> Tensor:
        onehot = like.new_zeros(*lead, self.config.n_subtasks)
        onehot[..., subtask] = 1.0
        return onehot


# Another name of the clocked planner, kept for code that imports it by that name.
PnpLstm = ClockedPlanner


def _subtask_names(n: int) -> list[str]:
    return ["pick", "place"] if n == 2 else [f"subtask{i}" for i in range(n)]


def _warn_long_episode(cfg: PnpLstmConfig, step: int) -> None:
    logger.warning(
        "pnp_lstm was trained on keyframe episodes of %d steps (dataset fps %s) but has been stepped %d times "
        "since reset: is the env in another control mode (e.g. --env.control_mode dense)? It only holds its "
        "last keyframe from step %d on.",
        cfg.clock_frames,
        cfg.dataset_fps if cfg.dataset_fps is not None else "unknown",
        step,
        cfg.clock_frames,
    )
