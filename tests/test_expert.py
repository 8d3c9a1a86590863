"""The scripted FSM expert: keyframes, a real grasp, a real placement, determinism, failures."""

import gymnasium as gym
import numpy as np
import pytest

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, UnreachableError
from lerobot_pnp.sim.env import BaxterPnPEnv
from lerobot_pnp.sim.expert import ExpertConfig, FSMExpert, grasp_yaw, run_expert_episode


def test_expert_episode_has_the_papers_ten_states(keyframe_env):
    ep = run_expert_episode(keyframe_env, seed=0)
    assert ep.success
    assert ep.states.shape == (10, 8) and ep.env_states.shape == (10, 3) and ep.actions.shape == (10, 8)
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
    assert np.linalg.norm(cube[:2] - keyframe_env.unwrapped.pnp_task.place_xy) < 0.02
    assert cube[2] == pytest.approx(robot.CUBE_REST_Z, abs=3e-3)
    assert info["is_success"] and terminated


def test_expert_is_deterministic(keyframe_env):
    a = run_expert_episode(keyframe_env, seed=21)
    b = run_expert_episode(keyframe_env, seed=21)
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.actions, b.actions)
    np.testing.assert_array_equal(a.env_states, b.env_states)


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


# ---------------------------------------------------------------------------------------------- task suite
PERTURBATIONS = {
    "grasp_miss": ({"grasp_miss_prob": 1.0}, "grasp_missed"),
    "drop": ({"drop_prob": 1.0}, "dropped"),
    "displace": ({"displace_prob": 1.0}, "displaced"),
}


@pytest.mark.parametrize("name", sorted(PERTURBATIONS))
def test_each_perturbation_happens_and_the_expert_recovers(name):
    from lerobot_pnp.sim.env_config import make_env

    changes, recovery = PERTURBATIONS[name]
    env = make_env(render_mode=None, keyframe_budget=30, **changes)
    for seed in range(3):
        ep = run_expert_episode(env, seed)
        assert ep.info["perturbations"] == [name] and ep.info["recoveries"] == [recovery]
        assert ep.success and ep.num_frames > 10  # more keyframes than the undisturbed 10
        # the recovery is labelled with FSM phases like the rest: it goes back to pick/start (phase 0)
        assert list(ep.phases).count(0) == 2


def test_the_grasp_really_misses_and_the_object_really_leaves_the_gripper():
    from lerobot_pnp.sim.env_config import make_env

    env = make_env(render_mode=None, keyframe_budget=30, grasp_miss_prob=1.0)
    env.reset(seed=2)
    expert, physics = FSMExpert(env), env.unwrapped.physics
    for _ in range(3):  # approach, grasp (the object slides away here), close
        env.step(expert.next_keyframe())
    assert not physics.object_in_grasp() and env.unwrapped.pnp_task.perturbations_fired == ["grasp_miss"]

    env = make_env(render_mode=None, keyframe_budget=30, drop_prob=1.0)
    env.reset(seed=2)
    expert = FSMExpert(env)
    physics = env.unwrapped.physics
    for _ in range(4):  # approach, grasp, close, retract (lifted: knocked out here)
        env.step(expert.next_keyframe())
    obj, _ = physics.object_pose()
    assert not physics.object_in_grasp() and obj[2] == pytest.approx(robot.CUBE_REST_Z, abs=3e-3)  # on the table
    assert physics.object_speed() < 0.02  # at rest


def test_full_preset_observes_yaw_and_goal_and_is_deterministic():
    from lerobot_pnp.sim.env_config import make_env

    env = make_env(render_mode=None, preset="full")
    cfg = env.unwrapped.config
    assert cfg.environment_state_names[3:] == ["object_yaw_sin4", "object_yaw_cos4", "goal_x", "goal_y"]
    obs, _ = env.reset(seed=9)
    _, yaw = env.unwrapped.physics.object_pose()
    np.testing.assert_allclose(obs["environment_state"][3:5], [np.sin(4 * yaw), np.cos(4 * yaw)], atol=1e-5)
    np.testing.assert_allclose(obs["environment_state"][5:], env.unwrapped.physics.place_target(), atol=1e-6)
    np.testing.assert_allclose(obs["environment_state"][5:], env.unwrapped.pnp_task.place_xy, atol=1e-6)
    # the yaw features are the same for the cube's four symmetric faces
    env.reset(seed=9, options={"object_yaw": yaw + np.pi / 2})
    again = env.unwrapped.pnp_task.observe(env.unwrapped.physics, np.random.default_rng(0))
    np.testing.assert_allclose(again["environment_state"][3:5], obs["environment_state"][3:5], atol=1e-4)
    a, b = run_expert_episode(env, 21), run_expert_episode(env, 21)
    np.testing.assert_array_equal(a.actions, b.actions)
    np.testing.assert_array_equal(a.env_states, b.env_states)


def test_env_info_reports_phase_and_failure_cause():
    from lerobot_pnp.sim.env_config import make_env

    env = make_env(render_mode=None, episode_length=4)
    obs, info = env.reset(seed=3)
    assert info["phase"] == 0 and info["failure_cause"] == ""
    expert = FSMExpert(env)
    for _ in range(3):  # approach, grasp, close: then the budget is nearly spent
        obs, _, _, truncated, info = env.step(expert.next_keyframe())
    assert info["phase"] == 3 and info["furthest_phase"] == 3 and not truncated  # pick/close: the object is held
    hold = np.append(obs["agent_pos"][:7], 0.0).astype(np.float32)
    *_, truncated, info = env.step(hold)
    assert truncated and info["failure_cause"] == "not_transported"


def test_expert_labels_any_state_and_following_its_labels_succeeds():
    """DAgger's teacher: from a state reached by someone else, the labelled keyframes still finish the task."""
    from lerobot_pnp.sim.env_config import make_env

    env = make_env(render_mode=None, keyframe_budget=30)
    for seed in range(4):
        obs, _ = env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        # a clumsy start: a random joint perturbation of the start pose, then follow the labels only
        env.step(np.append(obs["agent_pos"][:7] + rng.normal(0, 0.05, 7), 1.0).astype(np.float32))
        teacher = FSMExpert(env)
        for _ in range(25):
            keyframe, phase = teacher.label()
            assert 0 <= phase < robot.N_KEYFRAMES
            _, _, terminated, truncated, _ = env.step(keyframe)
            if terminated or truncated:
                break
        assert terminated, f"seed {seed}: following the labels did not finish the task"


def test_a_label_commands_the_demonstrations_gripper_whatever_the_gripper_is_now():
    """Above the object with the gripper closed (a policy closed it early): the label descends to grasp with it
    open, as every demonstration does, not with the gripper as it happens to be."""
    from lerobot_pnp.sim.env_config import make_env

    env = make_env(render_mode=None, nudge_max=0.0, grasp_miss_prob=0.0)
    env.reset(seed=3)
    approach = FSMExpert(env).next_keyframe()
    env.step(np.append(approach[:7], robot.GRIPPER_CLOSED).astype(np.float32))
    assert env.unwrapped.physics.gripper_opening() < 0.5
    keyframe, phase = FSMExpert(env).label()
    assert phase == robot.Phase.PICK_APPROACH and keyframe[-1] == robot.GRIPPER_OPEN


@pytest.mark.parametrize("size", [0.045, 0.06])
def test_object_size_is_simulated_and_handled_by_the_expert(size):
    from lerobot_pnp.sim.env_config import make_env

    env = make_env(render_mode=None, size_range=(size, size))
    obs, _ = env.reset(seed=1)
    physics = env.unwrapped.physics
    assert physics.object_size == pytest.approx(size)
    assert obs["environment_state"][2] == pytest.approx(robot.TABLE_TOP_Z + size / 2, abs=2e-3)  # resting on the table
    assert all(run_expert_episode(env, s).success for s in range(3))


@pytest.mark.parametrize("carry_min_time, kept", [(0.0, False), (0.5, True)])
def test_a_short_carry_keeps_a_heavy_cube_only_when_gentle(carry_min_time, kept):
    """A re-pick 8 cm from the target (wide displacements make them common): at the joint velocity limits the
    short move accelerates hard enough to shake the smallest, heaviest, least grippy cube loose."""
    from lerobot_pnp.sim.env_config import make_env

    worst = {"size_range": (0.045, 0.045), "mass_range": (0.8, 0.8), "friction_range": (0.7, 0.7)}
    env = make_env(
        render_mode=None, place_low=(0.63, -0.18), place_high=(0.63, -0.18), carry_min_time=carry_min_time, **worst
    )
    env.reset(seed=0, options={"object_pos": [0.63, -0.10, 0.0]})
    expert, physics = FSMExpert(env), env.unwrapped.physics
    for _ in range(5):  # approach, grasp, close, retract, hold
        env.step(expert.next_keyframe())
    assert physics.object_in_grasp()
    env.step(expert.next_keyframe())  # the place approach: an 8 cm carry
    assert physics.object_in_grasp() == kept


def test_phase_is_an_int_enum_with_the_papers_names_and_subtasks():
    import json

    assert [int(p) for p in robot.Phase] == list(range(robot.N_KEYFRAMES))
    assert [p.label for p in robot.Phase] == list(robot.PHASE_NAMES)
    assert [p.subtask for p in robot.Phase] == [0] * 5 + [1] * 5
    # it serialises exactly as the plain ints it replaces (the dataset and the records do not change)
    assert json.dumps([robot.Phase.PLACE_OPEN]) == "[8]" and f"{robot.Phase.PICK_CLOSE}" == "3"
    assert np.asarray([robot.Phase.PICK_GRASP], dtype=np.int64).tolist() == [2]


def test_infer_phase_is_a_pure_query_and_step_info_records_the_grasp(keyframe_env):
    base = keyframe_env.unwrapped
    _, info = keyframe_env.reset(seed=0)
    assert type(info["phase"]) is int and info["phase"] == robot.Phase.PICK_START
    expert = FSMExpert(keyframe_env)
    while expert.phase != robot.Phase.PICK_RETRACT:  # up to the lift: the cube is held
        _, _, _, _, info = keyframe_env.step(expert.next_keyframe())
    task, physics = base.pnp_task, base.physics
    assert physics.object_in_grasp() and info["phase"] >= robot.Phase.PICK_CLOSE
    task._was_grasped = False
    assert isinstance(task.infer_phase(physics), robot.Phase) and task.infer_phase(physics) == info["phase"]
    expert.label()  # the expert's query reads the inferred phase: no side effect either
    assert task._was_grasped is False
    assert type(task.step_info(physics, False, False)["phase"]) is int and task._was_grasped
