"""The open-loop nearest-neighbour replay (the "lookup table"): the baseline a planner has to beat.

Same inputs and same data as the learned planners: at the first step of an episode it reads the observed
``environment_state`` (object position, plus yaw features and goal when the task observes them), finds the
training episode whose first ``environment_state`` is nearest (Euclidean, in metres), and then replays that
episode's recorded actions one per step, ignoring every later observation; past the recorded actions it
holds the last one. It is a ``PreTrainedPolicy`` so stock LeRobot ``eval_policy`` drives it exactly like a
trained checkpoint (identity pre/post-processors: it works in raw units).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from lerobot.configs import PreTrainedConfig
from lerobot.optim import AdamConfig
from lerobot.policies.pretrained import PreTrainedPolicy
from lerobot.processor import PolicyProcessorPipeline
from lerobot.utils.constants import OBS_ENV_STATE

from lerobot_pnp.errors import PolicyError
from lerobot_pnp.report.adapters import Episodes


@dataclass
class LookupTableConfig(PreTrainedConfig):
    """Not registered as a LeRobot policy type: it is built in memory from a dataset, never saved."""

    device: str | None = "cpu"
    push_to_hub: bool = False

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
        return None


class LookupTablePolicy(PreTrainedPolicy):
    """Replays the actions of the training episode whose start is nearest to the observed one."""

    config_class = LookupTableConfig
    name = "pnp_lookup_table"

    def __init__(self, episodes: Episodes):
        super().__init__(LookupTableConfig())
        if not episodes.actions:
            raise PolicyError("the lookup table needs at least one training episode")
        self.keys = torch.as_tensor(episodes.first_env_state, dtype=torch.float32)
        length = max(len(a) for a in episodes.actions)
        # (E, T_max, A), each episode padded with its last action (= hold)
        padded = [np.concatenate([a, np.repeat(a[-1:], length - len(a), axis=0)]) for a in episodes.actions]
        self.table = torch.as_tensor(np.stack(padded), dtype=torch.float32)
        self.reset()

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
        return torch.cdist(env_state.float().cpu(), self.keys).argmin(dim=1)

    @torch.no_grad()
    def select_action(self, batch: dict[str, torch.Tensor], **kwargs) -> torch.Tensor:
        if self._rows is None:
            self._rows = self.nearest(batch[OBS_ENV_STATE])
        step = min(self._step, self.table.shape[1] - 1)
        self._step += 1
        return self.table[self._rows, step]

    def predict_action_chunk(self, batch, **kwargs):
        return self.select_action(batch).unsqueeze(1)

    def forward(self, batch):
        raise PolicyError("the lookup table is built from data, not trained")

    def get_optim_params(self):
        return []


def identity_processors() -> tuple[PolicyProcessorPipeline, PolicyProcessorPipeline]:
    """Pre/post-processors for a policy that works in raw units (no normalisation, no device move)."""
    from lerobot.processor.converters import policy_action_to_transition, transition_to_policy_action

    post = PolicyProcessorPipeline(
        steps=[], to_transition=policy_action_to_transition, to_output=transition_to_policy_action
    )
    return PolicyProcessorPipeline(steps=[]), post
