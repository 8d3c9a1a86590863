"""Packaging: LeRobot discovers the plugin with no flags, the MJCF ships in the wheel, async vector envs work."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_lerobot_discovers_the_plugin_by_distribution_name():
    # A fresh interpreter that never imports lerobot_pnp itself: LeRobot's own discovery must register both.
    code = (
        "from lerobot.utils.import_utils import register_third_party_plugins\n"
        "register_third_party_plugins()\n"
        "from lerobot.envs.configs import EnvConfig\n"
        "from lerobot.configs import PreTrainedConfig\n"
        "import gymnasium as gym\n"
        "print('baxter_pnp' in EnvConfig.get_known_choices(), 'pnp_lstm' in PreTrainedConfig.get_known_choices(),"
        " 'lerobot_pnp/BaxterPnP-v0' in gym.registry)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd="/")
    assert out.stdout.split()[-3:] == ["True", "True", "True"], out.stderr[-2000:]


@pytest.mark.slow
def test_wheel_ships_the_scene(tmp_path):
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            str(ROOT),
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path),
        ],
        check=True,
        capture_output=True,
        cwd=tmp_path,
    )
    (wheel,) = tmp_path.glob("lerobot_policy_pnp_lstm-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "lerobot_pnp/assets/baxter_pnp.xml" in names
    assert "lerobot_policy_pnp_lstm.py" in names
    assert "lerobot_pnp/policy/modeling_pnp_lstm.py" in names


@pytest.mark.slow
def test_async_vector_envs_through_the_lerobot_config():
    from lerobot_pnp.env_config import BaxterPnPEnvConfig

    envs = BaxterPnPEnvConfig().create_envs(n_envs=2, use_async_envs=True)["baxter_pnp"][0]
    try:
        obs, info = envs.reset(seed=[3, 4])
        assert obs["agent_pos"].shape == (2, 8) and obs["environment_state"].shape == (2, 3)
        obs, reward, terminated, truncated, info = envs.step(obs["agent_pos"])  # hold the start pose
        assert list(info["is_success"]) == [False, False]
    finally:
        envs.close()
