import os

# Tiny models and a 2-core machine: one thread each, headless rendering.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import pytest

import lerobot_pnp  # noqa: F401  (registers the env and policy)


@pytest.fixture
def keyframe_env():
    import gymnasium as gym

    env = gym.make("lerobot_pnp/BaxterPnP-v0")
    yield env
    env.close()
