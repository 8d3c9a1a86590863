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


# The files with the longest tests first: xdist (`--dist loadfile`, the Makefile's) hands whole files to its two
# workers in collection order, so the long ones start at once and the short ones fill the end on both workers,
# instead of one worker finishing a long file alone while the other is idle.
_LONGEST_FIRST = (
    "test_cli.py",
    "test_report.py",
    "test_dataset.py",
    "test_dataset_robustness.py",
    "test_image_policies.py",
    "test_report_methods.py",
    "test_caches.py",
    "test_cli_errors.py",
    "test_train_fast.py",
    "test_report_heldout.py",
    "test_dataset_slurm.py",
)


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(_LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: a file's tests keep their order
