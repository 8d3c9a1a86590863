import os

# Tiny models and a 2-core machine: one thread each, headless rendering.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import pytest

from lerobot_pnp.registration import register_all

register_all()  # the env, the policy and the task record, as LeRobot's plugin discovery does


def pytest_collection_modifyitems(config, items):
    """On an xdist worker, the files that hold a ``slow`` test first (each file in its place otherwise).

    ``make test`` hands out whole files (``--dist loadfile``) in collection order (``--no-loadscope-reorder``):
    the long files start first, and the many short ones fill in the end, so that the two workers finish together
    instead of one starting a long file while the other runs out of work.
    """
    if not hasattr(config, "workerinput"):
        return
    slow = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow)  # stable: the tests of a file keep their order


@pytest.fixture
def keyframe_env():
    import gymnasium as gym

    env = gym.make("lerobot_pnp/BaxterPnP-v0")
    yield env
    env.close()
