"""The scripted FSM expert: keyframes, a real grasp, a real placement, determinism, failures."""

import gymnasium as gym
import numpy as np
import pytest

from lerobot_pnp import robot
from lerobot_pnp.env import BaxterPnPEnv
from lerobot_pnp.errors import ConfigError, UnreachableError
from lerobot_pnp.expert import ExpertConfig, FSMExpert, grasp_yaw, run_expert_episode


def test_expert_episode_has_the_papers_ten_states(keyframe_env):
    ep = run_expert_episode(keyframe_env, seed=0)
    assert ep.success
    assert ep.states.shape == (10, 8) and ep.object_positions.shape == (10, 3) and ep.actions.shape == (10, 8)
    assert ep.keyframes.shape == (10, 8) and ep.keyframe_states.shape == (10, 11)
    np.testing.assert_array_equal(ep.phases, np.arange(10))
    # action k is the keyframe of state k + 1; the last frame holds
    np.testing.assert_array_equal(ep.actions[:9], ep.keyframes[1:])
    np.testing.assert_array_equal(ep.actions[9], ep.keyframes[9])
    # gripper: open until close, closed while carrying, open from the release on
    np.testing.assert_array_equal(ep.keyframes[:, 7], [1, 1, 1, 0, 0, 0, 0, 0, 1, 1])
    # place/start is pick/retract (the paper copies the last pick column)
    np.testing.assert_array_equal(ep.keyframes[5], ep.keyframes[4])
    # observed keyframe states reproduce the commanded joints closely
    np.testing.assert_allclose(ep.keyframe_states[1:, :7], ep.keyframes[1:, :7], atol=0.02)


def test_grasp_lifts_the_cube_and_release_places_it(keyframe_env):
    env = keyframe_env.unwrapped.physics
    keyframe_env.reset(seed=11)
    expert = FSMExpert(keyframe_env)
    start_cube, _ = env.object_pose()
    for _ in range(4):  # approach, grasp, close, retract
        keyframe_env.step(expert.next_keyframe())
    cube, _ = env.object_pose()
    assert env.object_in_grasp(), "both pads must touch the cube after the retract"
    assert cube[2] > start_cube[2] + 0.1, "the cube must be lifted with the gripper"
    # the fingers stopped on the 5 cm cube (not closed, not open)
    expected = (robot.CUBE_SIZE - robot.JAW_GAP_CLOSED) / 2 / robot.FINGER_TRAVEL
    assert env.gripper_opening() == pytest.approx(expected, abs=0.05)
    info = {}
    for _ in range(5):  # hold, approach place, descend, open, retract
        _, _, terminated, _, info = keyframe_env.step(expert.next_keyframe())
    cube, _ = env.object_pose()
    assert not env.object_in_grasp()
    assert np.linalg.norm(cube[:2] - np.array(keyframe_env.unwrapped.config.place_xy)) < 0.02
    assert cube[2] == pytest.approx(robot.CUBE_REST_Z, abs=3e-3)
    assert info["is_success"] and terminated


def test_expert_is_deterministic(keyframe_env):
    a = run_expert_episode(keyframe_env, seed=21)
    b = run_expert_episode(keyframe_env, seed=21)
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.actions, b.actions)
    np.testing.assert_array_equal(a.object_positions, b.object_positions)


def test_expert_success_on_a_seeded_sample(keyframe_env):
    results = [run_expert_episode(keyframe_env, seed=s).success for s in range(100, 120)]
    assert all(results)


def test_expert_dense_mode_and_cube_yaw():
    env = gym.make("lerobot_pnp/BaxterPnP-v0", control_mode="dense", yaw_range=(-0.6, 0.6))
    ep = run_expert_episode(env, seed=4)
    assert ep.success and 60 < ep.num_frames < 400
    assert np.all(np.diff(ep.phases) >= 0) and ep.phases[0] == 0 and ep.phases[-1] == 9
    # dense setpoints respect the joint velocity limits
    step = np.abs(np.diff(ep.actions[:, :7], axis=0)).max(axis=0)
    assert np.all(step <= robot.JOINT_VEL_LIMIT / env.unwrapped.fps + 1e-6)


def test_grasp_yaw_uses_the_cube_symmetry():
    assert grasp_yaw(0.0) == pytest.approx(0.0)
    assert grasp_yaw(np.pi / 2 + 0.1) == pytest.approx(0.1)
    assert grasp_yaw(-np.pi / 4 - 0.1) == pytest.approx(np.pi / 4 - 0.1)


def test_expert_recovers_from_a_nudged_cube():
    env = gym.make("lerobot_pnp/BaxterPnP-v0", nudge_max=0.03)
    assert all(run_expert_episode(env, seed=s).success for s in range(3))


def test_unreachable_object_raises_a_typed_error():
    env = BaxterPnPEnv()
    env.reset(seed=0)
    env.physics.displace_object(np.array([0.6, 0.0, 0.0]))  # pushed out of reach after the reset
    with pytest.raises(UnreachableError, match="IK did not converge"):
        FSMExpert(env).next_keyframe()


def test_bad_expert_config():
    with pytest.raises(ConfigError, match="grasp_depth"):
        ExpertConfig(grasp_depth=0.2)
