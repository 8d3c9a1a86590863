import os

# Tiny models and a 2-core machine: one thread each, headless rendering.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import pytest

from lerobot_pnp.registration import register_all

register_all()  # the env, the policy and the task record, as LeRobot's plugin discovery does


@pytest.fixture
def keyframe_env():
    import gymnasium as gym

    env = gym.make("lerobot_pnp/BaxterPnP-v0")
    yield env
    env.close()
