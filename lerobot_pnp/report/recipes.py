"""The recipes and round schedules of the study's learned methods.

The recovering planner's recipe and the memoryless controls' variants of it; the study's DAgger and DART rounds
(``dagger.DaggerConfig`` fields, part of the training key of the methods that run them, ``Method.schedule``);
``policy_settings``: a method's policy settings for its study and training data; the phrases the method
descriptions build from these values, so that a report cannot name other ones.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from lerobot_pnp.dagger.config import DEFAULT_ROLLOUT_SUITES, mixture_beta
from lerobot_pnp.policy.recipes import RECOVERING_RECIPE
from lerobot_pnp.sim.suites import RECOVERY_BUDGET

if TYPE_CHECKING:
    from lerobot_pnp.report.method_spec import TrainContext

# The study's settings of the recovering planner: RECOVERING_RECIPE, its training windows holding the longest
# episode of the study (a recovery suite's budget + the final state: DAgger's rollouts are that long).
RECOVERING_STUDY_SETTINGS = {**RECOVERING_RECIPE, "max_episode_length": RECOVERY_BUDGET + 1}
# The memoryless controls take the recipe that gave each its best nominal success on the `full` task
# (docs/policy.md): the plain MLP with the late episodes, the phase-told one without.
# Without memory there is none to restart at a re-pick: memory_per_attempt is off (it would change nothing).
MEMORYLESS_MLP = {**RECOVERING_STUDY_SETTINGS, "recurrent": False, "memory_per_attempt": False}
PHASE_TOLD_MLP = {
    **RECOVERING_STUDY_SETTINGS,
    "recurrent": False,
    "latency_augment_prob": 0.0,
    "memory_per_attempt": False,
}
DAGGER_ROLLOUTS = 300  # policy episodes of the one DAgger round, cycled over the rollout suites
# the recipe's trunk as the method descriptions name it, read from the recipe so that a report cannot name another
RECOVERING_TRUNK = f"{RECOVERING_STUDY_SETTINGS['num_layers']} x {RECOVERING_STUDY_SETTINGS['hidden_size']} LSTM"
# DAgger's rounds in the study (Ross et al.'s mixture): round r's rollouts execute the expert's label at each step
# with probability DAGGER_BETA * 0.5 ** (r - 1), the policy's action otherwise, and every visited state is labelled.
# Pure on-policy rounds (beta 0) label only the first keyframe of each recovery (docs/guides/dagger-dart.md).
DAGGER_ROUNDS = 2
DAGGER_BETA = 1.0
# rad of noise on each joint target the expert executes (benchmarks/dart_noise.py: about twice the grasp clearance)
DART_SIGMA = 0.02
# epochs of a DAgger round's training when it continues the previous round's weights (0: retrained from scratch).
# DART retrains from scratch: warm-started it loses the drop recovery (docs/changelog.md)
DAGGER_WARM_START_EPOCHS = 100

# The study's DAgger and DART rounds (``dagger.DaggerConfig`` fields): part of the training key of the methods
# that run them (``Method.schedule``), so a changed mixture, noise or rollout budget trains again.
# The same label budget for both: DAGGER_ROLLOUTS expert-labelled episodes, split evenly over DAgger's rounds.
_ROUND = {"env_changes": {"keyframe_budget": RECOVERY_BUDGET}}
DAGGER_SCHEDULE = {
    **_ROUND,
    "rounds": DAGGER_ROUNDS,
    "rollouts_per_round": DAGGER_ROLLOUTS // DAGGER_ROUNDS,
    "beta": DAGGER_BETA,
    "beta_decay": 0.5,
    "rollout_suites": list(DEFAULT_ROLLOUT_SUITES),
    "warm_start_epochs": DAGGER_WARM_START_EPOCHS,
}
DART_SCHEDULE = {
    **_ROUND,
    "rounds": 1,
    "rollouts_per_round": DAGGER_ROLLOUTS,
    "beta": 1.0,
    "dart": {"sigma": DART_SIGMA},
    "rollout_suites": ["nominal"],
    "warm_start_epochs": 0,
}
# What each ran before its schedule was part of the training key (a record made then is valid for this value):
# DAgger one pure on-policy round, DART as now.
SCHEDULE_BEFORE_KEYED = {
    "recovering_dagger": {**_ROUND, "rounds": 1, "rollouts_per_round": DAGGER_ROLLOUTS, "beta": 0.0,
                          "beta_decay": 0.5, "rollout_suites": list(DEFAULT_ROLLOUT_SUITES), "warm_start_epochs": 0},
    "recovering_dart": DART_SCHEDULE,
}  # fmt: skip


def policy_settings(overrides: dict, ctx: TrainContext) -> dict:
    """A method's policy settings for its study and training data. A method that takes the recovering recipe
    takes the study's changes to it (``ctx.recipe_changes``: the paper study trains it with one LSTM layer).
    A recovering-mode window must hold the longest episode the recorded task allows (its keyframe budget + the
    final state: 41 frames on the ``full`` task, more than the study's recovery budget); the paper's task (10
    keyframes) leaves it unchanged. A study without recipe changes on the paper task keeps its training keys."""
    if overrides.get("mode") != "recovering":
        return overrides
    # a change reaches the settings the method keeps from the recipe (the told MLP keeps its own augmentation)
    kept = {k: v for k, v in ctx.recipe_changes.items() if overrides.get(k) == RECOVERING_STUDY_SETTINGS.get(k)}
    settings = {**overrides, **kept}
    if ctx.task_budget is not None:
        settings["max_episode_length"] = max(settings["max_episode_length"], ctx.task_budget + 1)
    return settings


def retraining(schedule: dict) -> str:
    """How a round's policy is trained, for the method descriptions."""
    if epochs := schedule["warm_start_epochs"]:
        return f"the previous round's planner trained on for {epochs} epochs (warm start; at most the study's epochs)"
    return "retrained from scratch"


def dagger_betas() -> str:
    """The mixture weight of each of the study's DAgger rounds, for the method descriptions."""
    s = DAGGER_SCHEDULE
    return ", ".join(f"{mixture_beta(s['beta'], s['beta_decay'], r):g}" for r in range(1, s["rounds"] + 1))


def dagger_round_names() -> str:
    return ", ".join(str(r + 1) for r in range(DAGGER_SCHEDULE["rounds"]))


def policy_acts(schedule: dict | None) -> bool:
    """Whether the policy acts in some round of a DAgger ``schedule`` (a round's mixture weight below 1)."""
    if not schedule:
        return False
    return any(
        mixture_beta(schedule["beta"], schedule.get("beta_decay", 0.5), r) < 1 for r in range(1, schedule["rounds"] + 1)
    )
