"""The MuJoCo scene and the gymnasium env: kinematics, spaces, determinism, config errors, LeRobot config."""

import importlib
import re

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.presets import GYM_ID, PAPER_TASK
from lerobot_pnp.sim.env import BaxterPnPEnv
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.sim.ik import ArmIK, gripper_down_rotation

# Reference poses of Rethink's left arm (docs/baxter.md): joints -> left_gripper position, z axis.
REFERENCE_POSES = [
    ([0, -0.55, 0, 0.75, 0, 1.26, 0], (0.64626, 0.84126, 0.06262), (0.0782, 0.0782, -0.9939)),
    ([-0.08, -1.0, -1.19, 1.94, 0.67, 1.03, -0.50], (0.57971, 0.18329, 0.11370), (0.0537, 0.0159, -0.9984)),
]


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_path(str(robot.scene_path()))


def test_scene_loads_on_its_own_and_names_match(model):
    assert [model.joint(i).name for i in range(7)] == list(robot.JOINT_NAMES)
    np.testing.assert_allclose(model.jnt_range[:7, 0], robot.JOINT_LOWER)
    np.testing.assert_allclose(model.jnt_range[:7, 1], robot.JOINT_UPPER)
    assert model.body("cube").mass[0] == pytest.approx(0.5)
    assert model.site(robot.EE_SITE) is not None and model.site(robot.TARGET_SITE) is not None


@pytest.mark.parametrize("q, pos, z_axis", REFERENCE_POSES)
def test_forward_kinematics_matches_reference_poses(model, q, pos, z_axis):
    p, rot = ArmIK(model).forward(np.array(q))
    assert np.linalg.norm(p - np.array(pos)) < 1e-3  # < 1 mm
    np.testing.assert_allclose(rot[:, 2], z_axis, atol=2e-4)


def test_ik_reaches_gripper_down_pose_and_rejects_out_of_reach(model):
    from lerobot_pnp.errors import UnreachableError

    ik = ArmIK(model)
    target = np.array([0.6, 0.2, robot.CUBE_REST_Z])
    q = ik.solve(target, 0.3, robot.NEUTRAL_Q)
    p, rot = ik.forward(q)
    assert np.linalg.norm(p - target) < 1e-3
    np.testing.assert_allclose(rot, gripper_down_rotation(0.3), atol=5e-3)
    assert np.all(q >= robot.JOINT_LOWER) and np.all(q <= robot.JOINT_UPPER)
    with pytest.raises(UnreachableError, match="IK did not converge"):
        ik.solve(np.array([1.5, 0.2, 0.0]), 0.0, robot.NEUTRAL_Q)


def test_gym_make_and_env_checker():
    env = gym.make(GYM_ID)
    assert env.unwrapped._max_episode_steps == 10
    check_env(env.unwrapped, skip_render_check=True)
    dense = make_env(control_mode="dense")
    assert dense.unwrapped.control_mode == "dense" and dense.unwrapped._max_episode_steps == 200
    check_env(dense.unwrapped, skip_render_check=True)


def test_episode_truncates_at_the_configured_length():
    env = make_env(episode_length=2)
    obs, _ = env.reset(seed=0)
    hold = np.append(obs["agent_pos"][:7], 1.0).astype(np.float32)
    assert env.step(hold)[3] is False
    assert env.step(hold)[3] is True  # the one episode-length rule: the config's episode_length


def test_reset_is_seeded_and_in_the_workspace(keyframe_env):
    obs_a, info = keyframe_env.reset(seed=7)
    obs_b, _ = keyframe_env.reset(seed=7)
    obs_c, _ = keyframe_env.reset(seed=8)
    np.testing.assert_array_equal(obs_a["agent_pos"], obs_b["agent_pos"])
    np.testing.assert_array_equal(obs_a["environment_state"], obs_b["environment_state"])
    assert not np.array_equal(obs_a["environment_state"], obs_c["environment_state"])
    assert info["is_success"] is False
    tc = keyframe_env.unwrapped.config
    cube = obs_a["environment_state"]
    assert tc.object_low[0] <= cube[0] <= tc.object_high[0] and tc.object_low[1] <= cube[1] <= tc.object_high[1]
    assert cube[2] == pytest.approx(robot.CUBE_REST_Z, abs=2e-3)
    ee, rot = keyframe_env.unwrapped.physics.ee_pose()
    assert ee[2] > robot.TABLE_TOP_Z + 0.15 and rot[2, 2] < -0.99  # random start above the table, pointing down
    assert obs_a["agent_pos"][-1] == pytest.approx(1.0, abs=1e-3)  # gripper open


def test_keyframe_step_reaches_the_commanded_keyframe(keyframe_env):
    obs, _ = keyframe_env.reset(seed=3)
    env = keyframe_env.unwrapped.physics
    target = env.ik.solve(np.array([0.55, 0.25, 0.0]), 0.0, obs["agent_pos"][:7])
    obs, reward, terminated, truncated, info = keyframe_env.step(np.append(target, 1.0).astype(np.float32))
    np.testing.assert_allclose(obs["agent_pos"][:7], target, atol=5e-3)
    assert np.linalg.norm(env.ee_pose()[0] - np.array([0.55, 0.25, 0.0])) < 5e-3
    assert not terminated and not truncated and reward == 0.0


def test_straight_path_keeps_the_gripper_on_the_segment(model):
    from lerobot_pnp.sim.interpolation import joint_trajectory

    ik = ArmIK(model)
    top, bottom = np.array([0.5, 0.12, robot.CUBE_REST_Z + 0.15]), np.array([0.5, 0.12, robot.CUBE_REST_Z])
    q0 = ik.solve(top, 0.0, robot.NEUTRAL_Q)
    q1 = ik.solve(bottom, 0.0, q0)

    def max_sideways(path):
        return max(np.linalg.norm(ik.forward(q)[0][:2] - top[:2]) for q in path)

    straight = max_sideways(joint_trajectory(q0, q1, 100, ik=ik))
    plain = max_sideways(joint_trajectory(q0, q1, 100))
    assert straight < 1.5e-3 < plain  # bowing would eat most of the open gripper's 13.9 mm clearance


def test_invalid_actions_raise(keyframe_env):
    keyframe_env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN") as err:
        keyframe_env.step(np.full(8, np.nan, dtype=np.float32))
    # the message points to a checkpoint loader that exists
    loader = re.search(r"lerobot_pnp\.([\w.]+)\.(\w+)\)", str(err.value))
    assert loader, str(err.value)
    assert callable(getattr(importlib.import_module(f"lerobot_pnp.{loader.group(1)}"), loader.group(2)))
    with pytest.raises(ValueError, match="shape"):
        keyframe_env.step(np.zeros(5, dtype=np.float32))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"control_mode": "teleport"}, "control_mode must be one of"),
        ({"hover_height": -0.1}, "hover_height must be in"),
        ({"object_low": (0.9, 0.1), "object_high": (1.2, 0.5)}, "out of the arm's reach"),
        ({"object_low": (0.7, 0.1), "object_high": (0.5, 0.5)}, "object_low must be <= object_high"),
        ({"cameras": ("ceiling",)}, "cameras must be distinct names from"),
        ({"speed": 2.0}, "speed"),
        ({"nudge_max": -0.01}, "nudge_max must be in"),
        ({"preset": "hard"}, "preset must be one of"),
        ({"yaw_range": (0.1, float("nan"))}, "finite"),
        ({"bogus_field": 1}, "unknown baxter_pnp env field"),
        ({"size_range": (0.03, 0.05)}, "size_range must lie in"),
    ],
)
def test_bad_configs_raise_clear_errors(kwargs, message):
    with pytest.raises(ConfigError, match=message):
        BaxterPnPEnv(**kwargs)


def test_nudge_moves_the_cube_before_the_grasp_and_noise_only_touches_observations():
    env = BaxterPnPEnv(nudge_max=0.03, nudge_at_step=1, obs_noise_object=0.005, obs_noise_joints=0.01)
    obs, _ = env.reset(seed=5)
    physics = env.physics
    before, _ = physics.object_pose()
    assert np.linalg.norm(obs["environment_state"] - before) > 0  # noisy observation
    obs, *_ = env.step(np.append(physics.arm_qpos(), 1.0).astype(np.float32))
    after, _ = physics.object_pose()
    moved = np.linalg.norm(after[:2] - before[:2])
    assert 0 < moved <= 0.03 + 1e-6
    assert np.linalg.norm(obs["agent_pos"][:7] - physics.arm_qpos()) > 0


def test_reset_options_pin_the_start_state(keyframe_env):
    q = np.array([0.1, -0.6, 0.0, 0.9, 0.0, 1.2, 0.0])
    obs, _ = keyframe_env.reset(seed=0, options={"arm_qpos": q, "object_pos": [0.5, 0.3, 0.0]})
    np.testing.assert_allclose(obs["agent_pos"][:7], q, atol=2e-3)
    np.testing.assert_allclose(obs["environment_state"][:2], [0.5, 0.3], atol=1e-3)
    with pytest.raises(ValueError, match="object_pos"):
        keyframe_env.reset(options={"object_pos": [0.5, np.nan, 0.0]})


@pytest.mark.parametrize(
    "options, message",
    [
        ({"object_yaw": float("nan")}, "object_yaw"),
        ({"object_pos": [1.3, 0.2, 0.0]}, "out of the arm's reach"),
        ({"object_pos": [*PAPER_TASK["place_low"], 0.0]}, "start solved"),
        ({"arm_qpos": [5.0, 0, 0, 0, 0, 0, 0]}, "joint limits"),
        ({"object_position": [0.5, 0.3, 0.0]}, "unknown reset option"),
    ],
)
def test_bad_reset_options_raise(keyframe_env, options, message):
    from lerobot_pnp.errors import ResetOptionError

    with pytest.raises(ResetOptionError, match=message):
        keyframe_env.reset(seed=0, options=options)


def test_task_is_settable_from_the_env_config_and_recorded(tmp_path):
    from lerobot_pnp.integration.recorded_task import read_recorded
    from lerobot_pnp.sim.recorded_files import write_recorded

    cfg = BaxterPnPEnvConfig(
        object_low=(0.5, 0.2), object_high=(0.6, 0.3), place_low=(0.65, -0.1), place_high=(0.65, -0.1)
    )
    env = make_env(cfg)
    obs, _ = env.reset(seed=1)
    assert 0.5 <= obs["environment_state"][0] <= 0.6 and 0.2 <= obs["environment_state"][1] <= 0.3
    np.testing.assert_allclose(env.unwrapped.physics.place_target(), (0.65, -0.1))
    write_recorded(cfg, tmp_path)
    again = BaxterPnPEnvConfig.from_source(str(tmp_path))
    assert again.to_dict() == cfg.to_dict()
    assert read_recorded(tmp_path)["place_low"] == [0.65, -0.1]
    # a preset named explicitly wins over the recorded task; explicit fields win over both
    assert BaxterPnPEnvConfig.from_source(str(tmp_path), preset="paper").place_low == PAPER_TASK["place_low"]
    assert BaxterPnPEnvConfig.from_source(str(tmp_path), nudge_max=0.01).place_low == (0.65, -0.1)
    # a keyframe policy/dataset run in dense control would fail silently: the contradiction is an error
    with pytest.raises(ConfigError, match="contradicts the recorded task"):
        BaxterPnPEnvConfig.from_source(str(tmp_path), control_mode="dense")
    write_recorded(BaxterPnPEnvConfig(control_mode="dense"), tmp_path)
    dense = BaxterPnPEnvConfig.from_source(str(tmp_path))
    assert dense.control_mode == "dense" and dense.fps == 20


def test_a_config_never_reads_the_command_line_only_the_stock_script_boundary_does(tmp_path, monkeypatch):
    import sys

    from lerobot_pnp.integration.registration import hand_over_command_line
    from lerobot_pnp.sim.recorded_files import write_recorded

    write_recorded(BaxterPnPEnvConfig(preset="full"), tmp_path / "full")
    monkeypatch.setattr(BaxterPnPEnvConfig, "edge_records", {})  # restored after the test
    # a bogus root on the command line of this (not a lerobot-*) process: constructing a config does not read it
    monkeypatch.setattr(sys, "argv", ["pytest", "--dataset.root=/nonexistent/bogus"])
    assert BaxterPnPEnvConfig().to_dict() == BaxterPnPEnvConfig(preset="paper").to_dict()
    # neither does a real one, outside a stock script
    monkeypatch.setattr(sys, "argv", ["pytest", f"--dataset.root={tmp_path / 'full'}"])
    hand_over_command_line()
    assert BaxterPnPEnvConfig().preset == "paper" and BaxterPnPEnvConfig.edge_records == {}
    # inside a stock lerobot-* script the boundary hands it over once; then the config uses it as a value
    monkeypatch.setattr(sys, "argv", ["lerobot-train", f"--dataset.root={tmp_path / 'full'}"])
    assert BaxterPnPEnvConfig().preset == "paper"  # construction alone still reads nothing
    hand_over_command_line()
    monkeypatch.setattr(sys, "argv", ["lerobot-train", "--dataset.root=/nonexistent/bogus"])
    cfg = BaxterPnPEnvConfig()
    assert cfg.preset == "full" and cfg.to_dict() == BaxterPnPEnvConfig(preset="full").to_dict()
    assert BaxterPnPEnvConfig(preset="paper").preset == "paper"  # a preset named explicitly still wins


def test_camera_observations_render_lazily():
    env = BaxterPnPEnv(cameras=["front"], image_height=48, image_width=64)
    assert not env.physics._renderers  # nothing rendered before it is needed
    obs, _ = env.reset(seed=0)
    img = obs["pixels"]["front"]
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8 and img.std() > 0
    assert env.render().shape == (48, 64, 3)
    env.close()


def test_lerobot_env_config_builds_vector_envs():
    from lerobot.envs.configs import EnvConfig
    from lerobot.envs.factory import make_env_config
    from lerobot.envs.utils import env_to_policy_features

    cfg = make_env_config("baxter_pnp")
    assert isinstance(cfg, BaxterPnPEnvConfig) and cfg.fps == 1 and cfg.episode_length == 10
    assert "baxter_pnp" in EnvConfig.get_known_choices()
    features = env_to_policy_features(cfg)
    assert features["observation.state"].shape == (8,) and features["observation.environment_state"].shape == (3,)
    envs = cfg.create_envs(n_envs=2, use_async_envs=False)["baxter_pnp"][0]
    obs, info = envs.reset(seed=[0, 1])
    assert obs["agent_pos"].shape == (2, 8) and list(info["is_success"]) == [False, False]
    assert envs.call("_max_episode_steps")[0] == 10
    envs.close()
    dense = BaxterPnPEnvConfig(control_mode="dense", cameras=["front"])
    assert dense.fps == 20 and dense.episode_length == 200
    assert dense.features_map["pixels/front"] == "observation.images.front"
    with pytest.raises(ConfigError, match="control_mode"):
        BaxterPnPEnvConfig(control_mode="bogus")


def test_lerobot_rollout_signal_is_accepted(keyframe_env):
    from lerobot.envs.utils import NEW_ROLLOUT_OPTION

    a, _ = keyframe_env.reset(seed=4, options={NEW_ROLLOUT_OPTION: True})  # what lerobot-eval passes
    b, _ = keyframe_env.reset(seed=4)
    np.testing.assert_array_equal(a["environment_state"], b["environment_state"])


def test_observe_phase_appends_the_inferred_phase_one_hot():
    """The phase-told controls' observation: a one-hot of the phase the env reports in ``info``, after the
    object features; everything else of the observation is unchanged (same seed, same draws)."""
    from lerobot_pnp.sim.expert import FSMExpert

    plain, told = make_env(BaxterPnPEnvConfig()), make_env(BaxterPnPEnvConfig(observe_phase=True))
    assert told.unwrapped.config.environment_state_names[3:] == [f"phase={n}" for n in robot.PHASE_NAMES]
    obs_p, _ = plain.reset(seed=3)
    obs_t, info = told.reset(seed=3)
    seen = set()
    expert = FSMExpert(told)
    for _ in range(10):
        np.testing.assert_array_equal(obs_t["environment_state"][:3], obs_p["environment_state"])
        one_hot = obs_t["environment_state"][3:]
        assert one_hot.sum() == 1 and int(one_hot.argmax()) == info["phase"]
        seen.add(info["phase"])
        action = expert.next_keyframe()
        obs_p, *_ = plain.step(action)
        obs_t, _, terminated, _, info = told.step(action)
        if terminated:
            break
    assert len(seen) >= 5  # the one-hot follows the task through its phases
    assert told.observation_space["environment_state"].shape == (3 + robot.N_KEYFRAMES,)


def test_policy_feature_check_accepts_every_task_width_and_names_a_wrong_one():
    """A checkpoint trained on any task's observation (object, + yaw, + goal, + phase one-hot) passes the
    feature check; another width fails with a message naming the feature."""
    from lerobot.configs import FeatureType, PolicyFeature

    from lerobot_pnp.evaluation.checkpoints import IncompatiblePolicyError, check_policy_features
    from lerobot_pnp.policy import PnpLstmConfig

    def config(env_width):
        cfg = PnpLstmConfig()
        cfg.input_features = {
            "observation.state": PolicyFeature(FeatureType.STATE, (robot.STATE_DIM,)),
            "observation.environment_state": PolicyFeature(FeatureType.ENV, (env_width,)),
        }
        cfg.output_features = {"action": PolicyFeature(FeatureType.ACTION, (robot.ACTION_DIM,))}
        return cfg

    for preset_changes in ({}, {"preset": "full"}, {"observe_phase": True}, {"preset": "full", "observe_phase": True}):
        width = len(BaxterPnPEnvConfig(**preset_changes).environment_state_names)
        check_policy_features(config(width))
    with pytest.raises(IncompatiblePolicyError, match="observation.environment_state"):
        check_policy_features(config(4))
