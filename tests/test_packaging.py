"""Packaging: the built wheel is the product. It is built once, installed apart from the source tree, and every
command runs from it; LeRobot discovers the plugin with no flags; async vector envs work."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[1]


def _wheel_env(site: Path) -> dict[str, str]:
    """The environment of a user who installed the wheel: only the install folder on the path, no source tree."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return {**env, "PYTHONPATH": str(site), "OMP_NUM_THREADS": "1", "HF_HUB_OFFLINE": "1", "MUJOCO_GL": "egl"}


def _lock_pins(text: str) -> dict[str, str]:
    """requirements.lock as {name: version}: every line one ``name==version`` pin (markers allowed)."""
    pins = {}
    for line in text.splitlines():
        if line.split("#", 1)[0].strip():
            req = Requirement(line.split("#", 1)[0])
            (spec,) = req.specifier
            assert spec.operator == "==", f"not a pin in requirements.lock: {line}"
            pins[canonicalize_name(req.name)] = spec.version
    return pins


def test_the_lock_pins_every_requirement_of_the_install_and_the_test_extra_at_an_allowed_version():
    """make install takes exactly the lock's versions: a requirement of pyproject.toml the lock misses, or pins
    outside its range, means the lock is stale (make lock)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    pins = _lock_pins((ROOT / "requirements.lock").read_text())
    for req in map(Requirement, [*project["dependencies"], *project["optional-dependencies"]["test"]]):
        name = canonicalize_name(req.name)
        assert name in pins, f"{req} is not in requirements.lock: make lock"
        assert req.specifier.contains(pins[name], prereleases=True), (
            f"requirements.lock pins {name}=={pins[name]}: {req}"
        )
    assert "diffusers" not in pins  # the diffusion extra stays out of the default install


@pytest.fixture(scope="session")
def wheel(tmp_path_factory) -> Path:
    # Built from a clean copy: a stale build/ folder in the checkout could otherwise put removed files in the wheel.
    src = tmp_path_factory.mktemp("src") / "tree"
    junk = shutil.ignore_patterns(".git", ".venv", "build", "dist", "*.egg-info", "outputs", "__pycache__", ".*_cache")
    shutil.copytree(ROOT, src, ignore=junk)
    out = tmp_path_factory.mktemp("wheel")
    cmd = [sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "--no-build-isolation", "-q", "-w", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=out)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (path,) = out.glob("lerobot_policy_pnp_lstm-*.whl")
    return path


@pytest.fixture(scope="session")
def installed(wheel, tmp_path_factory) -> Path:
    """The wheel installed into its own folder (``pip install --target``), not the editable source tree."""
    site = tmp_path_factory.mktemp("site")
    cmd = [sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "-q", "--target", str(site), str(wheel)]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=site)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return site


@pytest.mark.slow
def test_wheel_holds_every_package_of_the_source_tree(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    assert "lerobot_pnp/assets/baxter_pnp.xml" in names
    assert "lerobot_policy_pnp_lstm.py" in names
    sources = {p.relative_to(ROOT).as_posix() for p in (ROOT / "lerobot_pnp").rglob("*.py")}
    assert sources and sources <= names, f"missing from the wheel: {sorted(sources - names)}"


@pytest.mark.slow
def test_every_command_runs_from_the_installed_wheel(installed, tmp_path):
    env, script = _wheel_env(installed), installed / "bin" / "lerobot-pnp"
    code = (
        "import json, lerobot_pnp, lerobot_pnp.assets\n"
        "from importlib.resources import files\n"
        "from lerobot_pnp import cli\n"
        "rcs = {name: cli.main([name, '--help']) for name in cli.COMMANDS}\n"
        "print(json.dumps({'pkg': lerobot_pnp.__file__, 'scene': str(files('lerobot_pnp.assets')), 'rcs': rcs}))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert Path(result["pkg"]).is_relative_to(installed), result["pkg"]  # not the editable source tree
    assert Path(result["scene"]).is_relative_to(installed), result["scene"]
    assert result["rcs"] == dict.fromkeys(result["rcs"], 0) and len(result["rcs"]) >= 8, result["rcs"]

    ds = tmp_path / "ds"  # the console script itself: a real command from the wheel
    gen = [str(script), "generate", "--repo_id=local/wheel", f"--root={ds}", "--num_episodes=2", "--workers=1"]
    proc = subprocess.run([*gen, "--progress=false"], capture_output=True, text=True, cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads((ds / "meta" / "info.json").read_text())["total_episodes"] == 2


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


def test_the_constants_import_no_torch_lerobot_or_mujoco_and_the_gym_id_still_registers():
    # A fresh interpreter: importing the package (the constants module, the presets) is light, and still
    # registers the gymnasium id (gym.make builds the env through its entry point, which loads the rest).
    code = (
        "import sys\n"
        "import lerobot_pnp.robot, lerobot_pnp.presets\n"
        "heavy = sorted(m for m in ('torch', 'lerobot', 'mujoco') if m in sys.modules)\n"
        "import gymnasium as gym\n"
        "print(heavy, lerobot_pnp.presets.GYM_ID in gym.registry)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd="/")
    assert out.stdout.strip().splitlines()[-1] == "[] True", out.stdout + out.stderr[-2000:]


def test_keyframe_eval_envs_are_sync_with_a_warning(caplog):
    import gymnasium as gym

    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    with caplog.at_level("WARNING"):
        envs = BaxterPnPEnvConfig().create_envs(n_envs=2, use_async_envs=True)["baxter_pnp"][0]
    envs.close()
    assert isinstance(envs, gym.vector.SyncVectorEnv)
    assert "keyframe control runs its 2 eval envs in this process" in caplog.text


def test_dense_eval_envs_beyond_the_cpu_count_are_sync_with_a_warning(caplog, monkeypatch):
    """More async workers than CPUs would only contend for them (and hold an interpreter each)."""
    import gymnasium as gym

    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    monkeypatch.setattr("os.cpu_count", lambda: 1)
    monkeypatch.setattr("os.sched_getaffinity", lambda pid: {0}, raising=False)  # one CPU allowed
    with caplog.at_level("WARNING"):
        envs = BaxterPnPEnvConfig(control_mode="dense").create_envs(n_envs=2, use_async_envs=True)["baxter_pnp"][0]
    envs.close()
    assert isinstance(envs, gym.vector.SyncVectorEnv)
    assert "dense control on 1 CPUs runs its 2 eval envs in this process" in caplog.text


@pytest.mark.slow
def test_async_vector_envs_through_the_lerobot_config():
    import gymnasium as gym

    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    # dense control keeps async envs (worker processes re-import the plugin)
    envs = BaxterPnPEnvConfig(control_mode="dense").create_envs(n_envs=2, use_async_envs=True)["baxter_pnp"][0]
    try:
        assert isinstance(envs, gym.vector.AsyncVectorEnv)
        obs, info = envs.reset(seed=[3, 4])
        assert obs["agent_pos"].shape == (2, 8) and obs["environment_state"].shape == (2, 3)
        obs, reward, terminated, truncated, info = envs.step(obs["agent_pos"])  # hold the start pose
        assert list(info["is_success"]) == [False, False]
    finally:
        envs.close()
