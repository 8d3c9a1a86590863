"""``config.mode`` -> its planner: the one place in the policy's model code that switches on the mode.

(The config itself derives LeRobot's sampling contract from the mode: ``window_length``, ``drop_n_last_frames``.)
"""

from __future__ import annotations

from torch import nn

from .clocked import ClockedPlanner
from .configuration_pnp_lstm import MODES, PnpLstmConfig
from .recovering import RecoveringPlanner

PLANNERS: dict[str, type[nn.Module]] = {"clocked": ClockedPlanner, "recovering": RecoveringPlanner}
assert tuple(PLANNERS) == MODES, "every mode of the config has a planner"


def build_planner(config: PnpLstmConfig, input_dim: int, action_dim: int) -> nn.Module:
    """The planner of ``config.mode`` (a ``planner.Planner``), its weights freshly initialised."""
    return PLANNERS[config.mode](config, input_dim, action_dim)
