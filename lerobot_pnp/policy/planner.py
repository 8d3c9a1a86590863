"""The one interface of the two planners behind ``PnpLstmPolicy``, and the one inference-state layout.

``PnpLstmPolicy`` is a thin LeRobot wrapper: it turns batches into ``(B, T, D)`` episodes (windows, padding,
training-time augmentation) and ``(B, D)`` observations, and hands them to its planner, the ``nn.Module`` at
``policy.model`` that holds every weight. A planner is either ``clocked.ClockedPlanner`` (the paper's two
subtask LSTMs on a fixed 10-frame clock) or ``recovering.RecoveringPlanner`` (one trunk, no clock, a learned
PICK/PLACE switch); ``modes.build_planner`` picks it from ``config.mode``, the one place that does. The policy
never asks which one it has.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import torch
from torch import Tensor, nn

if TYPE_CHECKING:
    from .observation_gate import ObservationGate


@dataclass(frozen=True)
class PlannerState:
    """What a planner carries from one ``select_action`` to the next for a batch of envs (``None`` after reset).

    Frozen: each step returns a new state, so tensors made under ``torch.inference_mode`` are never modified in
    place by a later step outside it."""

    step: int
    """Steps taken since the reset (the clocked planner's clock)."""
    action: Tensor
    """``(B, A)`` the action returned at the last step (held by the clocked planner after its last keyframe, and by
    the observation gate while a move is unobserved); its batch size is the episode's."""
    memory: Any = None
    """The network's recurrent state, ``None`` where it has none (memoryless, or a clocked subtask not begun)."""
    gate: ObservationGate | None = None
    """Recovering planner with ``await_observation``: the gate of this episode (``observation_gate``)."""
    subtask_prob: Tensor | None = None
    """Recovering planner: ``(B,)`` P(place) of the last step, for viewers and logs (never used to act)."""
    phase: Tensor | None = None
    """Recovering planner: ``(B,)`` its auxiliary phase classifier's last prediction (diagnostics, ``still_arm_phases``)."""

    @property
    def batch_size(self) -> int:
        return int(self.action.shape[0])


def lstm_step(lstm: nn.LSTM, x: Tensor, state: tuple[Tensor, Tensor] | None) -> tuple[Tensor, tuple[Tensor, Tensor]]:
    """One time step of ``lstm`` (any number of layers) in eval mode: ``(B, D)`` and its state ``(h, c)``, each
    ``(layers, B, H)`` as ``nn.LSTM``'s (``None``: zeros) -> the top layer's output ``(B, H)``, the new state.

    ``torch.lstm_cell`` on the LSTM's own weights: numerically its step, without ``nn.LSTM``'s per-call overhead
    (which dominates at batch 1). No dropout between layers (inference)."""
    if state is None:
        zeros = x.new_zeros(lstm.num_layers, x.shape[0], lstm.hidden_size)
        state = (zeros, zeros)
    hs, cs, inp = [], [], x
    for k in range(lstm.num_layers):
        weights = [getattr(lstm, f"{w}_l{k}") for w in ("weight_ih", "weight_hh", "bias_ih", "bias_hh")]
        h, c = torch.lstm_cell(inp, (state[0][k], state[1][k]), *weights)
        hs.append(h)
        cs.append(c)
        inp = h
    return inp, (torch.stack(hs), torch.stack(cs))


@runtime_checkable
class Planner(Protocol):
    """What ``PnpLstmPolicy`` asks of its planner (both are ``nn.Module``s; ``__call__`` is the raw network)."""

    def loss(
        self, x: Tensor, y: Tensor, valid: Tensor, subtask: Tensor | None, phase: Tensor | None
    ) -> tuple[Tensor, Tensor, dict[str, float]]:
        """Whole episodes ``(B, T, D)`` from frame 0, targets ``(B, T, A)``, the mask of real frames ``(B, T)`` and
        the per-frame labels where the batch has them -> (mean loss, per-sample loss ``(B,)``, logged floats)."""
        ...

    def sequence(self, x: Tensor) -> Tensor:
        """Teacher-forced actions ``(B, T, A)`` for whole episodes ``(B, T, D)`` from frame 0 (stateless)."""
        ...

    def act(self, x: Tensor, state: PlannerState | None) -> tuple[Tensor, PlannerState]:
        """One inference step: observations ``(B, D)`` and the state since the reset -> ``(B, A)``, the new state."""
        ...

    def check_episode_lengths(self, lengths: list[int]) -> None:
        """Raise ``DatasetError`` for a training dataset whose episode lengths this planner cannot learn from."""
        ...
