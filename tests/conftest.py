import os
import subprocess
from pathlib import Path

# Tiny models and a 2-core machine: one thread each, headless rendering.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import pytest

from lerobot_pnp.integration.registration import register_all

register_all()  # the env, the policy and the task record, as LeRobot's plugin discovery does

# the one-node SLURM cluster that .ci/run starts (the `cluster` fixture starts it where it is down, as root)
CLUSTER = Path(__file__).resolve().parents[1] / "benchmarks" / "slurm_local_cluster.sh"


def pytest_collection_modifyitems(config, items):
    """On an xdist worker, the files that hold a ``slow`` test first (each file in its place otherwise).

    ``make test`` hands out whole files (``--dist loadfile``) in collection order (``--no-loadscope-reorder``):
    the long files start first, and the many short ones fill in the end, so that the workers finish together
    instead of one starting a long file while another runs out of work.
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


@pytest.fixture(scope="module")
def cluster():
    """The one-node cluster's default partition, started first where SLURM is installed but down (as root)."""
    up = subprocess.run(["sinfo", "-h", "-o", "%P %T"], capture_output=True, text=True, timeout=30)
    if up.returncode != 0 and os.geteuid() == 0:
        subprocess.run([str(CLUSTER), "start"], check=True, capture_output=True, timeout=120)
        up = subprocess.run(["sinfo", "-h", "-o", "%P %T"], capture_output=True, text=True, timeout=30)
    assert up.returncode == 0, f"SLURM is installed but no controller answers: {up.stderr.strip()}"
    return up.stdout.split()[0].rstrip("*")  # the default partition
