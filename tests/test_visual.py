"""Visual variation (``sim/visual.py``, ``scene_variation``, ``distractors``, ``image_noise``): it changes what the
cameras see, within the configured ranges, as a function of the seed; it never changes the physics, the
perturbations or the state observations; off, the scene and every episode are exactly as before."""

from __future__ import annotations

import colorsys
import math

import numpy as np
import pytest

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.presets import PAPER_TASK, VISUAL_TRAINING
from lerobot_pnp.sim import visual
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.sim.expert import run_expert_episode
from lerobot_pnp.sim.image_noise import blur, degrade
from lerobot_pnp.sim.visual_suites import HELD_OUT_RANGES

CAMERAS = {"cameras": ["front", "wrist"], "image_height": 48, "image_width": 64}
EPISODE_ARRAYS = ("states", "env_states", "actions", "phases", "keyframes", "keyframe_states")


def _reset(changes: dict, seed: int, preset: str = "full", **kw):
    env = make_env(preset=preset, **CAMERAS, **changes, **kw)
    obs, _ = env.reset(seed=seed)
    return env, obs


def test_off_by_default_the_scene_is_the_mjcf_file_and_nothing_is_drawn():
    import mujoco

    from lerobot_pnp import robot

    env, obs = _reset({}, 0, preset="paper")
    u = env.unwrapped
    assert u.pnp_task.scene is None and not visual.is_varied(u.config)
    assert all(u.config.to_dict()[f] == list(PAPER_TASK[f]) for f in visual.FIELDS)
    scene = mujoco.MjModel.from_xml_path(str(robot.scene_path()))
    m = u.physics.model
    assert m.nbody == scene.nbody and m.ngeom == scene.ngeom  # no distractor slots
    for name in ("light_diffuse", "light_pos", "light_dir", "mat_rgba", "cam_pos", "cam_quat"):
        assert np.array_equal(getattr(m, name), getattr(scene, name)), name


@pytest.mark.parametrize("changes", [VISUAL_TRAINING, HELD_OUT_RANGES], ids=["training", "held_out"])
def test_visual_variation_leaves_the_episode_and_its_state_observations_bit_identical(changes):
    """The expert sees no pixels: on `full` (every perturbation and observation fault on) its episodes, and the
    final simulator state, are the same to the bit with or without the variation, distractors included."""
    plain, varied = make_env(preset="full"), make_env(preset="full", **changes)
    assert varied.unwrapped.pnp_task.scene is not None
    for seed in (0, 2):
        a, b = run_expert_episode(plain, seed), run_expert_episode(varied, seed)
        assert a.success == b.success and a.info.get("perturbations") == b.info.get("perturbations")
        for name in EPISODE_ARRAYS:
            assert np.array_equal(getattr(a, name), getattr(b, name)), (seed, name)
        assert np.array_equal(plain.unwrapped.physics.data.qpos, varied.unwrapped.physics.data.qpos)


def _ticks(env, seed: int) -> tuple[np.ndarray, bool]:
    """The simulator's coordinates after every control tick of the expert's episode, and its success."""
    ticks = []
    env.unwrapped.physics.on_control_tick = lambda p: ticks.append(p.data.qpos.copy())
    success = run_expert_episode(env, seed).success
    return np.array(ticks), success


def test_distractors_do_not_change_the_physics_even_in_the_arms_way(monkeypatch):
    """Distractors are visual only: three of them put on the cube and on the target (where placement never puts
    them) leave the state trajectory, control tick by control tick, what it is without them."""
    from lerobot_pnp.sim import distractors

    plain, ok_plain = _ticks(make_env(preset="full"), 1)

    def in_the_way(rng, count, object_xy, place_xy):
        return [np.asarray(object_xy), np.asarray(place_xy), (np.asarray(object_xy) + place_xy) / 2][:count]

    monkeypatch.setattr(distractors, "place", in_the_way)
    env = make_env(preset="full", distractors_range=(3, 3))
    cluttered, ok_cluttered = _ticks(env, 1)
    m = env.unwrapped.physics.model
    assert all(m.geom_group[g] == 0 for _, g in env.unwrapped.pnp_task.scene._distractor_slots)
    assert ok_plain == ok_cluttered and len(plain) > 100
    assert np.array_equal(plain, cluttered)  # mocap bodies: no coordinates of their own


def test_distractors_are_placed_clear_of_the_pick_the_place_and_the_way_between():
    from lerobot_pnp.sim import distractors as d

    env = make_env(preset="full", distractors_range=(3, 3))
    u = env.unwrapped
    for seed in range(8):
        env.reset(seed=seed)
        cube, place = u.physics.object_pose()[0][:2], u.pnp_task.place_xy
        spots = [u.physics.model.body_pos[b][:2] for b, g in u.pnp_task.scene._distractor_slots
                 if u.physics.model.geom_group[g] == 0]  # fmt: skip
        assert spots, seed
        for xy in spots:
            assert d._segment_distance(xy, cube, place) >= d.CLEARANCE
            assert min(d._segment_distance(xy, p, d.FRONT_CAMERA_XY) for p in (cube, place)) >= d.SIGHT_LINE
            assert np.all(np.asarray(d.REGION_LOW) <= xy) and np.all(xy <= np.asarray(d.REGION_HIGH))


def test_each_factor_changes_the_pixels_and_the_same_seed_gives_the_same_frames():
    _, nominal = _reset({}, 3)
    for name, held in HELD_OUT_RANGES.items():
        env, first = _reset({name: held}, 3)
        for cam in CAMERAS["cameras"]:
            assert first["pixels"][cam].shape == nominal["pixels"][cam].shape
        assert any(not np.array_equal(first["pixels"][c], nominal["pixels"][c]) for c in CAMERAS["cameras"]), name
        again, _ = env.reset(seed=3)
        for cam in CAMERAS["cameras"]:
            assert np.array_equal(again["pixels"][cam], first["pixels"][cam]), (name, cam)
        other, _ = env.reset(seed=4)
        assert not np.array_equal(other["pixels"]["front"], first["pixels"]["front"]) or name.startswith("wrist")


def test_model_fields_stay_within_the_drawn_ranges():
    lo, hi = HELD_OUT_RANGES["camera_shift_range"]
    tilt_lo, tilt_hi = HELD_OUT_RANGES["camera_tilt_range"]
    hue_lo, hue_hi = HELD_OUT_RANGES["cube_hue_range"]
    env = make_env(preset="paper", **HELD_OUT_RANGES)
    u = env.unwrapped
    scene = u.pnp_task.scene
    front = u.physics.model.camera("front").id
    pos0, quat0 = scene._cam["front"]
    hue0 = colorsys.rgb_to_hsv(*scene._mat_rgba["cube"][:3])[0]
    for seed in range(6):
        env.reset(seed=seed)
        m, s = u.physics.model, scene.sample
        assert lo <= np.linalg.norm(m.cam_pos[front] - pos0) <= hi + 1e-9
        turn = 2 * np.arccos(min(1.0, abs(float(np.dot(m.cam_quat[front], quat0)))))
        assert tilt_lo - 1e-6 <= turn <= tilt_hi + 1e-6
        hue = colorsys.rgb_to_hsv(*m.mat_rgba[m.mat("cube").id][:3])[0]
        turned = min(abs(hue - hue0), 1 - abs(hue - hue0))
        assert hue_lo - 1e-6 <= turned <= hue_hi + 1e-6
        assert 2 ** -HELD_OUT_RANGES["light_intensity_range"][1] - 1e-9 <= s.intensity
        assert abs(np.log2(s.intensity)) >= HELD_OUT_RANGES["light_intensity_range"][0] - 1e-9
        assert s.distractors in (2, 3)
        assert 0.04 <= s.noise_std <= 0.08 and 1.0 <= s.blur_sigma <= 2.0


def test_image_noise_and_blur():
    rng = np.random.default_rng(0)
    flat = np.full((40, 50, 3), 120, np.uint8)
    noisy = degrade(flat, 0.0, 0.05, rng).astype(float) - 120
    assert abs(noisy.std() / 255 - 0.05) < 0.005 and abs(noisy.mean()) < 1
    assert np.array_equal(degrade(flat, 0.0, 0.0, rng), flat)
    edge = np.zeros((20, 20, 3), np.uint8)
    edge[:, 10:] = 255
    soft = blur(edge, 1.5)
    assert soft[5, 0, 0] == 0 and soft[5, 19, 0] == 255 and 0 < soft[5, 9, 0] < soft[5, 10, 0] < 255
    assert abs(soft.sum() - edge.astype(float).sum()) < 1e-2 * edge.sum()  # the kernel keeps the brightness
    from lerobot_pnp.sim.image_noise import gaussian_kernel

    image = rng.integers(0, 256, (30, 41, 3)).astype(np.uint8)
    for sigma in (0.5, 1.0, 2.0):  # within a level of the float Gaussian with its edges repeated
        k, r = gaussian_kernel(sigma), math.ceil(3 * sigma)
        ref = np.pad(image, ((r, r), (r, r), (0, 0)), mode="edge").astype(float)
        ref = sum(w * ref[i : i + 30] for i, w in enumerate(k))
        ref = sum(w * ref[:, i : i + 41] for i, w in enumerate(k))
        assert np.abs(blur(image, sigma).astype(float) - ref).max() <= 1.5, sigma


def test_the_video_frame_has_no_sensor_noise_and_the_observation_does():
    env, obs = _reset({"image_noise_range": (0.05, 0.05)}, 0)
    rendered = env.unwrapped.render()  # the front camera at the observation's size, as the video records it
    clean = env.unwrapped.physics.render("front", 48, 64, env.unwrapped.config.render_effects)
    assert np.array_equal(rendered[:48, :64], clean) and not np.array_equal(obs["pixels"]["front"], clean)


def test_the_held_out_ranges_lie_beyond_the_training_ranges():
    assert set(HELD_OUT_RANGES) == set(VISUAL_TRAINING) == set(visual.FIELDS)
    for name, (lo, hi) in HELD_OUT_RANGES.items():
        train_lo, train_hi = VISUAL_TRAINING[name]
        assert train_lo <= train_hi <= lo <= hi and train_hi < hi, name
        assert train_hi < lo or name == "distractors_range", name  # no held-out deviation can be drawn in training
    assert HELD_OUT_RANGES["distractors_range"][0] > VISUAL_TRAINING["distractors_range"][1]
    for name in visual.FIELDS:
        BaxterPnPEnvConfig(preset="paper", **{name: HELD_OUT_RANGES[name]})  # each valid on its own


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"light_intensity_range": (0.5, 0.2)},
            "env.light_intensity_range must be (min, max) with 0 <= min <= max <= 2",
        ),
        ({"camera_tilt_range": (0.0, 1.0)}, "env.camera_tilt_range must be (min, max) with 0 <= min <= max <= 0.35"),
        ({"cube_hue_range": 0.2}, "env.cube_hue_range must be 2 finite numbers (min, max), got 0.2"),
        ({"image_noise_range": (0.0, float("nan"))}, "env.image_noise_range must be 2 finite numbers"),
        (
            {"distractors_range": (0, 4)},
            "env.distractors_range must be (min, max) whole numbers with 0 <= min <= max <= 3",
        ),
        ({"distractors_range": (0.5, 1)}, "env.distractors_range must be 2 whole numbers (min, max)"),
    ],
)
def test_bad_values_are_one_line_naming_the_valid_range(changes, message):
    with pytest.raises(ConfigError) as err:
        BaxterPnPEnvConfig(preset="paper", **changes)
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_the_visual_fields_are_recorded_and_read_back_with_the_task():
    cfg = BaxterPnPEnvConfig(preset="full", **VISUAL_TRAINING)
    record = cfg.to_dict()
    assert record["distractors_range"] == [0, 1] and record["camera_shift_range"] == [0.0, 0.005]
    again = BaxterPnPEnvConfig(recorded=record)
    assert all(getattr(again, f) == tuple(VISUAL_TRAINING[f]) for f in visual.FIELDS)
    old = {k: v for k, v in record.items() if k not in visual.FIELDS}  # recorded before these fields existed
    assert not visual.is_varied(BaxterPnPEnvConfig(recorded=old))


def test_the_training_data_config_has_the_training_ranges():
    import json
    from pathlib import Path

    config = json.loads((Path(__file__).resolve().parents[1] / "configs" / "generate_full_visual.json").read_text())
    env = BaxterPnPEnvConfig.from_dict(config["env"])
    assert env.preset == "full" and env.cameras == ["front", "wrist"]
    assert {f: getattr(env, f) for f in visual.FIELDS} == VISUAL_TRAINING
