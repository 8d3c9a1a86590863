"""The rules of ``pnp_lstm``'s options, one group per part of the planner that reads them.

``PnpLstmConfig`` holds the options of two planners and of the parts they share, and states every rule at
construction (``option_rules``). A part that stands alone owns its rules: latency augmentation
(``latency.latency_rules``) and the observation gate (``observation_gate.gate_rules``). The rules here are those
of the network and its training, of the choice between the clocked and recovering planners, and of the
recovering planner's still arm: ``recovering.py`` reads the config, so its rules sit beside the config rather
than in it. A rule is a pair (condition, the one-line message naming the option, its value and the valid ones).
"""

from __future__ import annotations

from typing import Any

from .latency import latency_rules
from .observation_gate import gate_rules

LR_SCHEDULERS = ("none", "cosine")
MODES = ("clocked", "recovering")
# The FSM states the expert leaves without moving the arm (``expert.FSMExpert.next_keyframe``: close, hold before
# the place, open, hold after the retract), the valid ``still_arm_phases``.
STILL_ARM_PHASES = (2, 4, 7, 9)

Rule = tuple[bool, str]


def network_rules(c: Any) -> list[Rule]:
    """The network, its inputs and its training."""
    return [
        (c.steps_per_subtask >= 1, f"steps_per_subtask must be >= 1, got {c.steps_per_subtask}"),
        (c.n_subtasks >= 1, f"n_subtasks must be >= 1, got {c.n_subtasks}"),
        (c.num_layers in (1, 2), f"num_layers must be 1 or 2, got {c.num_layers}"),
        (c.hidden_size >= 1, f"hidden_size must be >= 1, got {c.hidden_size}"),
        (0.0 <= c.dropout < 1.0, f"dropout must be in [0, 1), got {c.dropout}"),
        (c.input_noise_std >= 0.0, f"input_noise_std must be >= 0, got {c.input_noise_std}"),
        (c.optimizer_lr > 0.0, f"optimizer_lr must be > 0, got {c.optimizer_lr}"),
        (c.optimizer_weight_decay >= 0.0, f"optimizer_weight_decay must be >= 0, got {c.optimizer_weight_decay}"),
        (c.scheduler_warmup_steps >= 0, f"scheduler_warmup_steps must be >= 0, got {c.scheduler_warmup_steps}"),
        (c.lr_scheduler in LR_SCHEDULERS, f"lr_scheduler must be one of {LR_SCHEDULERS}, got {c.lr_scheduler!r}"),
        (
            c.n_obs_steps == 1,
            f"pnp_lstm keeps its own history in the LSTM state; n_obs_steps must be 1, got {c.n_obs_steps}",
        ),
        (c.max_episode_length >= 1, f"max_episode_length must be >= 1, got {c.max_episode_length}"),
        (
            c.subtask_loss_weight >= 0.0 and c.phase_loss_weight >= 0.0,
            "subtask_loss_weight and phase_loss_weight must be >= 0",
        ),
        (c.dataset_fps is None or c.dataset_fps >= 1, f"dataset_fps must be >= 1 or None, got {c.dataset_fps}"),
    ]


def planner_rules(c: Any) -> list[Rule]:
    """Which planner (``mode``), and the options that belong to one of them only."""
    return [
        (c.mode in MODES, f"mode must be one of {MODES}, got {c.mode!r}"),
        (
            not (c.carry_hidden_across_subtasks and not c.shared_network),
            "carry_hidden_across_subtasks=True needs shared_network=True: separate subtask networks "
            "do not share a hidden-state space",
        ),
        (
            c.mode == "recovering" or not c.memory_per_attempt,
            "memory_per_attempt is the recovering planner's (mode='recovering'); the clocked planner's "
            "subtask nets restart at their switch anyway",
        ),
        (
            c.mode != "recovering" or not (c.shared_network or c.carry_hidden_across_subtasks),
            "shared_network and carry_hidden_across_subtasks are the clocked planner's (its subtask nets); the "
            "recovering planner has one trunk over the whole episode: leave them False",
        ),
    ]


def still_arm_rules(c: Any) -> list[Rule]:
    """The recovering planner's still arm at inference (``recovering.py``): the FSM states whose keyframe keeps
    the arm."""
    return [
        (
            set(c.still_arm_phases) <= set(STILL_ARM_PHASES),
            f"still_arm_phases must be among the FSM states that keep the arm {list(STILL_ARM_PHASES)}, got "
            f"{list(c.still_arm_phases)}",
        ),
        (c.still_arm_tol >= 0.0, f"still_arm_tol must be >= 0, got {c.still_arm_tol}"),
    ]


def option_rules(c: Any) -> list[Rule]:
    """Every rule, in the order the config states them."""
    return [*network_rules(c), *latency_rules(c), *planner_rules(c), *gate_rules(c), *still_arm_rules(c)]
