"""What registers where, light at import (no torch, LeRobot or MuJoCo until a function runs).

Importing the package runs ``register_gym`` only: the gymnasium id (gymnasium alone), so the constants
(``robot``, ``presets``) stay cheap to import. LeRobot's env config ``baxter_pnp`` registers when ``env_config``
is imported, the policy ``pnp_lstm`` when ``lerobot_pnp.policy`` is. ``register_all`` is what LeRobot's plugin
discovery runs (through the ``lerobot_policy_pnp_lstm`` shim) and so do our own entry points (``lerobot-pnp``,
the tests, the benchmarks): both configs, the task record of pnp_lstm checkpoints, and inside a stock
``lerobot-*`` script its hooks: a ``sys.excepthook`` that prints our errors as one line
(``errors.install_cli_excepthook``; ``LEROBOT_PNP_DEBUG=1`` keeps the traceback), every checkpoint recording
its task (``stock_checkpoints``), and the task source its command line names handed to the env config.
"""

from __future__ import annotations

import functools
import os


def register_gym() -> None:
    """The gymnasium env ``lerobot_pnp/BaxterPnP-v0`` (no gymnasium TimeLimit: the env truncates at its
    config's episode_length); headless rendering by default (only used when a camera or render() is asked for)."""
    os.environ.setdefault("MUJOCO_GL", "egl")

    import gymnasium as gym

    from lerobot_pnp.presets import GYM_ID

    if GYM_ID not in gym.registry:
        gym.register(id=GYM_ID, entry_point="lerobot_pnp.env:BaxterPnPEnv")


def register_task_record() -> None:
    """A pnp_lstm checkpoint records the task of its training dataset (the policy package knows no env); the
    record is validated against ``baxter_pnp``, which importing ``env_config`` registers."""
    from lerobot_pnp import env_config  # noqa: F401
    from lerobot_pnp.policy.modeling_pnp_lstm import TaskRecord
    from lerobot_pnp.recorded_task import dataset_task, write_checkpoint_task

    TaskRecord.read, TaskRecord.write = dataset_task, write_checkpoint_task


def hand_over_command_line() -> None:
    """Inside a stock ``lerobot-*`` script, the task source its command line names (``stock_cli``) becomes the
    default of every preset-less env config: LeRobot's parser hands the env config none of its sibling fields."""
    from lerobot_pnp.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.stock_cli import stock_script, task_source_from_argv

    if stock_script() is not None:
        BaxterPnPEnvConfig.command_line_source = task_source_from_argv()


@functools.cache
def register_all() -> None:
    """Everything above, once per process."""
    register_gym()

    import lerobot_pnp.policy  # noqa: F401  (LeRobot's config registries are filled by importing the modules)
    from lerobot_pnp.errors import install_cli_excepthook
    from lerobot_pnp.stock_checkpoints import install_stock_checkpoint_hook

    install_cli_excepthook()
    register_task_record()
    # ... and any other policy's checkpoint written by stock lerobot-train (in that process only)
    install_stock_checkpoint_hook()
    # ... windows the phase labels for the recovering policy, and refuses in one line a stream LeRobot would
    # leave empty (--dataset.streaming with 0 workers)
    from lerobot_pnp.stock_train import install_stock_train_hooks

    install_stock_train_hooks()
    # LeRobot's own --help of our configs (lerobot-train --env.type=baxter_pnp --help) as `lerobot-pnp --help`:
    # no derived fields (env.features, policy.input_features ...), LeRobot's undocumented fields described
    from lerobot_pnp.cli_help import annotate_stock_help
    from lerobot_pnp.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.policy import PnpLstmConfig

    for config_class in (BaxterPnPEnvConfig, PnpLstmConfig):
        annotate_stock_help(config_class)
    hand_over_command_line()
