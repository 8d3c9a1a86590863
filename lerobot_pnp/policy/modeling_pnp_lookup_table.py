"""``PnpLookupTablePolicy``: replays the actions of the training episode whose start is nearest to the observed one.

Same inputs and same data as the learned planners: at the first step of an episode it reads the observed
``environment_state`` (object position, plus yaw features and goal when the task observes them), finds the training
episode whose first ``environment_state`` is nearest (Euclidean, in metres), and then replays that episode's
recorded actions one per step, ignoring every later observation; past the recorded actions it holds the last one.

The table is the model: buffers ``keys`` (E, D), the episodes' first environment states, ``actions`` (E, T, A), each
episode's recorded actions padded with its last one, and ``lengths`` (E,), how many of them were recorded. They are
what ``save_pretrained`` writes to ``model.safetensors`` and ``from_pretrained`` reads back (every buffer required,
every value finite). A ``PreTrainedPolicy`` so that stock LeRobot ``eval_policy`` drives it exactly like a trained
checkpoint.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from lerobot.configs import FeatureType, PolicyFeature
from lerobot.policies.pretrained import PreTrainedPolicy
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE

from lerobot_pnp.errors import PolicyError

from .configuration_pnp_lookup_table import PnpLookupTableConfig
from .weights import non_finite_weights

STATE_DIM = 8  # joints + gripper: the robot state the env observes (the table does not read it)


def table_config(starts: np.ndarray, actions: Sequence[np.ndarray], source: str = "") -> PnpLookupTableConfig:
    """The config of a table over episodes with first environment states ``starts`` (E, D) and ``actions``."""
    if len(actions) == 0:
        raise PolicyError("the lookup table needs at least one training episode")
    if len(starts) != len(actions):
        raise PolicyError(f"lookup table: {len(starts)} episode starts for {len(actions)} episodes")
    return PnpLookupTableConfig(
        input_features={
            OBS_STATE: PolicyFeature(type=FeatureType.STATE, shape=(STATE_DIM,)),
            OBS_ENV_STATE: PolicyFeature(type=FeatureType.ENV, shape=(int(np.shape(starts)[1]),)),
        },
        output_features={ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(int(np.shape(actions[0])[1]),))},
        table_episodes=len(actions),
        table_steps=max(len(a) for a in actions),
        source=source,
    )


class PnpLookupTablePolicy(PreTrainedPolicy):
    """Open-loop nearest-neighbour replay (see the module docstring); ``from_episodes`` builds one from data."""

    config_class = PnpLookupTableConfig
    name = "pnp_lookup_table"

    def __init__(self, config: PnpLookupTableConfig, **kwargs):
        super().__init__(config)
        config.validate_features()
        dim = config.input_features[OBS_ENV_STATE].shape[0]
        action_dim = config.output_features[ACTION].shape[0]
        e, t = config.table_episodes, config.table_steps
        self.register_buffer("keys", torch.zeros(e, dim))
        self.register_buffer("actions", torch.zeros(e, t, action_dim))
        self.register_buffer("lengths", torch.zeros(e, dtype=torch.int64))
        self.reset()

    @classmethod
    def from_episodes(cls, starts: np.ndarray, actions: Sequence[np.ndarray], source: str = ""):
        """A table over episodes whose first environment state is ``starts[i]`` and recorded actions ``actions[i]``."""
        policy = cls(table_config(starts, actions, source))
        policy.fill(starts, actions)
        return policy

    def fill(self, starts: np.ndarray, actions: Sequence[np.ndarray]) -> None:
        """Set the table's rows (shapes as the config says)."""
        length = self.config.table_steps
        padded = [np.concatenate([a, np.repeat(a[-1:], length - len(a), axis=0)]) for a in actions]
        self.keys.copy_(torch.as_tensor(np.asarray(starts), dtype=torch.float32))
        self.actions.copy_(torch.as_tensor(np.stack(padded), dtype=torch.float32))
        self.lengths.copy_(torch.as_tensor([len(a) for a in actions], dtype=torch.int64))

    def episodes(self) -> tuple[np.ndarray, list[np.ndarray]]:
        """The table's episodes as recorded: their first environment states and their actions (no padding)."""
        acts = self.actions.cpu().numpy()
        return self.keys.cpu().numpy(), [acts[i, :n] for i, n in enumerate(self.lengths.tolist())]

    @classmethod
    def _load_as_safetensor(cls, model, model_file: str, map_location: str, strict: bool):
        """Every buffer required (LeRobot's default, non-strict, would keep a missing table's zeros), every value
        finite."""
        model = super()._load_as_safetensor(model, model_file, map_location, True)
        bad = non_finite_weights(model.state_dict())
        if bad:
            raise PolicyError(f"lookup table {model_file}: non-finite values in {bad}")
        if model.config.table_episodes < 1:
            raise PolicyError(f"lookup table {model_file}: the table holds no episode")
        return model

    def reset(self) -> None:
        self._rows: torch.Tensor | None = None
        self._step = 0

    def nearest(self, env_state: torch.Tensor) -> torch.Tensor:
        """Row of the nearest training episode for each observed start ``(B, D)``."""
        if env_state.shape[-1] != self.keys.shape[-1]:
            raise PolicyError(
                f"lookup table: observed environment_state has {env_state.shape[-1]} values, the training data "
                f"{self.keys.shape[-1]} (evaluate on the task the dataset was recorded with)"
            )
        return torch.cdist(env_state.float().to(self.keys.device), self.keys).argmin(dim=1)

    @torch.no_grad()
    def select_action(self, batch: dict[str, torch.Tensor], **kwargs) -> torch.Tensor:
        if self._rows is None:
            self._rows = self.nearest(batch[OBS_ENV_STATE])
        step = min(self._step, self.actions.shape[1] - 1)
        self._step += 1
        return self.actions[self._rows, step]

    def predict_action_chunk(self, batch, **kwargs):
        return self.select_action(batch).unsqueeze(1)

    def forward(self, batch):
        raise PolicyError("the lookup table is built from data, not trained (lerobot-pnp lookup-table)")

    def get_optim_params(self):
        return []
