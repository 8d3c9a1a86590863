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
  episode, no clock, trained with the recipe of ``configs/dagger.json`` (``RECOVERING_RECIPE``) on the same
  demonstrations, which show no recovery.
* ``recovering_dagger``: ``recovering`` of the same seed plus one DAgger round (``lerobot_pnp.dagger``): 300
  rollouts of that policy under nominal, missed-grasp, drop, nudge and displacement conditions, every visited
  state labelled by the expert, aggregated with the demonstrations, retrained from scratch. Extra data the
  others do not get (interactive expert labels): it shows what the teacher adds, not a like-for-like method.
* ``recovering_dart``: ``recovering`` of the same seed plus one DART round at the same budget: 300 noisy
  expert demonstrations of the undisturbed task (``DART_SIGMA`` rad on the joint targets it executes, clean
  labels). Its data never shows a disturbance, only the off-path states the noise makes (docs/results/dart.md).
* ``memoryless_mlp``: the capacity-matched memoryless control: ``recovering`` with an MLP trunk of about the
  LSTM trunk's parameter count instead of the LSTM (same data, inputs, loss and budget).
* ``phase_told_mlp``: the same MLP told the phase: trained and run with ``observe_phase`` (a one-hot of the
  phase inferred from the true simulator state appended to ``environment_state``; privileged), on the same
  demonstrations recorded with that observation. What memory must infer, handed to a network without it.
* ``act``: LeRobot's ACT, state-only, trained on the dense recording of the same demonstrations and run in
  dense control mode (``act_baseline.py``; its budget is in its description).

A method may train on some task presets only (``Method.tasks``): the clocked planners need exactly 10-frame
demonstrations (the paper's task), so a study on the ``full`` task refuses them up front (``StudyConfig``).
"""

from __future__ import annotations

import copy
import json
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from lerobot_pnp.cache import STAGE_FILE, Stage, code_versions, remove
from lerobot_pnp.dagger import RECOVERING_BATCH_SIZE, RECOVERING_RECIPE
from lerobot_pnp.dagger.config import DEFAULT_ROLLOUT_SUITES, mixture_beta
from lerobot_pnp.dagger.rollouts import TEACHER_VERSION
from lerobot_pnp.env_config import BaxterPnPEnvConfig
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.checkpoints import load_policy
from lerobot_pnp.evaluation.episodes import eval_expert, eval_lerobot_policy
from lerobot_pnp.evaluation.records import EpisodeRecord
from lerobot_pnp.evaluation.suites import RECOVERY_BUDGET
from lerobot_pnp.report import act_baseline, adapters


@dataclass
class TrainContext:
    """Where a method finds its data and puts its training output."""

    dataset_root: Path
    train_dir: Path  # this method + training seed
    seed: int
    epochs: int
    n_demos: int | None = None  # keep only the first n training episodes (data efficiency); None = all
    dense_root: Path | None = None  # the dense recording of the same demonstrations (methods with data="dense")
    act_steps: int | None = None  # ACT's training steps (None = act_baseline.ActBudget's default)
    data_keys: dict[str, str] = field(default_factory=dict)  # recording -> its dataset's stage key
    task_budget: int | None = None  # keyframe budget of the task recorded with the data (None: not known)
    # the study's changes to the recovering recipe (``StudyConfig.recipe_changes``), for every method that takes it
    recipe_changes: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Method:
    """A compared method: ``train`` builds its artefact (None if nothing to train), ``evaluate`` runs it."""

    name: str
    label: str
    description: str
    learned: bool  # trained with several seeds
    train: Callable[[TrainContext], Path | None]
    evaluate: Callable[[Path | None, TrainContext, BaxterPnPEnvConfig, int, int, int], list[EpisodeRecord]]
    policy_overrides: dict = field(default_factory=dict)
    # the recording it trains on (the study generates each one needed, all of the same demonstrations):
    # keyframe | dense (control rate, ACT) | phase (keyframe with the phase one-hot observed)
    data: str = "keyframe"
    # the env config it runs a suite's config in (ACT: the same task in dense control mode); None = unchanged
    adapt_env: Callable[[BaxterPnPEnvConfig, TrainContext], BaxterPnPEnvConfig] | None = None
    suites: tuple[str, ...] | None = None  # evaluated only on these suites (cost); None = every suite
    # a method whose run of the same training seed this one starts from (the study runs that job first)
    continues: str | None = None
    # the task presets (presets.PRESETS) whose demonstrations it can train on, and why only those; None = any
    tasks: tuple[str, ...] | None = None
    tasks_why: str = ""
    # episodes per training batch when the method's recipe sets one (the recovering planners: the recipe's);
    # None = the study's default (adapters.BATCH_SIZE), which is then not part of the training key
    batch_size: int | None = None
    # the settings of its training procedure outside the policy config (the DAgger round's mixture, noise and
    # rollouts: ``dagger.DaggerConfig`` fields), part of its training key; empty = none
    schedule: dict = field(default_factory=dict)

    def env_config(self, env_cfg: BaxterPnPEnvConfig, ctx: TrainContext) -> BaxterPnPEnvConfig:
        return env_cfg if self.adapt_env is None else self.adapt_env(env_cfg, ctx)


# ------------------------------------------------------------------------------------------------ builders
def _no_training(ctx: TrainContext) -> None:
    return None


def _expert_eval(artifact, ctx, env_cfg, n, start_seed, batch_size):
    return eval_expert(env_cfg, n, start_seed)


_EPISODES: dict[tuple[str, int | None], adapters.Episodes] = {}


def _lookup_eval(artifact, ctx, env_cfg, n, start_seed, batch_size):
    from lerobot_pnp.report.baselines import LookupTablePolicy, identity_processors

    key = (str(ctx.dataset_root), ctx.data_keys.get("keyframe"), ctx.n_demos)
    if key not in _EPISODES:  # one read per dataset and subset, not one per suite
        _EPISODES[key] = adapters.load_train_episodes(ctx.dataset_root, limit=ctx.n_demos)
    episodes = _EPISODES[key]
    pre, post = identity_processors()
    return eval_lerobot_policy(LookupTablePolicy(episodes), pre, post, env_cfg, n, start_seed, batch_size)


def policy_settings(overrides: dict, ctx: TrainContext) -> dict:
    """A method's policy settings for its study and training data. A method that takes the recovering recipe
    takes the study's changes to it (``ctx.recipe_changes``: the paper study trains it with one LSTM layer).
    A recovering-mode window must hold the longest episode the recorded task allows (its keyframe budget + the
    final state: 41 frames on the ``full`` task, more than the study's recovery budget); the paper's task (10
    keyframes) leaves it unchanged. A study without recipe changes on the paper task keeps its training keys."""
    if overrides.get("mode") != "recovering":
        return overrides
    # a change reaches the settings the method keeps from the recipe (the told MLP keeps its own augmentation)
    kept = {k: v for k, v in ctx.recipe_changes.items() if overrides.get(k) == RECOVERING.get(k)}
    settings = {**overrides, **kept}
    if ctx.task_budget is not None:
        settings["max_episode_length"] = max(settings["max_episode_length"], ctx.task_budget + 1)
    return settings


def _pnp_lstm_trainer(overrides: dict, batch_size: int | None) -> Callable[[TrainContext], Path]:
    def train(ctx: TrainContext) -> Path:
        ckpt = adapters.checkpoint_of(ctx.train_dir)
        if (ckpt / "model.safetensors").is_file() and (ctx.train_dir / "test_keyframe_error.json").is_file():
            return ckpt  # finished earlier: reused
        return adapters.train_pnp_lstm(
            ctx.dataset_root,
            ctx.train_dir,
            ctx.seed,
            ctx.epochs,
            policy_settings(overrides, ctx),
            n_demos=ctx.n_demos,
            batch_size=batch_size or adapters.BATCH_SIZE,
        )

    return train


def _checkpoint_eval(artifact, ctx, env_cfg, n, start_seed, batch_size):
    lp = load_policy(artifact, env_cfg=env_cfg)
    return eval_lerobot_policy(lp.policy, lp.preprocessor, lp.postprocessor, env_cfg, n, start_seed, batch_size)


CLOCKED_WHY = (
    "the clocked planner trains on exactly 10-frame episodes (the paper's task); this task's demonstrations "
    "have recoveries (longer episodes of varying length)"
)


def pnp_lstm_method(name: str, label: str, description: str, **overrides) -> Method:
    """A ``pnp_lstm`` method; a recovering planner trains with the recipe's batch size, as DAgger does."""
    clocked = overrides.get("mode", "clocked") == "clocked"
    batch = None if clocked else RECOVERING_BATCH_SIZE
    return Method(name, label, description, True, _pnp_lstm_trainer(overrides, batch), _checkpoint_eval, overrides,
                  tasks=("paper",) if clocked else None, tasks_why=CLOCKED_WHY if clocked else "",
                  batch_size=batch)  # fmt: skip


# The recovering planner's recipe; its training windows hold the longest episode of the study (a recovery
# suite's budget + the final state: DAgger's rollouts are that long).
RECOVERING = {**RECOVERING_RECIPE, "max_episode_length": RECOVERY_BUDGET + 1}
# The memoryless controls take the recipe that gave each its best nominal success on the `full` task
# (docs/results/planner.md): the plain MLP with the late episodes, the phase-told one without.
# Without memory there is none to restart at a re-pick: memory_per_attempt is off (it would change nothing).
MEMORYLESS_MLP = {**RECOVERING, "recurrent": False, "memory_per_attempt": False}
PHASE_TOLD_MLP = {**RECOVERING, "recurrent": False, "latency_augment_prob": 0.0, "memory_per_attempt": False}
DAGGER_ROLLOUTS = 300  # policy episodes of the one DAgger round, cycled over the rollout suites
# the recipe's trunk as the method descriptions name it, read from the recipe so that a report cannot name another
RECOVERING_TRUNK = f"{RECOVERING['num_layers']} x {RECOVERING['hidden_size']} LSTM"
# DAgger's rounds in the study (Ross et al.'s mixture): round r's rollouts execute the expert's label at each step
# with probability DAGGER_BETA * 0.5 ** (r - 1), the policy's action otherwise, and every visited state is labelled.
# Pure on-policy rounds (beta 0) label only the first keyframe of each recovery (docs/results/dagger_curve.md).
DAGGER_ROUNDS = 2
DAGGER_BETA = 1.0
# rad of noise on each joint target the expert executes (docs/results/dart.md: about twice the grasp clearance)
DART_SIGMA = 0.02
# epochs of a DAgger round's training when it continues the previous round's weights (0: retrained from scratch).
# DART retrains from scratch: warm-started it lost the drop recovery (docs/results/dagger_curve.md, warm start)
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


def _dagger_train(ctx: TrainContext, name: str = "recovering_dagger") -> Path:
    """One round of ``lerobot_pnp.dagger`` on top of the ``recovering`` run of the same seed (trained first if
    missing), as the method's ``schedule`` sets it: DAgger's mixture under the recovery suites, or DART's noisy
    expert demonstrations of the undisturbed task."""
    from lerobot_pnp.dagger import DaggerConfig, run_dagger
    from lerobot_pnp.dagger.dart import DartNoise
    from lerobot_pnp.policy import PnpLstmConfig

    if ctx.n_demos is not None:
        raise ConfigError(f"method {name!r} has no data-efficiency variant")
    method = METHODS[name]
    schedule = copy.deepcopy(method.schedule)
    if "dart" in schedule:
        schedule["dart"] = DartNoise(**schedule["dart"])
    # a study with fewer epochs (--epochs) warm-starts for at most as many: never dearer than a retraining
    schedule["warm_start_epochs"] = min(schedule["warm_start_epochs"], ctx.epochs)
    round0, _ = keyed_train(METHODS[method.continues], _continued(ctx, method.continues))
    summary = run_dagger(
        DaggerConfig(
            **schedule,
            output_dir=str(ctx.train_dir),
            base_root=str(ctx.dataset_root),
            base_repo_id=f"local/{ctx.dataset_root.name}",
            round0_checkpoint=str(round0),
            eval_episodes=0,  # the study evaluates it like every other method
            policy=PnpLstmConfig(**policy_settings(RECOVERING, ctx)),
            epochs=ctx.epochs,
            batch_size=RECOVERING_BATCH_SIZE,
            seed=ctx.seed,
            progress=False,
        )
    )
    return Path(summary["final_checkpoint"])


def _retraining(schedule: dict) -> str:
    """How a round's policy is trained, for the method descriptions."""
    if epochs := schedule["warm_start_epochs"]:
        return f"the previous round's planner trained on for {epochs} epochs (warm start; at most the study's epochs)"
    return "retrained from scratch"


def _betas() -> str:
    s = DAGGER_SCHEDULE
    return ", ".join(f"{mixture_beta(s['beta'], s['beta_decay'], r):g}" for r in range(1, s["rounds"] + 1))


def _round_names() -> str:
    return ", ".join(str(r + 1) for r in range(DAGGER_SCHEDULE["rounds"]))


def _dart_train(ctx: TrainContext) -> Path:
    """DART (Laskey et al., 2017) at DAgger's budget: one round of ``DAGGER_ROLLOUTS`` expert demonstrations of
    the undisturbed task with Gaussian noise on the joint targets the expert executes, each frame labelled with
    its clean command; no disturbance is ever in the data."""
    return _dagger_train(ctx, "recovering_dart")


def _observe_phase(env_cfg: BaxterPnPEnvConfig, ctx: TrainContext) -> BaxterPnPEnvConfig:
    return env_cfg.with_changes(observe_phase=True)


def _act_budget(ctx: TrainContext):
    return act_baseline.ActBudget() if ctx.act_steps is None else act_baseline.ActBudget(steps=ctx.act_steps)


def _act_train(ctx: TrainContext) -> Path:
    if ctx.dense_root is None:
        raise ConfigError("method 'act' needs the dense dataset (TrainContext.dense_root)")
    ckpt, log, budget = adapters.checkpoint_of(ctx.train_dir), ctx.train_dir / "act_train.json", _act_budget(ctx)
    if (
        (ckpt / "model.safetensors").is_file()
        and log.is_file()
        and json.loads(log.read_text()).get("identity") == budget.identity()
    ):
        return ckpt  # finished earlier with this budget: reused
    if ctx.train_dir.exists():
        shutil.rmtree(ctx.train_dir)  # interrupted, or another budget: start over (a seed takes minutes)
    return act_baseline.train_act(ctx.dense_root, ctx.train_dir, ctx.seed, budget, n_demos=ctx.n_demos)


def _act_env(env_cfg: BaxterPnPEnvConfig, ctx: TrainContext) -> BaxterPnPEnvConfig:
    return act_baseline.dense_env(env_cfg, ctx.dense_root)


def _act_description() -> str:
    o = act_baseline.ACT_OVERRIDES
    return (
        "LeRobot ACT, state-only (joints + the environment state: object position; on `full` also its yaw and "
        f"the goal), no VAE, chunk {o['chunk_size']} / "
        f"{o['n_action_steps']} executed, width {o['dim_model']}, {o['n_encoder_layers']}+{o['n_decoder_layers']} "
        f"layers; trained on the dense recording of the same demonstrations ({act_baseline.ActBudget().describe()} per seed); "
        "run in dense control mode (20 fps)"
    )


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method(
            "expert",
            "expert (FSM)",
            "scripted feedback FSM; upper bound. It reads the simulator's state, so observation noise, bias and "
            "latency do not reach it: on those suites it is not a like-for-like bound",
            False,
            _no_training,
            _expert_eval,
        ),
        Method(
            "lookup_table",
            "lookup table",
            "open-loop replay of the nearest training episode (same inputs, same data)",
            False,
            _no_training,
            _lookup_eval,
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
            _pnp_lstm_trainer(PHASE_TOLD_MLP, RECOVERING_BATCH_SIZE),
            _checkpoint_eval,
            PHASE_TOLD_MLP,
            data="phase",
            adapt_env=_observe_phase,
            batch_size=RECOVERING_BATCH_SIZE,
        ),
        pnp_lstm_method(
            "recovering",
            "recovering LSTM",
            "one LSTM over the whole episode, no clock, learned subtask switch; the recipe of `configs/dagger.json` "
            f"({RECOVERING_TRUNK} trunk, late episodes, binary gripper, the observation gate, the arm held on the place's open, the memory restarted at each "
            "re-pick); recoveries only as the task "
            "demonstrates them (none on `paper`, every disturbance on `full`)",
            **RECOVERING,
        ),
        Method(
            "recovering_dagger",
            "recovering LSTM + DAgger",
            f"`recovering` of the same seed + {DAGGER_ROUNDS} DAgger rounds of "
            f"{DAGGER_SCHEDULE['rollouts_per_round']} rollouts under nominal, missed-grasp, drop, nudge and "
            "displacement conditions (Ross et al.'s mixture: each step executes the expert's label with "
            f"probability {_betas()} in rounds {_round_names()}, the policy's own action otherwise), every visited state "
            f"labelled by the expert, aggregated with the demonstrations and earlier rounds, each round "
            f"{_retraining(DAGGER_SCHEDULE)} (extra interactive data: what the teacher adds)",
            True,
            _dagger_train,
            _checkpoint_eval,
            RECOVERING,
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
            f"it executes, labelled with its clean commands, aggregated with the demonstrations, {_retraining(DART_SCHEDULE)} "
            "(no disturbance in its data)",
            True,
            _dart_train,
            _checkpoint_eval,
            RECOVERING,
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
            _act_description(),
            True,
            _act_train,
            _checkpoint_eval,
            data="dense",
            adapt_env=_act_env,
        ),
    )
}


def _continued(ctx: TrainContext, base: str) -> TrainContext:
    """The context of the run of the same seed that a method continues (``Method.continues``)."""
    return replace(ctx, train_dir=ctx.train_dir.parent.parent / base / ctx.train_dir.name)


def _policy_acts(schedule: dict | None) -> bool:
    """Whether the policy acts in some round of a DAgger ``schedule`` (a round's mixture weight below 1)."""
    if not schedule:
        return False
    return any(
        mixture_beta(schedule["beta"], schedule.get("beta_decay", 0.5), r) < 1 for r in range(1, schedule["rounds"] + 1)
    )


def train_stage(method: Method, ctx: TrainContext) -> Stage:
    """The key of a learned method's training: the method (its policy settings), the key of the recording
    it trains on, seed, epochs, demonstrations, ACT's steps, the run it continues, the code versions."""
    parts = {
        "stage": "train",
        "method": method.name,
        "overrides": policy_settings(method.policy_overrides, ctx),
        "data": ctx.data_keys.get(method.data),
        "seed": ctx.seed,
        "epochs": ctx.epochs,
        "n_demos": ctx.n_demos,
        # the loss curve's resolution (an output of the training): one held-out loss per whole-split epoch
        **({"heldout_every": "whole_split_epoch"} if ctx.n_demos is not None and method.data != "dense" else {}),
        "act_steps": ctx.act_steps if method.data == "dense" else None,
        "continues": train_stage(METHODS[method.continues], _continued(ctx, method.continues)).key
        if method.continues
        else None,
        "versions": code_versions(),
        **({"batch_size": method.batch_size} if method.batch_size is not None else {}),
        **({"schedule": method.schedule} if method.schedule else {}),
        # the DAgger teacher's version where the policy acts in some round (its rollouts key it too)
        **({"teacher": TEACHER_VERSION} if _policy_acts(method.schedule) else {}),
    }
    before = SCHEDULE_BEFORE_KEYED.get(method.name)
    return Stage(ctx.train_dir / STAGE_FILE, parts, added={"schedule": before} if before else None)


def keyed_train(method: Method, ctx: TrainContext) -> tuple[Path | None, bool]:
    """``method.train(ctx)`` unless a training of the same key is on disk: (artefact, trained now).

    A training folder without a matching record (another key, or killed midway) is deleted and trained
    again: what is in it is never trusted by its existence alone."""
    if not method.learned:
        return method.train(ctx), False
    stage = train_stage(method, ctx)
    if stage.done(f"training {method.name} {ctx.train_dir.name}"):
        return ctx.train_dir / stage.stored()["artifact"], False
    stage.invalidate()
    remove(ctx.train_dir)
    artifact = Path(method.train(ctx))
    stage.commit(artifact=str(artifact.resolve().relative_to(ctx.train_dir.resolve())))
    return artifact, True


# The methods trained again on fewer demonstrations (``StudyConfig.data_efficiency``): the paper's comparison.
DATA_EFFICIENCY_METHODS = ("lookup_table", "clocked_lstm")


def get_methods(names: list[str]) -> list[Method]:
    unknown = [n for n in names if n not in METHODS]
    if unknown:
        raise ConfigError(f"unknown method(s) {unknown}; valid: {sorted(METHODS)}")
    return [METHODS[n] for n in names]
