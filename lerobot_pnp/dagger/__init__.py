"""``lerobot-pnp dagger``: DAgger for the pnp_lstm planner with the scripted expert as a free, perfect teacher.

Modules: ``config`` (DaggerConfig), ``rollouts`` (suites, expert demos, expert-labelled policy rollouts,
evaluation), ``writer`` (LeRobotDataset writing and aggregation), ``loop`` (the rounds and the table),
``stats`` (Wilson intervals).
"""

from .config import RECOVERING_RECIPE, DaggerConfig
from .loop import evaluate_checkpoint, run_dagger, write_table
from .rollouts import NOMINAL, SUITES, evaluate, labelled_rollout
from .stats import wilson

__all__ = [
    "NOMINAL",
    "RECOVERING_RECIPE",
    "SUITES",
    "DaggerConfig",
    "evaluate",
    "evaluate_checkpoint",
    "labelled_rollout",
    "run_dagger",
    "wilson",
    "write_table",
]
