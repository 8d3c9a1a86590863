"""Stock LeRobot image policies on this env: the recorded observation setup, the shipped configs, offline.

Fast tests: a dataset's cameras and image size are read back like its task (so ``lerobot-eval`` needs no camera
flag), an explicit flag still wins, and the shipped configs parse and are offline (no backbone download). The
``slow`` test runs the stock CLIs: ``lerobot-pnp generate`` with a camera -> ``lerobot-train --config_path
configs/train_act_images.json`` (a few steps, in-training eval included) -> ``lerobot-eval`` with no camera flag.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import zygote
from clis import exe as _exe

from lerobot_pnp.integration.registration import hand_over_command_line
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.env_validation import MAX_IMAGE_SIDE, MIN_IMAGE_HEIGHT, MIN_IMAGE_WIDTH
from lerobot_pnp.sim.recorded_files import write_recorded

REPO = Path(__file__).resolve().parents[1]
IMAGE_CONFIGS = ("train_act_images.json", "train_diffusion_images.json")


# ---------------------------------------------------------------------------------------------- fast
def test_recorded_cameras_found_through_a_config_file(tmp_path, monkeypatch):
    """``lerobot-train --config_path file.json`` names the dataset only in the file: its task is read from there."""
    write_recorded(BaxterPnPEnvConfig(cameras=["front"], image_height=64, image_width=64), tmp_path / "ds")
    config = tmp_path / "train.json"
    config.write_text(json.dumps({"dataset": {"repo_id": "local/ds", "root": str(tmp_path / "ds")}}))
    monkeypatch.setattr(BaxterPnPEnvConfig, "edge_records", {})  # restored after the test
    monkeypatch.setattr(sys, "argv", ["lerobot-train", f"--config_path={config}", "--steps=3"])
    hand_over_command_line()  # what the plugin does when lerobot-train loads it
    cfg = BaxterPnPEnvConfig()
    assert cfg.cameras == ["front"] and cfg.image_height == 64
    monkeypatch.setattr(sys, "argv", ["lerobot-train", "--steps=3"])
    hand_over_command_line()
    assert BaxterPnPEnvConfig().cameras == []


def test_recorded_cameras_are_read_back(tmp_path):
    recorded = BaxterPnPEnvConfig(cameras=["front", "wrist"], image_height=48, image_width=64)
    write_recorded(recorded, tmp_path)
    cfg = BaxterPnPEnvConfig.from_source(str(tmp_path))
    assert cfg.cameras == ["front", "wrist"] and (cfg.image_height, cfg.image_width) == (48, 64)
    assert cfg.features["pixels/front"].shape == (48, 64, 3)
    assert cfg.features_map["pixels/wrist"] == "observation.images.wrist"


def test_explicit_camera_flags_win_and_defaults_stay(tmp_path):
    write_recorded(BaxterPnPEnvConfig(cameras=["front"], image_height=48, image_width=64), tmp_path)
    cfg = BaxterPnPEnvConfig.from_source(str(tmp_path), cameras=[], image_width=80)
    assert cfg.cameras == [] and (cfg.image_height, cfg.image_width) == (48, 80)
    plain = BaxterPnPEnvConfig()
    assert plain.cameras == [] and (plain.image_height, plain.image_width) == (240, 320)
    assert not any(k.startswith("pixels/") for k in plain.features)


@pytest.mark.parametrize(
    ("height", "width"), [(4, 64), (64, "64"), (24, 24), (64, MIN_IMAGE_WIDTH - 1), (MAX_IMAGE_SIDE + 1, 64)]
)
def test_bad_image_size_is_one_clear_error_naming_the_range(height, width):
    """Below the video encoder's smallest frame (it crashes the process writing a dataset) or above the largest
    side: one line naming the valid range and the size given."""
    from lerobot_pnp.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        BaxterPnPEnvConfig(image_height=height, image_width=width)
    ranges = f"[{MIN_IMAGE_HEIGHT}, {MAX_IMAGE_SIDE}] and env.image_width in [{MIN_IMAGE_WIDTH}, {MAX_IMAGE_SIDE}]"
    assert ranges in str(err.value) and f"got {height!r}x{width!r}" in str(err.value)


def test_the_extreme_image_sizes_render():
    """A side above the MJCF's offscreen framebuffer (640x480) renders: the framebuffer is the image's size."""
    from lerobot_pnp.sim.env_config import make_env

    for height, width in ((MAX_IMAGE_SIDE, MIN_IMAGE_WIDTH), (MIN_IMAGE_HEIGHT, 704)):
        env = make_env(cameras=["front"], image_height=height, image_width=width, render_mode=None)
        image = env.reset(seed=0)[0]["pixels"]["front"]
        env.close()
        assert image.shape == (height, width, 3) and image.std() > 0


def test_a_camera_dataset_at_the_smallest_image_size(tmp_path):
    """`lerobot-pnp generate` at the smallest accepted size: the video encoder writes it and LeRobot reads it."""
    from lerobot_pnp.dataset.validation import open_local_dataset

    root = tmp_path / "ds"
    size = [f"--env.image_height={MIN_IMAGE_HEIGHT}", f"--env.image_width={MIN_IMAGE_WIDTH}"]
    cmd = [_exe("lerobot-pnp"), "generate", f"--root={root}", "--num_episodes=2", "--env.cameras=[front]", *size]
    proc = zygote.run([*cmd, "--progress=false"], tmp_path)  # the script, forked from a warm interpreter
    assert proc.returncode == 0, proc.stderr[-3000:]
    frame = open_local_dataset("local/ds", root)[0]["observation.images.front"]
    assert tuple(frame.shape) == (3, MIN_IMAGE_HEIGHT, MIN_IMAGE_WIDTH)


@pytest.mark.parametrize("name", IMAGE_CONFIGS)
def test_shipped_image_configs_are_offline(name):
    """The configs parse as LeRobot policy configs and name no downloadable backbone."""
    import lerobot.policies  # noqa: F401  (registers LeRobot's own policy configs, as its CLIs' imports do)
    from lerobot.configs.policies import PreTrainedConfig

    raw = json.loads((REPO / "configs" / name).read_text())
    policy = dict(raw["policy"])
    assert policy["pretrained_backbone_weights"] is None
    cls = PreTrainedConfig.get_choice_class(policy.pop("type"))
    policy.pop("input_features")
    cfg = cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in policy.items()})
    assert cfg.pretrained_backbone_weights is None
    assert raw["eval"]["use_async_envs"] is False and raw["env"] == {"type": "baxter_pnp"}


# ---------------------------------------------------------------------------------------------- slow
@pytest.mark.slow
def test_act_on_images_stock_train_then_eval_without_camera_flags(tmp_path):
    from lerobot_pnp import cli

    train, evaluate = _exe("lerobot-train"), _exe("lerobot-eval")  # the stock processes under test
    config = json.loads((REPO / "configs" / "train_act_images.json").read_text())
    ds = tmp_path / config["dataset"]["root"]  # the config's own (relative) dataset root, run from tmp_path
    repo_id = config["dataset"]["repo_id"]
    gen = ["generate", f"--repo_id={repo_id}", f"--root={ds}", "--num_episodes=3", "--workers=1"]
    cams = ["--env.cameras=[front]", "--env.image_height=64", "--env.image_width=64", "--progress=false"]
    assert cli.main([*gen, *cams]) == 0

    out = tmp_path / "train"
    proc = zygote.run(  # the stock entry points, in processes forked from a warm interpreter (tests/zygote.py)
        [
            train,
            f"--config_path={REPO / 'configs' / 'train_act_images.json'}",  # no dataset or camera flag
            "--steps=3",
            "--save_freq=3",
            "--env_eval_freq=3",
            "--log_freq=1",
            "--batch_size=4",
            "--eval.n_episodes=1",
            "--eval.batch_size=1",
            f"--output_dir={out}",
        ],
        tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Suite overall aggregated" in proc.stdout + proc.stderr  # the in-training eval ran in the camera env
    ckpt = out / "checkpoints" / "last" / "pretrained_model"
    assert json.loads((ckpt / "config.json").read_text())["input_features"]["observation.images.front"]
    # stock lerobot-train wrote the task into ACT's checkpoint too (stock_checkpoints): it outlives the dataset
    task = json.loads((ckpt / "baxter_pnp_env.json").read_text())
    assert task["cameras"] == ["front"] and (task["image_height"], task["image_width"]) == (64, 64)
    (ds / "meta" / "baxter_pnp_env.json").unlink()  # the dataset root no longer says which cameras

    ev = tmp_path / "eval"
    cmd = [evaluate, f"--policy.path={ckpt}", "--env.type=baxter_pnp", "--eval.n_episodes=1"]
    proc = zygote.run([*cmd, "--eval.batch_size=1", "--policy.device=cpu", f"--output_dir={ev}"], tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    overall = json.loads((ev / "eval_info.json").read_text())["overall"]
    assert overall["n_episodes"] == 1  # the camera env was built from the checkpoint's own task
