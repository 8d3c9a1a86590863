"""What the study compares. A method is a small spec: how it is built from the training data and how it
is evaluated. New methods (the recovering planner, DAgger rounds, ACT) plug in by adding a ``Method``.

* ``expert``: the scripted FSM (upper bound; privileged, reads the simulator), its own loop.
* ``lookup_table``: open-loop nearest-neighbour replay of the training episodes (``baselines.py``); no
  training seed (deterministic given the data).
* ``clocked_lstm``: the paper's planner, two LSTMs (PICK, PLACE) on a fixed 10-step clock.
* ``shared_lstm``: one LSTM for both subtasks with a subtask one-hot input.
* ``memoryless``: the clocked two-network model with the hidden state reset every step (same weights and
  inputs; no memory). Only the input-to-hidden weights are used, so it is not capacity-matched: the paper's
  architecture without its memory.
* ``recovering``: the recovering planner (``policy/recovering.py``): one LSTM over the whole variable-length
  episode, no clock, trained with ``policy/recipes.py:RECOVERING_RECIPE`` on the same
  demonstrations, which show no recovery.
* ``recovering_dagger``: ``recovering`` of the same seed plus one DAgger round (``lerobot_pnp.dagger``): 300
  rollouts of that policy under nominal, missed-grasp, drop, nudge and displacement conditions, every visited
  state labelled by the expert, aggregated with the demonstrations, retrained from scratch. Extra data the
  others do not get (interactive expert labels): it shows what the teacher adds, not a like-for-like method.
* ``recovering_dart``: ``recovering`` of the same seed plus one DART round at the same budget: 300 noisy
  expert demonstrations of the undisturbed task (``DART_SIGMA`` rad on the joint targets it executes, clean
  labels). Its data never shows a disturbance, only the off-path states the noise makes (docs/guides/dagger-dart.md).
* ``memoryless_mlp``: the capacity-matched memoryless control: ``recovering`` with an MLP trunk of about the
  LSTM trunk's parameter count instead of the LSTM (same data, inputs, loss and budget).
* ``phase_told_mlp``: the same MLP told the phase: trained and run with ``observe_phase`` (a one-hot of the
  phase inferred from the true simulator state appended to ``environment_state``; privileged), on the same
  demonstrations recorded with that observation. What memory must infer, handed to a network without it.
* ``act``: LeRobot's ACT, state-only, trained on the dense recording of the same demonstrations and run in
  dense control mode (``act_baseline.py``; its budget is in its description).

A method may train on some task presets only (``Method.tasks``): the clocked planners need exactly 10-frame
demonstrations (the paper's task), so a study on the ``full`` task refuses them up front (``StudyConfig``).

The parts live beside this catalogue: ``recipes`` (the recovering recipe, the DAgger and DART schedules,
``policy_settings``), ``builders`` (how each method is trained and evaluated), ``training`` (a training's key,
and the keyed training that reuses one on disk) and ``method_spec`` (``Method``, ``TrainContext``). A training
that continues another method's run finds that method through the catalogue's lookup, handed down to it.
"""

from __future__ import annotations

import functools
from pathlib import Path

from lerobot_pnp.cache import Stage
from lerobot_pnp.dagger import RECOVERING_BATCH_SIZE
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.report import training
from lerobot_pnp.report.builders import (
    act_description,
    act_env,
    act_train,
    checkpoint_eval,
    dagger_train,
    dart_train,
    expert_eval,
    lookup_eval,
    no_training,
    observe_phase,
    pnp_lstm_trainer,
)
from lerobot_pnp.report.method_spec import Method
from lerobot_pnp.report.method_spec import TrainContext as TrainContext
from lerobot_pnp.report.recipes import (
    DAGGER_ROLLOUTS,
    DAGGER_ROUNDS,
    DAGGER_SCHEDULE,
    DART_SCHEDULE,
    DART_SIGMA,
    MEMORYLESS_MLP,
    PHASE_TOLD_MLP,
    RECOVERING_STUDY_SETTINGS,
    RECOVERING_TRUNK,
    dagger_betas,
    dagger_round_names,
    retraining,
)
from lerobot_pnp.report.recipes import policy_settings as policy_settings
from lerobot_pnp.sim.suites import RECOVERY_BUDGET


def _method(name: str) -> Method:
    """The catalogue's method ``name``: what the catalogue hands to the trainings that continue another method."""
    return METHODS[name]


def train_stage(method: Method, ctx: TrainContext) -> Stage:
    """The key of ``method``'s training (``training.train_stage``, the run it continues from this catalogue)."""
    return training.train_stage(method, ctx, _method)


def keyed_train(method: Method, ctx: TrainContext) -> tuple[Path | None, bool]:
    """``method``'s training unless one of the same key is on disk (``training.keyed_train``)."""
    return training.keyed_train(method, ctx, _method)


CLOCKED_WHY = (
    "the clocked planner trains on exactly 10-frame episodes (the paper's task); this task's demonstrations "
    "have recoveries (longer episodes of varying length)"
)


def pnp_lstm_method(name: str, label: str, description: str, **overrides) -> Method:
    """A ``pnp_lstm`` method; a recovering planner trains with the recipe's batch size, as DAgger does."""
    clocked = overrides.get("mode", "clocked") == "clocked"
    batch = None if clocked else RECOVERING_BATCH_SIZE
    return Method(name, label, description, True, pnp_lstm_trainer(overrides, batch), checkpoint_eval, overrides,
                  tasks=("paper",) if clocked else None, tasks_why=CLOCKED_WHY if clocked else "",
                  batch_size=batch)  # fmt: skip


# The recovering planner's recipe; its training windows hold the longest episode of the study (a recovery
METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method(
            "expert",
            "expert (FSM)",
            "scripted feedback FSM; upper bound. It reads the simulator's state, so observation noise, bias and "
            "latency do not reach it: on those suites it is not a like-for-like bound",
            False,
            no_training,
            expert_eval,
        ),
        Method(
            "lookup_table",
            "lookup table",
            "open-loop replay of the nearest training episode (same inputs, same data)",
            False,
            no_training,
            lookup_eval,
        ),
        pnp_lstm_method("clocked_lstm", "clocked LSTM (paper)", "two LSTMs on a fixed 10-step clock (paper)"),
        pnp_lstm_method("shared_lstm", "shared LSTM", "one LSTM + subtask one-hot", shared_network=True),
        pnp_lstm_method("memoryless", "memoryless", "clocked nets, hidden state reset every step", recurrent=False),
        pnp_lstm_method(
            "memoryless_mlp",
            "memoryless MLP (matched)",
            f"the recovering planner's recipe with an MLP trunk of about its {RECOVERING_TRUNK} trunk's parameter count "
            "(no memory)",
            **MEMORYLESS_MLP,
        ),
        Method(
            "phase_told_mlp",
            "MLP told the phase",
            "the matched MLP with the phase one-hot inferred from the simulator appended to its input (privileged; "
            "the same demonstrations recorded with `observe_phase`; trained on current observations only)",
            True,
            pnp_lstm_trainer(PHASE_TOLD_MLP, RECOVERING_BATCH_SIZE),
            checkpoint_eval,
            PHASE_TOLD_MLP,
            data="phase",
            adapt_env=observe_phase,
            batch_size=RECOVERING_BATCH_SIZE,
        ),
        pnp_lstm_method(
            "recovering",
            "recovering LSTM",
            "one LSTM over the whole episode, no clock, learned subtask switch; the recipe `RECOVERING_RECIPE` "
            f"({RECOVERING_TRUNK} trunk, late episodes, binary gripper, the observation gate, the arm held on the place's open, the memory restarted at each "
            "re-pick); recoveries only as the task "
            "demonstrates them (none on `paper`, every disturbance on `full`)",
            **RECOVERING_STUDY_SETTINGS,
        ),
        Method(
            "recovering_dagger",
            "recovering LSTM + DAgger",
            f"`recovering` of the same seed + {DAGGER_ROUNDS} DAgger rounds of "
            f"{DAGGER_SCHEDULE['rollouts_per_round']} rollouts under nominal, missed-grasp, drop, nudge and "
            "displacement conditions (Ross et al.'s mixture: each step executes the expert's label with "
            f"probability {dagger_betas()} in rounds {dagger_round_names()}, the policy's own action otherwise), every visited state "
            f"labelled by the expert, aggregated with the demonstrations and earlier rounds, each round "
            f"{retraining(DAGGER_SCHEDULE)} (extra interactive data: what the teacher adds)",
            True,
            functools.partial(dagger_train, method_of=_method),
            checkpoint_eval,
            RECOVERING_STUDY_SETTINGS,
            continues="recovering",
            batch_size=RECOVERING_BATCH_SIZE,
            schedule=DAGGER_SCHEDULE,
            tasks=("paper",),
            tasks_why="the study's DAgger round is set up for the paper task (its rollouts run at a "
            f"{RECOVERY_BUDGET}-keyframe budget, below the full task's); DAgger on full: `lerobot-pnp dagger`",
        ),
        Method(
            "recovering_dart",
            "recovering LSTM + DART",
            f"`recovering` of the same seed + one DART round at DAgger's budget: {DAGGER_ROLLOUTS} expert "
            f"demonstrations of the undisturbed task with {DART_SIGMA} rad of Gaussian noise on each joint target "
            f"it executes, labelled with its clean commands, aggregated with the demonstrations, {retraining(DART_SCHEDULE)} "
            "(no disturbance in its data)",
            True,
            functools.partial(dart_train, method_of=_method),
            checkpoint_eval,
            RECOVERING_STUDY_SETTINGS,
            continues="recovering",
            batch_size=RECOVERING_BATCH_SIZE,
            schedule=DART_SCHEDULE,
            tasks=("paper",),
            tasks_why="the study's DART round is set up for the paper task, as its DAgger round; DART on full: "
            "`lerobot-pnp dagger --config_path configs/dart_full.json`",
        ),
        Method(
            "act",
            "ACT (dense)",
            act_description(),
            True,
            act_train,
            checkpoint_eval,
            data="dense",
            adapt_env=act_env,
        ),
    )
}


# The methods trained again on fewer demonstrations (``StudyConfig.data_efficiency``): the paper's comparison.
DATA_EFFICIENCY_METHODS = ("lookup_table", "clocked_lstm")


def get_methods(names: list[str]) -> list[Method]:
    unknown = [n for n in names if n not in METHODS]
    if unknown:
        raise ConfigError(f"unknown method(s) {unknown}; valid: {sorted(METHODS)}")
    return [METHODS[n] for n in names]
