"""The camera-only planner and what its cameras render.

Render settings: ``render_effects`` is part of the recorded observation setup (new tasks render without shadows,
reflections and multisampling; a task recorded before the field existed reads back as rendered with them), and the
two settings render different, deterministic images of the same scene.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.sim.recorded_files import RECORDED_FILE, write_recorded


# ---------------------------------------------------------------------------------------------- render settings
def test_render_effects_off_by_default_and_recorded(tmp_path):
    assert BaxterPnPEnvConfig().render_effects is False
    write_recorded(BaxterPnPEnvConfig(cameras=["front"], image_height=32, image_width=32), tmp_path)
    assert json.loads((tmp_path / RECORDED_FILE).read_text())["render_effects"] is False
    assert BaxterPnPEnvConfig.from_source(str(tmp_path)).render_effects is False
    assert BaxterPnPEnvConfig.from_source(str(tmp_path), render_effects=True).render_effects is True  # flag wins


def test_a_task_recorded_before_the_field_reads_back_with_effects(tmp_path):
    """The recorded-task rule: a field missing from a stored config has the value it had then."""
    write_recorded(BaxterPnPEnvConfig(cameras=["front"], image_height=32, image_width=32), tmp_path)
    path = tmp_path / RECORDED_FILE
    old = json.loads(path.read_text())
    del old["render_effects"]
    path.write_text(json.dumps(old))
    cfg = BaxterPnPEnvConfig.from_source(str(tmp_path))
    assert cfg.render_effects is True and cfg.cameras == ["front"]
    from lerobot_pnp.cache import same_env_configs

    assert same_env_configs(old, cfg.to_dict())  # a stored stage of that task is the same task
    assert not same_env_configs(old, BaxterPnPEnvConfig(cameras=["front"], image_height=32, image_width=32).to_dict())


def test_render_effects_must_be_a_bool():
    with pytest.raises(ConfigError, match="render_effects must be true or false"):
        BaxterPnPEnvConfig(render_effects="yes")


def test_the_two_settings_render_different_deterministic_images():
    images = {}
    for effects in (True, False):
        env = make_env(cameras=["front"], image_height=32, image_width=32, render_effects=effects, render_mode=None)
        first = env.reset(seed=3)[0]["pixels"]["front"]
        again = env.unwrapped.physics.render("front", 32, 32, effects)
        assert np.array_equal(first, again) and first.std() > 0
        images[effects] = first
        env.close()
    assert not np.array_equal(images[True], images[False])
    # the scene is the same: the images differ in shading, not in what is where
    assert np.abs(images[True].astype(int) - images[False].astype(int)).mean() < 40


# ---------------------------------------------------------------------------------------------- the policy
STATE_DIM, ENV_DIM, ACTION_DIM, SIZE = 8, 7, 8, 32  # the video codec (SVT-AV1) fails on 24x24


def _config(**changes):
    from lerobot.configs.types import FeatureType, PolicyFeature

    from lerobot_pnp.policy import PnpPixelsConfig

    cfg = PnpPixelsConfig(**{"hidden_size": 32, "conv_channels": [8, 8], "num_keypoints": 4, **changes})
    cfg.input_features = {
        "observation.state": PolicyFeature(type=FeatureType.STATE, shape=(STATE_DIM,)),
        "observation.environment_state": PolicyFeature(type=FeatureType.ENV, shape=(ENV_DIM,)),
        "observation.images.front": PolicyFeature(type=FeatureType.VISUAL, shape=(3, SIZE, SIZE)),
    }
    cfg.output_features = {"action": PolicyFeature(type=FeatureType.ACTION, shape=(ACTION_DIM,))}
    return cfg


def _policy(**changes):
    import torch

    from lerobot_pnp.policy import PnpPixelsPolicy

    torch.manual_seed(0)
    return PnpPixelsPolicy(_config(**changes))


def _episodes(b: int = 3, t: int = 6, seed: int = 0) -> dict:
    import torch

    g = torch.Generator().manual_seed(seed)
    pad = torch.zeros(b, t, dtype=torch.bool)
    pad[0, t - 2 :] = True  # a shorter episode, padded
    return {
        "observation.state": torch.randn(b, t, STATE_DIM, generator=g),
        "observation.environment_state": torch.randn(b, t, ENV_DIM, generator=g),
        "observation.images.front": torch.rand(b, t, 3, SIZE, SIZE, generator=g),
        "action": torch.randn(b, t, ACTION_DIM, generator=g),
        "action_is_pad": pad,
        "phase.subtask": (torch.arange(t) >= t // 2).long().expand(b, t).clone(),
        "phase.index": torch.arange(t).clamp(max=9).expand(b, t).clone(),
    }


def test_forward_backward_shapes_and_the_auxiliary_pose_loss():
    policy = _policy()
    policy.train()
    batch = _episodes()
    loss, info = policy.forward(batch)
    assert loss.ndim == 0 and "pose_loss" in info
    loss.backward()
    encoder_grads = [p.grad for p in policy.encoders.parameters()]
    assert all(g is not None and bool(g.abs().sum() > 0) for g in encoder_grads)
    per_sample, _ = policy.forward(batch, reduction="none")
    assert per_sample.shape == (3,)
    feats, real = policy.keypoints(batch)
    assert feats.shape == (3, 6, 2 * 4) and not bool(feats[0, -2:].any()) and int(real.sum()) == 16
    without = _policy(pose_loss_weight=0.0)
    assert without.pose_head is None and "pose_loss" not in without.forward(batch)[1]


def _act(policy, frames: list[dict]) -> list:
    import torch

    policy.reset()
    return [policy.select_action(f).clone() for f in frames] if frames else [torch.empty(0)]


def _frames(env_state: str = "random") -> list[dict]:
    import torch

    batch = _episodes(b=2, t=4, seed=1)
    out = []
    for k in range(4):
        frame = {key: batch[key][:, k] for key in ("observation.state", "observation.images.front")}
        if env_state == "random":
            frame["observation.environment_state"] = batch["observation.environment_state"][:, k]
        elif env_state == "nan":
            frame["observation.environment_state"] = torch.full((2, ENV_DIM), float("nan"))
        out.append(frame)
    return out


def test_acting_never_reads_the_environment_state():
    import torch

    policy = _policy()
    policy.eval()
    seen = _act(policy, _frames("random"))
    for other in ("nan", "absent"):
        assert all(torch.equal(a, b) for a, b in zip(seen, _act(policy, _frames(other)), strict=True))
    assert all(bool(torch.isfinite(a).all()) for a in seen)


def test_the_images_change_the_actions():
    import torch

    policy = _policy()
    policy.eval()
    frames = _frames("absent")
    dark = [{**f, "observation.images.front": torch.zeros_like(f["observation.images.front"])} for f in frames]
    assert not torch.equal(_act(policy, frames)[0], _act(policy, dark)[0])


def test_save_load_round_trip_gives_identical_actions(tmp_path):
    import torch

    from lerobot_pnp.policy import PnpLstmConfig, PnpPixelsPolicy

    policy = _policy()
    policy.eval()
    policy.save_pretrained(tmp_path)
    assert json.loads((tmp_path / "config.json").read_text())["type"] == "pnp_pixels"
    assert type(PnpLstmConfig.from_pretrained(tmp_path)).__name__ == "PnpPixelsConfig"
    loaded = PnpPixelsPolicy.from_pretrained(tmp_path)
    loaded.eval()
    frames = _frames("absent")
    assert all(torch.equal(a, b) for a, b in zip(_act(policy, frames), _act(loaded, frames), strict=True))


def test_needs_a_camera_and_the_joints():
    from lerobot_pnp.policy import PnpPixelsPolicy

    cfg = _config()
    del cfg.input_features["observation.images.front"]
    with pytest.raises(ConfigError, match="at least one camera"):
        PnpPixelsPolicy(cfg)
    with pytest.raises(ConfigError, match="num_keypoints must be >= 1"):
        _config(num_keypoints=0)
    with pytest.raises(ConfigError, match="image_downsample=3 must divide the images'"):
        PnpPixelsPolicy(_config(image_downsample=3))


def test_a_downsampled_encoder_trains_on_the_same_images():
    policy = _policy(image_downsample=2)
    policy.train()
    loss, _ = policy.forward(_episodes())
    loss.backward()
    assert policy.encoders[0].map_shape == (SIZE // 8, SIZE // 8)
    assert all(p.grad is not None for p in policy.encoders.parameters())


def test_keypoint_strength_is_the_map_value_where_each_keypoint_looks():
    """With ``strength``, the encoder gives each keypoint's attended feature value after the same positions."""
    import torch

    from lerobot_pnp.policy.image_encoder import KeypointEncoder

    torch.manual_seed(0)
    plain = KeypointEncoder((3, SIZE, SIZE), [8, 8], num_keypoints=2).eval()
    strong = KeypointEncoder((3, SIZE, SIZE), [8, 8], num_keypoints=2, strength=True).eval()
    strong.load_state_dict(plain.state_dict())  # no new parameters: the same weights
    images = torch.rand(5, 3, SIZE, SIZE)
    with torch.no_grad():
        out = strong(images)
        assert out.shape == (5, 6) and strong.out_dim == 6 and plain.out_dim == 4
        torch.testing.assert_close(out[:, :4], plain(images))
        np.testing.assert_allclose(strong.pixel_coordinates(out), plain.pixel_coordinates(plain(images)))
        h, w = strong.map_shape
        maps = torch.full((2, 2, h, w), -50.0)
        maps[0, 0, 1, 6], maps[0, 1, 7, 0], maps[1, 0, 3, 3], maps[1, 1, 3, 3] = 3.0, -2.0, 0.5, 7.0
        xy, value = strong.softmax.attend(maps)
    torch.testing.assert_close(value, torch.tensor([[3.0, -2.0], [0.5, 7.0]]))
    torch.testing.assert_close(xy, strong.softmax(maps))


def test_a_planner_with_keypoint_strength_trains_and_round_trips(tmp_path):
    import torch

    from lerobot_pnp.policy import PnpPixelsPolicy

    policy = _policy(keypoint_strength=True)
    policy.train()
    batch = _episodes()
    loss, _ = policy.forward(batch)
    loss.backward()
    assert policy.keypoints(batch)[0].shape == (3, 6, 3 * 4)
    assert all(p.grad is not None and bool(p.grad.abs().sum() > 0) for p in policy.encoders.parameters())
    policy.eval()
    policy.save_pretrained(tmp_path)
    loaded = PnpPixelsPolicy.from_pretrained(tmp_path)
    loaded.eval()
    assert loaded.config.keypoint_strength is True
    frames = _frames("absent")
    assert all(torch.equal(a, b) for a, b in zip(_act(policy, frames), _act(loaded, frames), strict=True))
    assert _policy().config.keypoint_strength is False  # checkpoints saved without the field read back as before


def test_normalised_keypoint_strengths_train_and_round_trip_with_their_statistics(tmp_path):
    """``keypoint_strength_norm``: training standardises each keypoint's strength over the batch's real frames,
    the running statistics travel with the checkpoint, and inference reads them; without strengths it is refused."""
    import torch

    from lerobot_pnp.errors import ConfigError
    from lerobot_pnp.policy import PnpPixelsPolicy

    policy = _policy(keypoint_strength=True, keypoint_strength_norm=True, image_shift=0)
    policy.train()
    batch = _episodes()
    feats, real = policy.keypoints(batch)
    encoder = policy.encoders[0]
    with torch.no_grad():
        raw = encoder.softmax.attend(encoder.feature_maps(batch["observation.images.front"][real]))[1]
    expected = (raw - raw.mean(0)) / (raw.var(0, unbiased=False) + encoder.strength_norm.eps).sqrt()
    torch.testing.assert_close(feats[real][:, 2 * 4 :], expected)
    assert float(raw.std(0).min()) > 0 and not torch.allclose(raw, expected)
    loss, _ = policy.forward(batch)
    loss.backward()
    norm = policy.encoders[0].strength_norm
    assert int(norm.num_batches_tracked) == 2 and bool((norm.running_var != 1).all())
    policy.eval()
    policy.save_pretrained(tmp_path)
    loaded = PnpPixelsPolicy.from_pretrained(tmp_path)
    loaded.eval()
    torch.testing.assert_close(loaded.encoders[0].strength_norm.running_mean, norm.running_mean)
    frames = _frames("absent")
    assert all(torch.equal(a, b) for a, b in zip(_act(policy, frames), _act(loaded, frames), strict=True))
    with pytest.raises(ConfigError, match="keypoint_strength_norm .* needs keypoint_strength true"):
        _config(keypoint_strength_norm=True)


# ---------------------------------------------------------------------------------------------- the fast path
def _image_of(obj, size: int = SIZE) -> np.ndarray:
    """A grey table with the object as a bright square where it lies (x, y in the synthetic data's ranges)."""
    image = np.full((size, size, 3), 60, dtype=np.uint8)
    col = int(np.clip((obj[0] - 0.45) / 0.5 * (size - 4), 0, size - 4))
    row = int(np.clip((obj[1] + 0.35) / 0.7 * (size - 4), 0, size - 4))
    image[row : row + 4, col : col + 4] = (60, 120, 250)
    return image


@pytest.fixture(scope="module")
def image_dataset(tmp_path_factory):
    """12 synthetic keyframe episodes (tests/keyframe_synth.py) with a camera that shows the object, as video."""
    from keyframe_synth import ACTION, OBS_ENV, OBS_STATE, T, features, synthetic_episode
    from lerobot.datasets import LeRobotDataset

    root = tmp_path_factory.mktemp("pixels") / "ds"
    feats = {**features(), "observation.images.front": {"dtype": "video", "shape": (SIZE, SIZE, 3),
                                                       "names": ["height", "width", "channels"]}}  # fmt: skip
    ds = LeRobotDataset.create("test/pixels", fps=1, features=feats, root=root, use_videos=True, video_backend="pyav")
    rng = np.random.default_rng(0)
    for _ in range(12):
        states, objs, acts = synthetic_episode(rng)
        for k in range(T):
            ds.add_frame({
                OBS_STATE: states[k].astype(np.float32), OBS_ENV: objs[k].astype(np.float32),
                ACTION: acts[k].astype(np.float32), "observation.images.front": _image_of(objs[k]),
                "phase.index": np.array([k]), "phase.subtask": np.array([k // 5]),
                "next.done": np.array([k == T - 1]), "next.success": np.array([k == T - 1]),
                "task": "Pick the cube and place it on the target.",
            })  # fmt: skip
        ds.save_episode()
    ds.finalize()
    return root


def test_fast_path_loads_the_frames_and_learns(image_dataset, tmp_path):
    import torch

    from lerobot_pnp.policy import PnpPixelsConfig, PnpPixelsPolicy
    from lerobot_pnp.train_fast import TrainFastConfig, train_fast
    from lerobot_pnp.train_fast.data import load_keyframe_data
    from lerobot_pnp.train_fast.images import episode_images

    ds, data = load_keyframe_data("test/pixels", image_dataset, max_length=10, with_images=True)
    frames = data.images["observation.images.front"]
    assert frames.shape == (12, 10, 3, SIZE, SIZE) and frames.dtype == torch.uint8
    # the decoded video shows the object where the recorded state puts it (lossy codec: the bright square)
    blue = frames[3, 0, 2].float() - frames[3, 0, 0].float()
    row, col = divmod(int(blue.argmax()), SIZE)
    expected = _image_of(data.env_state[3, 0].numpy())[..., 2].astype(int) - 60
    assert expected[row, col] > 0
    # episodes shorter than the longest are padded with their last real frame, like every other feature
    short = episode_images(ds, "observation.images.front", np.arange(12), np.full(12, 7), t_max=10)
    assert torch.equal(short[:, :7], frames[:, :7])
    assert torch.equal(short[:, 7:], frames[:, 6:7].expand(-1, 3, -1, -1, -1))
    policy = PnpPixelsConfig(hidden_size=32, conv_channels=[8, 8], num_keypoints=4, max_episode_length=10)
    cfg = TrainFastConfig(dataset_repo_id="test/pixels", dataset_root=str(image_dataset), policy=policy, steps=40,
                          batch_size=4, lr=3e-3, output_dir=str(tmp_path / "out"), progress=False)  # fmt: skip
    result = train_fast(cfg)
    assert result.history[-1]["train_mse"] < 0.7 * result.history[0]["train_mse"], result.history
    loaded = PnpPixelsPolicy.from_pretrained(result.checkpoint_dir)
    assert loaded.config.type == "pnp_pixels" and loaded.config.num_keypoints == 4


def test_the_training_split_shares_the_frames_and_its_loss_is_taken_in_chunks(image_dataset, monkeypatch):
    """The fast path holds camera frames once (a consecutive split is a view of them), and a whole split's loss,
    taken a few episodes at a time to bound its activations, is the loss of the split at once."""
    import torch
    from lerobot.policies.factory import make_policy, make_pre_post_processors

    from lerobot_pnp.policy import PnpPixelsConfig
    from lerobot_pnp.train_fast import loop
    from lerobot_pnp.train_fast.data import load_keyframe_data

    ds, data = load_keyframe_data("test/pixels", image_dataset, max_length=10, with_images=True)
    cfg = PnpPixelsConfig(hidden_size=16, conv_channels=[8], num_keypoints=4, max_episode_length=10)
    policy = make_policy(cfg, ds_meta=ds.meta)
    pre, _ = make_pre_post_processors(cfg, dataset_stats=ds.meta.stats)
    train = loop._normalised(pre, data, data.train_idx, "cpu")
    key = "observation.images.front"
    assert train[key].untyped_storage().data_ptr() == data.images[key].untyped_storage().data_ptr()
    scattered = loop._normalised(pre, data, data.train_idx.flip(0), "cpu")  # not consecutive: a copy, right rows
    assert torch.equal(scattered[key], data.images[key][data.train_idx.flip(0)])
    pad = torch.zeros(train["action"].shape[:2], dtype=torch.bool)
    pad[:4, 6:] = True  # episodes of unequal length weigh by their real frames
    train["action_is_pad"] = pad
    whole = loop._mse(policy, train)
    monkeypatch.setattr(loop, "CHUNK_EPISODES", 3)
    assert abs(loop._mse(policy, train) - whole) < 1e-5 * whole


def test_the_shipped_config_trains_on_both_paths(image_dataset, tmp_path):
    """configs/train_pnp_pixels.json: a stock ``lerobot-train`` config of LeRobot's registered ``pnp_pixels``, and
    ``lerobot-pnp train --config_path`` of it (or ``--policy.type=pnp_pixels``) runs the fast path."""
    from pathlib import Path

    from lerobot.configs.policies import PreTrainedConfig

    from lerobot_pnp.cli import main
    from lerobot_pnp.policy import PnpPixelsConfig
    from lerobot_pnp.train_fast.config import TrainFastConfig, TrainFastPixelsConfig

    path = Path(__file__).resolve().parents[1] / "configs" / "train_pnp_pixels.json"
    policy = json.loads(path.read_text())["policy"]
    assert isinstance(PreTrainedConfig.get_choice_class(policy.pop("type"))(**policy), PnpPixelsConfig)
    cls, rest = TrainFastConfig.command_class(str(path), ["--policy.type=pnp_pixels", "--epochs=2"])
    assert cls is TrainFastPixelsConfig and rest == ["--epochs=2"]
    assert TrainFastConfig.command_class(None, ["--policy.type", "pnp_pixels"])[0] is TrainFastPixelsConfig
    assert TrainFastConfig.command_class(None, [])[0] is TrainFastConfig
    with pytest.raises(ConfigError, match="the fast path trains"):
        TrainFastConfig.command_class(None, ["--policy.type=act"])
    out = tmp_path / "cli"
    args = ["train", f"--config_path={path}", "--dataset_repo_id=test/pixels", f"--dataset_root={image_dataset}",
            "--steps=2", "--policy.max_episode_length=10", "--policy.hidden_size=16", "--progress=false",
            f"--output_dir={out}"]  # fmt: skip
    assert main(args) == 0
    saved = json.loads((out / "checkpoints" / "last" / "pretrained_model" / "config.json").read_text())
    assert saved["type"] == "pnp_pixels" and saved["hidden_size"] == 16 and saved["num_keypoints"] == 16


def test_the_pre_processor_refuses_a_missing_camera_naming_pnp_pixels():
    """A batch without the trained camera is refused by the check step, in a message that names the policy."""
    import torch

    from lerobot_pnp.errors import PolicyError
    from lerobot_pnp.policy import make_pnp_pixels_pre_post_processors

    def unit(n: int) -> dict:
        return {"mean": torch.zeros(n), "std": torch.ones(n), "min": -torch.ones(n), "max": torch.ones(n)}

    stats = {"observation.state": unit(STATE_DIM), "observation.environment_state": unit(ENV_DIM)}
    pre, _ = make_pnp_pixels_pre_post_processors(_config(), {**stats, "action": unit(ACTION_DIM)})
    with pytest.raises(PolicyError, match=r"^pnp_pixels: observation 'observation\.images\.front' is missing"):
        pre({"observation.state": torch.zeros(1, STATE_DIM)})
