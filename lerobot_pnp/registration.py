"""The one place with import side effects: register the gymnasium env and LeRobot's env and policy configs."""

from __future__ import annotations

import os


def register_all() -> None:
    # Headless rendering by default (only used when a camera or render() is asked for).
    os.environ.setdefault("MUJOCO_GL", "egl")

    import gymnasium as gym

    from lerobot_pnp.env import DEFAULT_MAX_STEPS
    from lerobot_pnp.env_config import DENSE_FPS, DENSE_GYM_ID, GYM_ID, KEYFRAME_FPS

    if GYM_ID not in gym.registry:
        gym.register(
            id=GYM_ID,
            entry_point="lerobot_pnp.env:BaxterPnPEnv",
            max_episode_steps=DEFAULT_MAX_STEPS["keyframe"],
            kwargs={"control_mode": "keyframe", "fps": KEYFRAME_FPS},
        )
        gym.register(
            id=DENSE_GYM_ID,
            entry_point="lerobot_pnp.env:BaxterPnPEnv",
            max_episode_steps=DEFAULT_MAX_STEPS["dense"],
            kwargs={"control_mode": "dense", "fps": DENSE_FPS},
        )
    # LeRobot config registries (draccus choice registries) are filled by importing the modules.
    import lerobot_pnp.env_config  # noqa: F401
    import lerobot_pnp.policy  # noqa: F401
