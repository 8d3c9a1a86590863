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
until ``max_steps``.

**Running ahead on an efference copy** (``run_ahead``, an ``EfferenceCopy``). Waiting costs a step per move, and
the task's keyframe budget is the same at every latency. The planner knows what it commanded, and the keyframe
interpolator brings the arm to the commanded joint targets within the step. So where the gate would wait and no
unobserved move changes the gripper, the planner steps at once on the late observation with its joints replaced by
the targets it commanded ``in_flight + 1`` steps ago, which is what its trained latency would have shown:

* gripper open (nothing in it, every command the view must predict open): the move changed only the joints;
* gripper closed on the object (the observed opening is the object's width, the object within ``HOLD_RADIUS`` of
  the hand, every command the view must predict closed): the object moved with the hand, so its observed position
  is moved by the hand's displacement between the observed and the commanded joints (the robot model's forward
  kinematics, ``ik.hand_positions``).

The commands the view must predict are the unobserved ones older than the newest ``in_flight``: those the trained
latency does not show either are not predicted. It keeps such a step only when the new command keeps the gripper
as it is; a gripper command (a grasp decided on a view that cannot show a nudge yet, a release) is dropped, and
waited for as without running ahead, unless ``run_ahead_gripper`` keeps it. A disturbance
(a drop, a nudge) is seen as late as the latency shows it, as without running ahead. At latencies within training
the gate never waits, so running ahead never happens there either.

Everything is per environment of the batch: each env waits for its own move.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

GRIPPER_THRESHOLD = 0.5  # raw units: a gripper command or an observed opening above it is open (0 closed, 1 open)
HOLD_OPENING = 0.1  # raw units: a closed gripper whose opening stays above this closed on something
HOLD_RADIUS = 0.04  # m: an object this close to the hand with the gripper closed on something is held
N_JOINTS = 7  # the arm joints that lead the robot state and the action; the gripper follows them
N_OBJECT = 3  # the object's xyz that lead the environment state


@dataclass(frozen=True)
class EfferenceCopy:
    """Turns a normalised command into the normalised observation its execution shows: the training data's
    MEAN_STD statistics (raw units) of the robot state ``(S,)``, the action ``(A,)`` and the environment state
    ``(E,)``, as the pre- and post-processor use them."""

    state_mean: Tensor
    state_std: Tensor
    action_mean: Tensor
    action_std: Tensor
    env_mean: Tensor
    env_std: Tensor
    eps: float = 1e-8  # LeRobot's normaliser divides by ``std + eps``

    def joints_seen(self, action: Tensor) -> Tensor:
        """``(B, A)`` normalised commands -> ``(B, 7)`` the normalised joint angles that reach their targets."""
        return self._state(self._raw_joints(action, self.action_mean, self.action_std))

    def gripper_commanded_open(self, action: Tensor) -> Tensor:
        return action[..., N_JOINTS] * self.action_std[N_JOINTS] + self.action_mean[N_JOINTS] > GRIPPER_THRESHOLD

    def gripper_observed_open(self, state: Tensor) -> Tensor:
        return self._opening(state) > GRIPPER_THRESHOLD

    def holding(self, state: Tensor, env: Tensor) -> Tensor:
        """``(B,)`` the observation shows the object in the closed gripper."""
        opening = self._opening(state)
        closed_on_something = (opening > HOLD_OPENING) & (opening <= GRIPPER_THRESHOLD)
        if not bool(closed_on_something.any()):
            return torch.zeros_like(closed_on_something)
        hand = self._hand(self._raw_joints(state, self.state_mean, self.state_std))
        near = (self._raw_object(env) - hand).norm(dim=-1) < HOLD_RADIUS
        return closed_on_something & near

    def object_seen(self, state: Tensor, env: Tensor, action: Tensor) -> Tensor:
        """``(B, 3)`` the normalised object position once the held object has moved with the hand from the observed
        joints to the targets of ``action``."""
        start = self._hand(self._raw_joints(state, self.state_mean, self.state_std))
        end = self._hand(self._raw_joints(action, self.action_mean, self.action_std))
        moved = self._raw_object(env) + end - start
        return (moved - self.env_mean[:N_OBJECT]) / (self.env_std[:N_OBJECT] + self.eps)

    def _raw_joints(self, x: Tensor, mean: Tensor, std: Tensor) -> Tensor:
        return x[:, :N_JOINTS] * std[:N_JOINTS] + mean[:N_JOINTS]

    def _state(self, joints: Tensor) -> Tensor:
        return (joints - self.state_mean[:N_JOINTS]) / (self.state_std[:N_JOINTS] + self.eps)

    def _opening(self, state: Tensor) -> Tensor:
        return state[..., N_JOINTS] * self.state_std[N_JOINTS] + self.state_mean[N_JOINTS]

    def _raw_object(self, env: Tensor) -> Tensor:
        return env[:, :N_OBJECT] * self.env_std[:N_OBJECT] + self.env_mean[:N_OBJECT]

    def _hand(self, joints: Tensor) -> Tensor:
        """``(B, 7)`` raw joints -> ``(B, 3)`` the gripper site (m): the robot model's forward kinematics."""
        from lerobot_pnp.ik import hand_positions  # MuJoCo, loaded when a held object first moves

        hand = hand_positions(joints.detach().cpu().double().numpy())
        return torch.as_tensor(hand, dtype=joints.dtype, device=joints.device)

    @classmethod
    def from_stats(cls, stats: dict, state_key: str, action_key: str, env_key: str) -> EfferenceCopy | None:
        """From LeRobot stats (``{key: {"mean", "std"}}``, tensors, arrays or lists); None when one is missing."""
        try:
            parts = [stats[k][m] for k in (state_key, action_key, env_key) for m in ("mean", "std")]
        except (KeyError, TypeError):
            return None
        return cls(*(torch.as_tensor(v, dtype=torch.float32).reshape(-1) for v in parts))


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
    run_ahead: EfferenceCopy | None = None  # step on the efference copy instead of waiting (module docstring)
    run_ahead_gripper: bool = False  # keep gripper commands planned running ahead too

    def __post_init__(self) -> None:
        self._seen: Tensor | None = None  # (B, P, S) the last distinct observed robot states, newest first
        self._unseen: Tensor | None = None  # (B,) commanded moves not observed yet
        self._waited: Tensor | None = None  # (B,) steps held since the last decision
        self._commands: Tensor | None = None  # (B, in_flight + 1, A) the commands of the last steps, newest first
        self._moves_open: Tensor | None = None  # (B, M) gripper open in the last commanded moves, newest first
        self._ahead: tuple[Tensor, Tensor] | None = None  # (B,) x2: envs run ahead open / holding, until ``confirm``

    def decide(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """``(B, D)`` normalised inputs -> (``(B,)`` bool: True where the planner steps on this observation, the
        ``(B, D)`` inputs it steps on: ``x``, with the efference copy's joints where it runs ahead)."""
        state = x[:, : self.state_dim]
        if self._seen is None:
            self._seen = state.unsqueeze(1).repeat(1, self.past, 1)
            self._unseen = torch.zeros(x.shape[0], dtype=torch.long, device=x.device)
            self._waited = torch.zeros(x.shape[0], dtype=torch.long, device=x.device)
            return torch.ones(x.shape[0], dtype=torch.bool, device=x.device), x
        new = ((state.unsqueeze(1) - self._seen).norm(dim=-1) > self.state_tol).all(dim=1)  # a move arrived
        self._seen = torch.where(new[:, None, None], torch.cat([state.unsqueeze(1), self._seen[:, :-1]], 1), self._seen)
        self._unseen = torch.where(new, (self._unseen - 1).clamp(min=0), self._unseen)
        timeout = self._waited >= self.max_steps
        self._unseen = torch.where(timeout, torch.zeros_like(self._unseen), self._unseen)
        decided = (self._unseen <= self.in_flight) | timeout
        copy = self.run_ahead
        if copy is None or self._commands is None or self._commands.shape[1] <= self.in_flight or bool(decided.all()):
            return decided, x
        # the gripper of every move the view must predict (the unobserved ones older than the newest ``in_flight``,
        # which the trained latency does not show either): all open, or all closed
        depth = torch.arange(self._moves_open.shape[1], device=x.device)
        unseen = (depth[None, :] < self._unseen[:, None]) & (depth[None, :] >= self.in_flight)
        all_open = (self._moves_open | ~unseen).all(dim=1)
        all_closed = (~self._moves_open | ~unseen).all(dim=1)
        env = x[:, self.state_dim :]
        wait = ~decided
        ahead_open = wait & all_open & copy.gripper_observed_open(state)
        ahead_held = wait & all_closed & ~ahead_open
        if bool(ahead_held.any()):
            ahead_held &= copy.holding(state, env)
        ahead = ahead_open | ahead_held
        if not bool(ahead.any()):
            return decided, x
        target = self._commands[:, self.in_flight]
        shown = x.clone()
        shown[:, :N_JOINTS] = torch.where(ahead[:, None], copy.joints_seen(target), x[:, :N_JOINTS])
        if bool(ahead_held.any()):
            moved = copy.object_seen(state, env, target)
            at = slice(self.state_dim, self.state_dim + N_OBJECT)
            shown[:, at] = torch.where(ahead_held[:, None], moved, x[:, at])
        self._ahead = (ahead_open, ahead_held)
        return decided | ahead, shown

    def confirm(self, decided: Tensor, action: Tensor) -> Tensor:
        """Keep a decision made running ahead only when its command keeps the gripper as it was (open, or closed on
        the object): a gripper command is planned on an observation that shows every earlier move, as the plain
        gate does (the envs whose decision is dropped keep their command and network state)."""
        if self._ahead is None or self.run_ahead_gripper:
            self._ahead = None
            return decided
        ahead_open, ahead_held = self._ahead
        opened = self.run_ahead.gripper_commanded_open(action)
        self._ahead = None
        return decided & ~((ahead_open & ~opened) | (ahead_held & opened))

    def update(self, decided: Tensor, new_action: Tensor, old_action: Tensor | None) -> None:
        """Count the decisions of this step whose commands move something (a hold keyframe moves nothing)."""
        moves = (
            torch.ones_like(decided) if old_action is None else (new_action - old_action).norm(dim=-1) > self.action_tol
        )
        self._unseen = self._unseen + (decided & moves).long()
        self._waited = torch.where(decided, torch.zeros_like(self._waited), self._waited + 1)
        if self.run_ahead is None:
            return
        new = new_action.unsqueeze(1)
        self._commands = new if self._commands is None else torch.cat([new, self._commands], 1)[:, : self.in_flight + 1]
        opened = self.run_ahead.gripper_commanded_open(new_action)[:, None]
        if self._moves_open is None:
            self._moves_open = opened.repeat(1, self.in_flight + self.max_steps + 1)
        moved = (decided & moves)[:, None]
        self._moves_open = torch.where(moved, torch.cat([opened, self._moves_open[:, :-1]], 1), self._moves_open)
