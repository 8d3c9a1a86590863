"""The one place with import side effects: register the gymnasium envs and LeRobot's env and policy configs, and,
inside a stock ``lerobot-*`` script only, a ``sys.excepthook`` that prints our errors as one line
(``errors.install_cli_excepthook``; ``LEROBOT_PNP_DEBUG=1`` keeps the traceback)."""

from __future__ import annotations

import os


def register_all() -> None:
    # Headless rendering by default (only used when a camera or render() is asked for).
    os.environ.setdefault("MUJOCO_GL", "egl")

    import gymnasium as gym

    import lerobot_pnp.policy  # noqa: F401
    from lerobot_pnp.errors import install_cli_excepthook

    install_cli_excepthook()
    # LeRobot config registries (draccus choice registries) are filled by importing the modules.
    from lerobot_pnp import env_config

    # LeRobot's own --help of our configs (lerobot-train --env.type=baxter_pnp --help) as `lerobot-pnp --help`:
    # no derived fields (env.features, policy.input_features ...), LeRobot's undocumented fields described
    from lerobot_pnp.cli_help import annotate_stock_help
    from lerobot_pnp.policy import PnpLstmConfig
    from lerobot_pnp.policy.modeling_pnp_lstm import TaskRecord

    for config_class in (env_config.BaxterPnPEnvConfig, PnpLstmConfig):
        annotate_stock_help(config_class)
    # a pnp_lstm checkpoint records the task of its training dataset (the policy package knows no env)
    TaskRecord.read, TaskRecord.write = env_config.dataset_task, env_config.write_checkpoint_task
    # ... and so does any other policy's checkpoint written by stock lerobot-train (in that process only)
    from lerobot_pnp.stock_checkpoints import install_stock_checkpoint_hook

    install_stock_checkpoint_hook()
    # ... windows the phase labels for the recovering policy, and refuses in one line a stream LeRobot would
    # leave empty (--dataset.streaming with 0 workers)
    from lerobot_pnp.stock_train import install_stock_train_hooks

    install_stock_train_hooks()

    if env_config.GYM_ID not in gym.registry:
        gym.register(
            id=env_config.GYM_ID,
            entry_point="lerobot_pnp.env:BaxterPnPEnv",
        )  # no gymnasium TimeLimit: the env truncates at its config's episode_length
