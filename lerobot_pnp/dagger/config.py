"""Configuration of ``lerobot-pnp dagger`` (validated when built: a bad flag is one clear ConfigError)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.policy import PnpLstmConfig
from lerobot_pnp.policy.recipes import RECOVERING_RECIPE
from lerobot_pnp.presets import TASK_FIELDS
from lerobot_pnp.sim.suites import SUITES

from .dart import DartNoise

# The default rollouts have no observation latency. Rollouts under latency are allowed (a rollout records the
# current state, and training shows half of all episodes late, policy.latency_augment_*), but the expert labels
# what a late planner cannot see yet, so such a round hurts (docs/guides/dagger-dart.md).
DEFAULT_ROLLOUT_SUITES = ["nominal", "quiet_grasp_miss", "quiet_drop", "quiet_nudge_0.03", "quiet_displace"]
DEFAULT_EVAL_SUITES = [
    "quiet", "quiet_grasp_miss", "quiet_drop", "quiet_nudge_0.03", "quiet_displace", "quiet_noise_latency",
]  # fmt: skip

# DAgger's own suite names before the one catalogue (lerobot_pnp.sim.suites), and the catalogue entry
# with the same env changes. Several old names are catalogue names with another meaning (DAgger's "nominal" had
# every perturbation off; the catalogue's is the training task unchanged), so a list that still holds one of
# the retired names is refused with the renames, rather than read with the new meanings.
_RENAMED = {
    "full": "nominal",
    "nominal": "quiet",
    "grasp_miss": "quiet_grasp_miss",
    "drop": "quiet_drop",
    "nudge": "quiet_nudge_0.03",
    "displace": "quiet_displace",
    "noise_latency": "quiet_noise_latency",
    "noise": "quiet_noise",
    "bias": "quiet_bias",
    "latency": "quiet_latency",
}


def _suite_problems(field_name: str, names: list[str]) -> list[str]:
    """What is wrong with the list ``field_name`` of suite names (retired DAgger names, unknown or multi-part)."""
    if any(s in _RENAMED and s not in SUITES for s in names):
        renames = ", ".join(f"{s!r} -> {_RENAMED[s]!r}" for s in dict.fromkeys(names) if s in _RENAMED)
        return [f"{field_name} {names} uses DAgger's old suite names; rename them: {renames}"]
    problems = []
    if unknown := [s for s in names if s not in SUITES]:
        problems.append(f"{field_name}: unknown suites {unknown}; choose from {sorted(SUITES)}")
    if multi := [s for s in names if s in SUITES and len(SUITES[s].parts) != 1]:
        problems.append(f"{field_name}: suites {multi} have several parts; DAgger runs one env per suite")
    return problems


RECOVERING_BATCH_SIZE = 32  # episodes per batch of the recipe (DAgger's default, the held-out protocol's)
# epochs between two held-out losses of a recipe training (no figure reads its curve; a pass over the held-out
# episodes costs about a tenth of an epoch's training)
RECOVERING_CURVE_EVERY = 10


def _recovering_policy() -> PnpLstmConfig:
    return PnpLstmConfig(**RECOVERING_RECIPE)


def mixture_beta(beta: float, beta_decay: float, rnd: int) -> float:
    """Round ``rnd >= 1``'s mixture weight: ``beta * beta_decay ** (rnd - 1)`` (``beta_i = p^(i-1)`` in Ross et al.)."""
    return beta * beta_decay ** (rnd - 1)


@dataclass
class DaggerConfig:
    """DAgger with the scripted expert as teacher.

    Round 0 trains on expert demonstrations of the task; round ``r >= 1`` rolls out the round ``r-1`` policy
    mixed with the expert (``beta``; by default the policy's own actions are executed) under ``rollout_suites``,
    labels every visited state with the expert's ``Teacher`` (``rollouts``: the FSM continued while the policy
    follows its labels, ``FSMExpert.label()`` where it does not), aggregates the labelled episodes with
    everything before (LeRobot's ``aggregate_datasets``) and retrains, from scratch or warm-started
    (``warm_start_epochs``; see ``loop``). Each round is evaluated on the same
    seeds. Everything lives in ``output_dir``; a finished step (dataset, checkpoint, evaluation) is reused
    while its key (the settings and inputs it was made from) is unchanged, so an interrupted run continues
    where it stopped and a changed flag re-runs what depends on it. Deterministic given ``seed``.

    Args:
        output_dir: Where the datasets, checkpoints, evaluations and ``table.md`` go.
        preset: Task preset of the demonstrations (``full``); ignored with ``base_root``.
        env_changes: Task fields set on top of the preset (or of ``base_root``'s recorded task), e.g.
            ``{"observe_phase": true}`` for the phase-told memoryless control; validated by the env config.
        base_root: An existing keyframe dataset folder (its recorded task defines the env) used as the round-0
            data instead of generating ``num_episodes`` demonstrations.
        base_repo_id: The repo id of ``base_root``; also the stem of the repo ids of the datasets written here.
        round0_checkpoint: A policy already trained on the round-0 data (a ``pretrained_model`` folder): round 0
            is not trained again, the first rollouts run this policy (the study's ``recovering_dagger``
            continues its ``recovering`` run of the same seed this way).
        num_episodes: Round-0 expert demonstrations, generated by the dataset pipeline in the task as recorded
            (recoveries included); slot ``i`` is seed ``seed + i``; the last ``test_fraction`` is held out.
        rounds: DAgger rounds after round 0.
        rollouts_per_round: Policy episodes per round, cycled over ``rollout_suites``.
        beta: Round 1's mixture weight (Ross et al.): at each rollout step the expert's label is executed with
            probability ``beta``, the policy's action otherwise; every visited state is labelled either way. With
            ``0`` a policy that does not yet recover only visits the first state of a recovery, so a round teaches
            one more recovery keyframe at most; with ``1`` round 1 visits whole recoveries
            (docs/guides/dagger-dart.md).
        beta_decay: Round ``r``'s weight is ``beta * beta_decay ** (r - 1)`` (``beta_i = p^(i-1)`` in the paper).
        dart: DART's noise (``dagger.dart``) on the expert's executed labels (``--dart.sigma`` rad on each
            joint target, ``--dart.gripper_flip`` probability per step); the frames keep the clean labels. With
            ``beta = 1`` a round's rollouts are noisy expert demonstrations: DART. Off by default.
        test_fraction: The fraction of the round-0 episodes (the last ones) held out of training.
        rollout_suites: Suites of the one catalogue (``lerobot_pnp.sim.suites``, one part each) that the
            rollouts cycle over: ``nominal`` (the task as recorded), the ``quiet*`` suites (every perturbation off,
            then one at a time).
        eval_suites: The suites every round's policy is evaluated on (same catalogue).
        n_episodes: Evaluation episodes per suite.
        eval_seed: Evaluation episode ``i`` uses seed ``eval_seed + i``, the same every round.
        policy: The ``pnp_lstm`` config trained each round (``--policy.mode=recovering`` by default).
        epochs: Training epochs of each round (the fast path, ``lerobot-pnp train``).
        warm_start_epochs: ``0``: each round after round 0 retrains from scratch on the aggregate. ``> 0``:
            each such round continues the previous round's weights and normalisation statistics for this many
            epochs instead (cheaper; not neutral: DART warm-started loses its drop recovery).
        batch_size: Episodes per training batch.
        seed: The seed of the demonstrations, rollouts and training (the run is deterministic given it).
        progress: Show progress bars (demonstrations, rollouts, training, evaluation).
    """

    output_dir: str = "outputs/dagger"
    preset: str = "full"
    env_changes: dict[str, Any] = field(default_factory=dict)
    base_root: str | None = None
    base_repo_id: str = "local/baxter_pnp_full"
    round0_checkpoint: str | None = None
    num_episodes: int = 600
    test_fraction: float = 0.1
    rounds: int = 1
    rollouts_per_round: int = 300
    beta: float = 0.0
    beta_decay: float = 0.5
    dart: DartNoise = field(default_factory=DartNoise)
    rollout_suites: list[str] = field(default_factory=lambda: list(DEFAULT_ROLLOUT_SUITES))
    eval_suites: list[str] = field(default_factory=lambda: list(DEFAULT_EVAL_SUITES))
    n_episodes: int = 200
    eval_seed: int = 10_000_000
    policy: PnpLstmConfig = field(default_factory=_recovering_policy)
    epochs: int = 100
    warm_start_epochs: int = 0
    batch_size: int = RECOVERING_BATCH_SIZE
    seed: int = 0
    progress: bool = True

    def beta_of(self, rnd: int) -> float:
        """The mixture weight of round ``rnd >= 1``'s rollouts."""
        return mixture_beta(self.beta, self.beta_decay, rnd)

    def __post_init__(self) -> None:
        checks = [
            *((False, problem) for problem in _suite_problems("rollout_suites", self.rollout_suites)),
            *((False, problem) for problem in _suite_problems("eval_suites", self.eval_suites)),
            (self.rounds >= 0, f"rounds must be >= 0, got {self.rounds}"),
            (self.num_episodes >= 2, f"num_episodes must be >= 2, got {self.num_episodes}"),
            (0.0 < self.test_fraction < 1.0, f"test_fraction must be in (0, 1), got {self.test_fraction}"),
            (self.rollouts_per_round >= 1, f"rollouts_per_round must be >= 1, got {self.rollouts_per_round}"),
            (0.0 <= self.beta <= 1.0, f"beta must be in [0, 1], got {self.beta}"),
            (0.0 <= self.beta_decay <= 1.0, f"beta_decay must be in [0, 1], got {self.beta_decay}"),
            (
                self.beta > 0.0 or not self.dart.active,
                f"dart noise {self.dart} is added to the expert's executed labels; with beta 0 the expert never "
                "acts: set beta > 0 (1 for DART)",
            ),
            (self.n_episodes >= 0, f"n_episodes must be >= 0, got {self.n_episodes}"),
            (self.epochs >= 1, f"epochs must be >= 1, got {self.epochs}"),
            (self.batch_size >= 1, f"batch_size must be >= 1 (episodes per training batch), got {self.batch_size}"),
            (
                isinstance(self.warm_start_epochs, int) and self.warm_start_epochs >= 0,
                f"warm_start_epochs must be an integer >= 0 (0: retrain from scratch), got {self.warm_start_epochs!r}",
            ),
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
