"""How each method of ``methods.METHODS`` is trained and evaluated: the callables of its ``Method``.

A trainer takes a ``TrainContext`` and returns the artefact the evaluator runs (a checkpoint folder, or None
for the methods without training); an evaluator runs that artefact on an env config's seeds through stock
``eval_policy`` (the expert through its own loop).
"""

from __future__ import annotations

import copy
import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from lerobot_pnp.dagger import RECOVERING_BATCH_SIZE
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.checkpoints import load_policy
from lerobot_pnp.evaluation.closed_loop import eval_expert, eval_lerobot_policy
from lerobot_pnp.report import act_baseline, adapters, training
from lerobot_pnp.report.recipes import RECOVERING_STUDY_SETTINGS, policy_settings
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

if TYPE_CHECKING:
    from lerobot_pnp.report.method_spec import MethodOf, TrainContext


def no_training(ctx: TrainContext) -> None:
    return None


def expert_eval(artifact, ctx, env_cfg, n, start_seed, batch_size):
    return eval_expert(env_cfg, n, start_seed)


_EPISODES: dict[tuple[str, str | None, int | None], adapters.Episodes] = {}


def lookup_eval(artifact, ctx, env_cfg, n, start_seed, batch_size):
    from lerobot_pnp.report.baselines import LookupTablePolicy, identity_processors

    key = (str(ctx.dataset_root), ctx.data_keys.get("keyframe"), ctx.n_demos)
    if key not in _EPISODES:  # one read per dataset and subset, not one per suite
        _EPISODES[key] = adapters.load_train_episodes(ctx.dataset_root, limit=ctx.n_demos)
    episodes = _EPISODES[key]
    policy = LookupTablePolicy(episodes)  # the class lerobot-pnp lookup-table saves: the same table, the same replay
    pre, post = identity_processors(policy.config)
    return eval_lerobot_policy(policy, pre, post, env_cfg, n, start_seed, batch_size)


def pnp_lstm_trainer(overrides: dict, batch_size: int | None) -> Callable[[TrainContext], Path]:
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


def checkpoint_eval(artifact, ctx, env_cfg, n, start_seed, batch_size):
    lp = load_policy(artifact, env_cfg=env_cfg)
    return eval_lerobot_policy(lp.policy, lp.preprocessor, lp.postprocessor, env_cfg, n, start_seed, batch_size)


def dagger_train(ctx: TrainContext, name: str = "recovering_dagger", *, method_of: MethodOf) -> Path:
    """One round of ``lerobot_pnp.dagger`` on top of the ``recovering`` run of the same seed (trained first if
    missing), as the method's ``schedule`` sets it: DAgger's mixture under the recovery suites, or DART's noisy
    expert demonstrations of the undisturbed task. ``method_of``: the catalogue's method of a name."""
    from lerobot_pnp.dagger import DaggerConfig, run_dagger
    from lerobot_pnp.dagger.dart import DartNoise
    from lerobot_pnp.policy import PnpLstmConfig

    if ctx.n_demos is not None:
        raise ConfigError(f"method {name!r} has no data-efficiency variant")
    method = method_of(name)
    schedule = copy.deepcopy(method.schedule)
    if "dart" in schedule:
        schedule["dart"] = DartNoise(**schedule["dart"])
    # a study with fewer epochs (--epochs) warm-starts for at most as many: never dearer than a retraining
    schedule["warm_start_epochs"] = min(schedule["warm_start_epochs"], ctx.epochs)
    continued = training.continued(ctx, method.continues)
    round0, _ = training.keyed_train(method_of(method.continues), continued, method_of)
    summary = run_dagger(
        DaggerConfig(
            **schedule,
            output_dir=str(ctx.train_dir),
            base_root=str(ctx.dataset_root),
            base_repo_id=f"local/{ctx.dataset_root.name}",
            round0_checkpoint=str(round0),
            n_episodes=0,  # the study evaluates it like every other method
            policy=PnpLstmConfig(**policy_settings(RECOVERING_STUDY_SETTINGS, ctx)),
            epochs=ctx.epochs,
            batch_size=RECOVERING_BATCH_SIZE,
            seed=ctx.seed,
            progress=False,
        )
    )
    return Path(summary["final_checkpoint"])


def dart_train(ctx: TrainContext, *, method_of: MethodOf) -> Path:
    """DART (Laskey et al., 2017) at DAgger's budget: one round of ``DAGGER_ROLLOUTS`` expert demonstrations of
    the undisturbed task with Gaussian noise on the joint targets the expert executes, each frame labelled with
    its clean command; no disturbance is ever in the data."""
    return dagger_train(ctx, "recovering_dart", method_of=method_of)


def observe_phase(env_cfg: BaxterPnPEnvConfig, ctx: TrainContext) -> BaxterPnPEnvConfig:
    return env_cfg.with_changes(observe_phase=True)


def _act_budget(ctx: TrainContext):
    return act_baseline.ActBudget() if ctx.act_steps is None else act_baseline.ActBudget(steps=ctx.act_steps)


def act_train(ctx: TrainContext) -> Path:
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


def act_env(env_cfg: BaxterPnPEnvConfig, ctx: TrainContext) -> BaxterPnPEnvConfig:
    return act_baseline.dense_env(env_cfg, ctx.dense_root)


def act_description() -> str:
    o = act_baseline.ACT_OVERRIDES
    return (
        "LeRobot ACT, state-only (joints + the environment state: object position; on `full` also its yaw and "
        f"the goal), no VAE, chunk {o['chunk_size']} / "
        f"{o['n_action_steps']} executed, width {o['dim_model']}, {o['n_encoder_layers']}+{o['n_decoder_layers']} "
        f"layers; trained on the dense recording of the same demonstrations ({act_baseline.ActBudget().describe()} per seed); "
        "run in dense control mode (20 fps)"
    )
