"""What a method of the study is (``Method``) and what its training is given (``TrainContext``): the types the
catalogue (``methods``), its trainers and evaluators (``builders``), its recipes and its keyed training
(``training``) share, below all of them."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from lerobot_pnp.env_config import BaxterPnPEnvConfig
from lerobot_pnp.evaluation.records import EpisodeRecord


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


# A method of the catalogue by its name (``methods.METHODS``), handed down by the catalogue to what needs another
# method: the training a method continues (``Method.continues``)
MethodOf = Callable[[str], Method]
