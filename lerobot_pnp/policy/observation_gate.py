"""Act on settled observations: hold a commanded keyframe until the observed robot state shows it.

The paper's run-time loop is "the net predicts the next keyframe, an interpolator moves there, repeat". With
observation latency the robot has moved there, but the observation that shows it comes ``L`` steps later; a
planner that steps its LSTM on every observation sees a history whose shape depends on ``L``, and fails at a
latency it was never trained on. The gate holds a command that moves the arm or the gripper (returning it again,
without stepping the network) while more than ``in_flight`` commanded moves are still unobserved, and counts a
move as observed when the observed robot state changes. With ``in_flight = 0`` every keyframe is planned on an
observation that shows all earlier moves: the inputs of latency 0 at any latency, one move per ``1 + L`` steps.
With ``in_flight = k`` (a planner trained on observations up to ``k`` steps late) it never waits at latency
``<= k`` and acts exactly as without the gate; at a larger latency it waits just long enough that what it sees
is ``k`` moves behind, as in training. A move that never shows (too small to see) is given up on after
``max_steps`` steps; a command that moves nothing (a hold keyframe) is not counted.

"Changed" ignores an observation that goes back to one of the last ``past`` observed states: when the latency
grows within an episode the observation jumps back in time, to a pose the arm has already left.
Thresholds are Euclidean norms in normalised units (the pre-processor's mean/std), which average the per-joint
observation noise. A command counts as a move only when it changes by clearly more than an observation must
change to count as its arrival (a normalised joint target and a normalised joint angle have about the same
scale), so that every move counted is seen to arrive; a missed arrival would make the gate wait needlessly
until ``max_steps``. The converse does happen, and is kept: a command below the action threshold is not counted,
yet its arrival is seen and taken for a counted move's, so a few decisions are planned on a view that misses
two moves. Waiting exactly (with the simulator's knowledge of which moves are unobserved) spends more of the
episode's budget than those views lose (``scripts/latency_decisions.py --oracle_gate``).

Everything is per environment of the batch: each env waits for its own move.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch
from torch import Tensor


@dataclass
class ObservationGate:
    """One episode's gate for a batch (a fresh one per episode); ``decide`` says which envs step the planner now.
    Its settings are the policy config's ``await_*`` fields."""

    state_dim: int  # the leading input dims that are the robot state (joints + gripper)
    state_tol: float
    action_tol: float
    max_steps: int
    in_flight: int  # moves that may be unobserved when the planner plans the next one
    past: int  # how many of the last observed states count as "the past" for a latency that grows

    def __post_init__(self) -> None:
        self._seen: Tensor | None = None  # (B, P, S) the last distinct observed robot states, newest first
        self._unseen: Tensor | None = None  # (B,) commanded moves not observed yet
        self._waited: Tensor | None = None  # (B,) steps held since the last decision

    def decide(self, x: Tensor) -> Tensor:
        """``(B, D)`` normalised inputs -> ``(B,)`` bool: True where the planner steps on this observation."""
        state = x[:, : self.state_dim]
        if self._seen is None:
            self._seen = state.unsqueeze(1).repeat(1, self.past, 1)
            self._unseen = torch.zeros(x.shape[0], dtype=torch.long, device=x.device)
            self._waited = torch.zeros(x.shape[0], dtype=torch.long, device=x.device)
            return torch.ones(x.shape[0], dtype=torch.bool, device=x.device)
        new = ((state.unsqueeze(1) - self._seen).norm(dim=-1) > self.state_tol).all(dim=1)  # a move arrived
        self._seen = torch.where(new[:, None, None], torch.cat([state.unsqueeze(1), self._seen[:, :-1]], 1), self._seen)
        self._unseen = torch.where(new, (self._unseen - 1).clamp(min=0), self._unseen)
        timeout = self._waited >= self.max_steps
        self._unseen = torch.where(timeout, torch.zeros_like(self._unseen), self._unseen)
        return (self._unseen <= self.in_flight) | timeout

    def update(self, decided: Tensor, new_action: Tensor, old_action: Tensor | None) -> None:
        """Count the decisions of this step whose commands move something (a hold keyframe moves nothing)."""
        moves = (
            torch.ones_like(decided) if old_action is None else (new_action - old_action).norm(dim=-1) > self.action_tol
        )
        self._unseen = self._unseen + (decided & moves).long()
        self._waited = torch.where(decided, torch.zeros_like(self._waited), self._waited + 1)


def gate_rules(c: Any) -> list[tuple[bool, str]]:
    """The rules of the config's ``await_*`` options, which set up the gate: (condition, the one-line message
    naming the options and their values)."""
    return [
        (
            c.await_state_tol > 0
            and c.await_action_tol > 0
            and c.await_max_steps >= 1
            and (c.await_in_flight is None or c.await_in_flight >= 0)
            and c.await_past_states >= 1,
            "await_state_tol and await_action_tol must be > 0, await_max_steps and await_past_states >= 1 and "
            f"await_in_flight >= 0, got {c.await_state_tol}, {c.await_action_tol}, {c.await_max_steps}, "
            f"{c.await_past_states} and {c.await_in_flight}",
        ),
    ]
