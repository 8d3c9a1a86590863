"""The paper's clocked planner network (``--policy.mode=clocked``, the default): two LSTMs on a fixed clock.

The PICK net maps keyframes 0..4 to the next keyframe, the PLACE net, from a zero hidden state, keyframes
5..9 (de Magistris et al. 2016); ``shared_network`` makes it one LSTM told the subtask (one-hot). The policy
wrapper (``modeling_pnp_lstm.PnpLstmPolicy``) owns the clock; ``recovering.py`` is the unclocked mode.
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor, nn

from .configuration_pnp_lstm import PnpLstmConfig


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
        """One time step ``(B, D) -> (B, A)`` in eval mode, with ``torch.lstm_cell`` on the LSTM's own weights.

        Numerically the LSTM's step, at a fifth of ``nn.LSTM``'s per-call overhead at batch 1.
        """
        lstm = self.lstm
        if state is None:
            zeros = x.new_zeros(lstm.num_layers, x.shape[0], lstm.hidden_size)
            state = (zeros, zeros)
        h_all, c_all = state
        hs, cs = [], []
        inp = x
        for layer in range(lstm.num_layers):
            h, c = torch.lstm_cell(
                inp,
                (h_all[layer], c_all[layer]),
                getattr(lstm, f"weight_ih_l{layer}"),
                getattr(lstm, f"weight_hh_l{layer}"),
                getattr(lstm, f"bias_ih_l{layer}"),
                getattr(lstm, f"bias_hh_l{layer}"),
            )
            hs.append(h)
            cs.append(c)
            inp = h
        return self.head(inp), (torch.stack(hs), torch.stack(cs))


class PnpLstm(nn.Module):
    """The planner network: one ``SubtaskLSTM`` per subtask, or one shared net told the subtask (one-hot)."""

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
