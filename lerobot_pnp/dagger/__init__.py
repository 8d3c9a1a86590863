"""``lerobot-pnp dagger``: DAgger for the pnp_lstm planner with the scripted expert as a free, perfect teacher.

Modules: ``config`` (DaggerConfig), ``rollouts`` (suite envs, expert demos, expert-labelled policy rollouts,
evaluation), ``writer`` (LeRobotDataset writing and aggregation), ``loop`` (the rounds), ``folder`` (the output
folder: what a run records as its own, the table).
The suites and the statistics are ``lerobot_pnp.evaluation``'s.
"""

from .config import RECOVERING_BATCH_SIZE, DaggerConfig
from .folder import write_table
from .loop import evaluate_checkpoint, run_dagger
from .rollouts import evaluate, labelled_rollout

__all__ = [
    "RECOVERING_BATCH_SIZE",
    "DaggerConfig",
    "evaluate",
    "evaluate_checkpoint",
    "labelled_rollout",
    "run_dagger",
    "write_table",
]
