"""Configuration of ``lerobot-pnp dagger`` (validated when built: a bad flag is one clear ConfigError)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lerobot_pnp.env_config import TASK_FIELDS
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.policy import PnpLstmConfig

from .rollouts import SUITES

# Rollouts under observation latency are left out by default: their recorded observations are already late,
# and training shows half of all episodes one step later still (policy.latency_augment_prob). With an earlier
# recipe that had no late episodes, adding them also cost nominal success (round 1: 93 % with, 98.5 % without).
DEFAULT_ROLLOUT_SUITES = ["full", "grasp_miss", "drop", "nudge", "displace"]
DEFAULT_EVAL_SUITES = ["nominal", "grasp_miss", "drop", "nudge", "displace", "noise_latency"]


# The recovering planner's recipe (``configs/dagger.json``; how each part was chosen: docs/results/planner.md).
# The study (``lerobot_pnp.report``) trains the same recipe on its own data.
RECOVERING_RECIPE: dict[str, Any] = {
    "mode": "recovering",
    "hidden_size": 256,
    "optimizer_lr": 3e-3,
    "lr_scheduler": "cosine",
    "scheduler_warmup_steps": 200,
    "latency_augment_prob": 0.5,
    "binary_gripper": True,
}


def _recovering_policy() -> PnpLstmConfig:
    return PnpLstmConfig(**RECOVERING_RECIPE)


@dataclass
class DaggerConfig:
    """DAgger with the scripted expert as teacher.

    Round 0 trains on expert demonstrations of the task; round ``r >= 1`` rolls out the round ``r-1`` policy
    (its own actions are executed) under ``rollout_suites``, labels every visited state with
    ``FSMExpert(env).label()``, aggregates the labelled episodes with everything before (LeRobot's
    ``aggregate_datasets``) and retrains from scratch (see ``loop``). Each round is evaluated on the same
    seeds. Everything lives in ``output_dir``; a finished step (dataset, checkpoint, evaluation) is reused, so
    an interrupted run continues where it stopped. Deterministic given ``seed``.

    Args:
        output_dir: Where the datasets, checkpoints, evaluations and ``table.md`` go.
        preset: Task preset of the demonstrations (``full``); ignored with ``base_root``.
        env_changes: Task fields set on top of the preset (or of ``base_root``'s recorded task), e.g.
            ``{"observe_phase": true}`` for the phase-told memoryless control; validated by the env config.
        base_root / base_repo_id: An existing keyframe dataset (its recorded task defines the env) used as the
            round-0 data instead of generating ``num_demos`` demonstrations.
        round0_checkpoint: A policy already trained on the round-0 data (a ``pretrained_model`` folder): round 0
            is not trained again, the first rollouts run this policy (the study's ``recovering_dagger``
            continues its ``recovering`` run of the same seed this way).
        num_demos: Expert demonstrations generated for round 0 by the dataset pipeline (``full`` task as
            recorded: every perturbation at its preset probability, so recoveries are demonstrated; slot ``i`` is
            seed ``seed + i``, reseeded as ``lerobot-pnp generate`` does); the last ``test_fraction`` is held out
            (``lerobot_pnp.dataset.splits.test_split``).
        rounds: DAgger rounds after round 0.
        rollouts_per_round: Policy episodes per round, cycled over ``rollout_suites``.
        eval_suites / eval_episodes / eval_seed: The evaluation (same seeds ``eval_seed + i`` every round).
        policy: The ``pnp_lstm`` config trained each round (``--policy.mode=recovering`` by default).
        epochs / batch_size / seed: Fast-path training of each round.
    """

    output_dir: str = "outputs/dagger"
    preset: str = "full"
    env_changes: dict[str, Any] = field(default_factory=dict)
    base_root: str | None = None
    base_repo_id: str = "local/baxter_pnp_full"
    round0_checkpoint: str | None = None
    num_demos: int = 600
    test_fraction: float = 0.1
    rounds: int = 1
    rollouts_per_round: int = 300
    rollout_suites: list[str] = field(default_factory=lambda: list(DEFAULT_ROLLOUT_SUITES))
    eval_suites: list[str] = field(default_factory=lambda: list(DEFAULT_EVAL_SUITES))
    eval_episodes: int = 200
    eval_seed: int = 10_000_000
    policy: PnpLstmConfig = field(default_factory=_recovering_policy)
    epochs: int = 100
    batch_size: int = 32
    seed: int = 0
    progress: bool = True

    def __post_init__(self) -> None:
        unknown = [s for s in (*self.rollout_suites, *self.eval_suites) if s not in SUITES]
        checks = [
            (not unknown, f"unknown suites {unknown}; choose from {sorted(SUITES)}"),
            (self.rounds >= 0, f"rounds must be >= 0, got {self.rounds}"),
            (self.num_demos >= 2, f"num_demos must be >= 2, got {self.num_demos}"),
            (0.0 < self.test_fraction < 1.0, f"test_fraction must be in (0, 1), got {self.test_fraction}"),
            (self.rollouts_per_round >= 1, f"rollouts_per_round must be >= 1, got {self.rollouts_per_round}"),
            (self.eval_episodes >= 0, f"eval_episodes must be >= 0, got {self.eval_episodes}"),
            (self.epochs >= 1 and self.batch_size >= 1, "epochs and batch_size must be >= 1"),
            (bool(self.rollout_suites), "rollout_suites must not be empty"),
            (
                self.round0_checkpoint is None or Path(self.round0_checkpoint, "config.json").is_file(),
                f"round0_checkpoint {self.round0_checkpoint} is not a policy checkpoint (no config.json)",
            ),
            (
                not (bad := sorted(set(self.env_changes) - set(TASK_FIELDS))),
                f"env_changes has unknown task fields {bad}; valid: {sorted(TASK_FIELDS)}",
            ),
        ]
        for ok, message in checks:
            if not ok:
                raise ConfigError(f"dagger: {message}")
