"""Configuration of ``pnp_lookup_table``: the open-loop nearest-neighbour replay, the baseline a planner has to beat.

A policy type of its own so that the table is a checkpoint like any other: ``save_pretrained`` writes the training
episodes' first observed ``environment_state`` and their recorded actions into ``model.safetensors``, and stock
``lerobot-eval --policy.path`` loads it with no extra flag. Nothing is learned, so there is nothing to train: a
table is built from a dataset (``lerobot-pnp lookup-table``; the study builds the same class in memory). The config
records the table's size, so LeRobot's loader can allocate the tensors the file holds before it reads them, and
where the episodes came from.

LeRobot finds the classes by naming convention: ``PnpLookupTableConfig`` -> ``PnpLookupTablePolicy`` in
``modeling_pnp_lookup_table`` and ``make_pnp_lookup_table_pre_post_processors`` in ``processor_pnp_lookup_table``.
This module knows LeRobot features only (the policy package never imports the simulator).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.configs import NormalizationMode, PreTrainedConfig
from lerobot.optim import AdamConfig
from lerobot.utils.constants import ACTION, OBS_ENV_STATE

from lerobot_pnp.errors import ConfigError


@PreTrainedConfig.register_subclass("pnp_lookup_table")
@dataclass
class PnpLookupTableConfig(PreTrainedConfig):
    """The lookup table's shape and provenance; its inputs and output are ``input_features`` / ``output_features``
    (``observation.environment_state`` is the key it looks up, ``action`` what it replays)."""

    device: str | None = "cpu"
    push_to_hub: bool = False
    normalization_mapping: dict[str, NormalizationMode] = field(
        default_factory=lambda: {
            "STATE": NormalizationMode.IDENTITY,
            "ENV": NormalizationMode.IDENTITY,
            "ACTION": NormalizationMode.IDENTITY,
        }
    )
    """Raw units in and out: distances between starts are in metres, the replayed actions are the recorded ones."""
    table_episodes: int = 0
    """Episodes in the table (rows of ``model.safetensors``'s ``keys`` and ``actions``)."""
    table_steps: int = 0
    """Actions per row: the longest episode's; a shorter one is padded with its last action (the replay holds it)."""
    source: str = ""
    """The dataset and split the table was built from (provenance only)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.table_episodes < 0 or self.table_steps < 0:
            raise ConfigError(
                f"pnp_lookup_table: table_episodes and table_steps must be >= 0, got "
                f"{self.table_episodes} and {self.table_steps}"
            )

    @property
    def observation_delta_indices(self):
        return None

    @property
    def action_delta_indices(self):
        return None

    @property
    def reward_delta_indices(self):
        return None

    def get_optimizer_preset(self):
        return AdamConfig()

    def get_scheduler_preset(self):
        return None

    def validate_features(self) -> None:
        """It looks up the environment state and replays actions: it needs both features."""
        missing = [k for k, fts in ((OBS_ENV_STATE, self.input_features), (ACTION, self.output_features))
                   if k not in (fts or {})]  # fmt: skip
        if missing:
            raise ConfigError(f"pnp_lookup_table needs the features {missing} (a dataset of the baxter_pnp task)")
