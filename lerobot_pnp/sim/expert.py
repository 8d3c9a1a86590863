"""The scripted finite-state-machine expert (the paper's motion planner).

PICK: start, approach (above the object at z_obj + h), grasp, close, retract.
PLACE: start (= pick retract), approach (above the target), descend, open, retract.
Each state is a joint-space keyframe found by IK (gripper down, yaw aligned with the cube, seeded from
the previous keyframe). The FSM is closed-loop: each keyframe is planned from the state observed when the
previous one was reached, so a nudged cube is still picked. It drives the env through its public API only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, ExpertFailure, UnreachableError
from lerobot_pnp.robot import Phase
from lerobot_pnp.sim.interpolation import joint_trajectory
from lerobot_pnp.sim.task import grasp_yaw


@dataclass
class ExpertConfig:
    """How the expert grasps and places (metres)."""

    grasp_depth: float = 0.005  # gripper endpoint below the cube centre at the grasp
    place_clearance: float = 0.003  # cube bottom above the table when it is released
    settle_time: float = 0.3  # dense mode: hold time after each arm move (s)
    gripper_time: float = 0.6  # dense mode: time given to the gripper to open/close (s)

    def __post_init__(self):
        if not 0 <= self.grasp_depth <= robot.CUBE_SIZE / 2:
            raise ConfigError(
                f"ExpertConfig.grasp_depth must be in [0, {robot.CUBE_SIZE / 2}] m, got {self.grasp_depth}"
            )
        if not 0 <= self.place_clearance <= 0.02:
            raise ConfigError(f"ExpertConfig.place_clearance must be in [0, 0.02] m, got {self.place_clearance}")
        if self.settle_time < 0 or self.gripper_time <= 0:
            raise ConfigError("ExpertConfig.settle_time must be >= 0 and gripper_time > 0")


@dataclass
class ExpertEpisode:
    """One demonstration. Frame arrays have one row per recorded frame (10 in keyframe mode)."""

    seed: int
    states: np.ndarray  # (T, 8) observed joints + gripper opening
    env_states: np.ndarray  # (T, E) observed environment state (object xyz [+ yaw] [+ goal] [+ phase one-hot])
    actions: np.ndarray  # (T, 8) commanded joint targets + gripper command
    phases: np.ndarray  # (T,) int64 robot.Phase values (the state being left; recoveries reuse the indices)
    keyframes: np.ndarray  # (K+1, 8) the commanded keyframes (row 0 = the start state); K = 9 undisturbed
    keyframe_states: np.ndarray  # (K+1, D) observed state + environment state at each keyframe (the paper's sample)
    success: bool
    info: dict = field(default_factory=dict)

    @property
    def num_frames(self) -> int:
        return len(self.actions)


def failure_cause(err: Exception) -> str:
    """A short, groupable name for why an expert episode failed."""
    if isinstance(err, UnreachableError):
        return "unreachable"
    return getattr(err, "cause", type(err).__name__)


# The gripper each keyframe commands, by the FSM state it leaves: open until the close, closed while carrying,
# open from the place's open on. The FSM's own run always has it so; stating it per state keeps a label
# planned from an arbitrary state (``label()``, DAgger) the demonstrations' command there, instead of whatever
# the gripper happens to be (a descent to grasp with the gripper still closed after a miss, a transport with it
# open), which no demonstration shows.
_PHASE_GRIPPER = {
    p: robot.GRIPPER_OPEN
    if p in (Phase.PICK_START, Phase.PICK_APPROACH) or p >= Phase.PLACE_DESCEND
    else robot.GRIPPER_CLOSED
    for p in Phase
}


class FSMExpert:
    """Plans the next keyframe (7 joints + gripper command) from the current physical state.

    It walks the paper's FSM (``phase`` = the FSM state being left, 0..9) and, before each keyframe, checks
    that the world is where the FSM expects it; when it is not, it jumps to the phase that recovers:

    * the grasp closed on nothing (a missed grasp) -> lift with the gripper open (labelled pick/retract), then
      approach the object again (pick/start);
    * the object left the gripper in transport (a drop) -> approach it where it now rests (pick/start);
    * the object is off the target after the place/retract (it was moved after release) -> approach it again.

    In an undisturbed episode the checks all pass and the keyframes are exactly the paper's 10 states.
    The expert is privileged: it reads the true object pose and the episode's target from the env.
    """

    def __init__(self, env: gym.Env, config: ExpertConfig | None = None):
        base = env.unwrapped
        self.physics = base.physics
        self.task = base.pnp_task
        self.config = config or ExpertConfig()
        self.hover = base.config.hover_height
        self.reset()

    def reset(self) -> None:
        self.phase = Phase.PICK_START
        self.last_phase = Phase.PICK_START
        self.recoveries: list[str] = []
        self._cmd = np.append(self.physics.arm_qpos(), robot.GRIPPER_OPEN)
        self._yaw = 0.0
        self._next_phase: Phase | None = None

    # The FSM state to plan from, for each phase the task infers (task.PickPlaceTask.infer_phase): "held and
    # lifted" (pick/retract) continues with place/start, "placed but the gripper still around it" (place/open) retracts.
    _PLAN_FROM_INFERRED = {p: p for p in Phase} | {Phase.PICK_RETRACT: Phase.PLACE_START}

    def sync_to_state(self) -> None:
        """Forget the episode's history and plan from the current physical state (DAgger labelling).

        The FSM state comes from the task's inferred phase; the last command is the servos' current
        setpoints with the gripper command matching its measured state (open above half-open); the next
        keyframe commands its own state's gripper (``_PHASE_GRIPPER``), whatever the gripper is now.
        """
        inferred = self.task.infer_phase(self.physics)
        self.phase = self._PLAN_FROM_INFERRED[inferred]
        grip = robot.GRIPPER_OPEN if self.physics.gripper_opening() > 0.5 else robot.GRIPPER_CLOSED
        self._cmd = np.append(self.physics.arm_command(), grip)
        _, cube_yaw = self.physics.object_pose()
        self._yaw = grasp_yaw(cube_yaw) if inferred <= Phase.PLACE_START else 0.0
        self._next_phase = None

    def label(self) -> tuple[np.ndarray, Phase]:
        """The expert's next keyframe and its phase label from the current state (no side effects on the sim)."""
        self.sync_to_state()
        keyframe = self.next_keyframe()
        return keyframe, self.last_phase

    def place_xy(self) -> np.ndarray:
        return self.task.place_xy

    @property
    def command(self) -> np.ndarray:
        """The last commanded keyframe (the start state before the first call)."""
        return self._cmd.astype(np.float32)

    def _check(self, p: Phase) -> tuple[Phase, float | None]:
        """The phase to plan from the observed state, and a gripper override for recovery lifts."""
        held = self.physics.object_in_grasp()
        if p == Phase.PICK_CLOSE and not held:  # the close found nothing: a missed grasp
            self.recoveries.append("grasp_missed")
            self._next_phase = Phase.PICK_START
            return Phase.PICK_CLOSE, robot.GRIPPER_OPEN
        in_transport = Phase.PICK_RETRACT <= p <= Phase.PLACE_DESCEND
        if in_transport and not held and not self.task.object_placed(self.physics):  # dropped in transport
            self.recoveries.append("dropped")
            return Phase.PICK_START, None
        if p == Phase.PLACE_RETRACT and not self.task.is_success(self.physics):  # moved off the target after release
            self.recoveries.append("displaced")
            return Phase.PICK_START, None
        return p, None

    def next_keyframe(self) -> np.ndarray:
        """Keyframe to go to from FSM state ``self.phase`` (the command that reaches state phase+1).

        ``last_phase`` is the label of the returned keyframe (the FSM state it leaves).
        """
        physics, cfg, ik = self.physics, self.config, self.physics.ik
        p, grip_override = self._check(self.phase)
        q_prev = self._cmd[:7]
        cube, cube_yaw = physics.object_pose()
        ee, _ = physics.ee_pose()
        place = np.array([*self.place_xy(), physics.object_rest_z()])
        if p == 0:  # -> pick/approach: above the object
            self._yaw = grasp_yaw(cube_yaw)
            q = ik.solve(cube + [0, 0, self.hover], self._yaw, q_prev)
        elif p == 1:  # -> pick/grasp: at the object
            self._yaw = grasp_yaw(cube_yaw)
            q = ik.solve(cube - [0, 0, cfg.grasp_depth], self._yaw, q_prev)
        elif p == 2:  # -> pick/close
            q = q_prev
        elif p == 3:  # -> pick/retract: back up to z_obj + h
            q = ik.solve(np.array([ee[0], ee[1], robot.CUBE_REST_Z + self.hover]), self._yaw, q_prev)
        elif p == 4:  # -> place/start (= pick/retract): hold
            q = q_prev
        elif p == 5:  # -> place/approach: above the target, compensating where the cube sits in the hand
            offset = ee - cube
            self._yaw = 0.0
            q = ik.solve(place + offset * [1, 1, 0] + [0, 0, self.hover], self._yaw, q_prev)
        elif p == 6:  # -> place/descend: cube just above the table at the target
            offset = ee - cube
            q = ik.solve(place + offset + [0, 0, cfg.place_clearance], self._yaw, q_prev)
        elif p == 7:  # -> place/open
            q = q_prev
        elif p == 8:  # -> place/retract
            q = ik.solve(np.array([ee[0], ee[1], robot.CUBE_REST_Z + self.hover]), self._yaw, q_prev)
        else:  # after the last state: hold
            q = q_prev
        grip = grip_override if grip_override is not None else _PHASE_GRIPPER[p]
        self._cmd = np.append(q, grip)
        self.last_phase = p
        self.phase = self._next_phase if self._next_phase is not None else Phase(min(p + 1, robot.N_KEYFRAMES - 1))
        self._next_phase = None
        return self._cmd.astype(np.float32)


def _frame(obs: dict) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(obs["agent_pos"], dtype=np.float32), np.asarray(obs["environment_state"], dtype=np.float32)


def run_expert_episode(env: gym.Env, seed: int, config: ExpertConfig | None = None) -> ExpertEpisode:
    """Reset ``env`` with ``seed``, run the feedback FSM until success or the env's step budget.

    Raises UnreachableError when a keyframe has no IK solution and ExpertFailure when the budget ran out
    (``cause`` from the env's ``info["failure_cause"]``); nothing half-valid is returned.
    """
    cfg = config or ExpertConfig()
    base = env.unwrapped
    physics = base.physics
    obs, info = env.reset(seed=seed)
    expert = FSMExpert(env, cfg)
    dense = base.config.control_mode == "dense"
    states, objects, actions, phases = [], [], [], []
    keyframes = [expert.command]
    kf_states = [np.concatenate(_frame(obs))]
    done = False
    while not done:
        target = expert.next_keyframe()
        phase = expert.last_phase
        keyframes.append(target)
        segment = _dense_segment(base.config, physics, keyframes[-2], target, cfg) if dense else [target]
        for action in segment:
            state, obj = _frame(obs)
            states.append(state), objects.append(obj), actions.append(action), phases.append(phase)
            obs, _, terminated, truncated, info = env.step(action)
            if truncated:
                cause = info.get("failure_cause") or "truncated"
                cube, _ = physics.object_pose()
                raise ExpertFailure(
                    f"seed {seed}: expert failed within the {base.config.episode_length}-step budget: {cause} "
                    f"(last phase {phase.label}, object at {np.round(cube, 3).tolist()})",
                    cause,
                    Phase(info.get("furthest_phase", phase)).label,
                )
            done = done or terminated  # a dense keyframe's segment is finished even after success
        kf_states.append(np.concatenate(_frame(obs)))
    # The final observed state, with a hold action, ends the episode.
    state, obj = _frame(obs)
    states.append(state), objects.append(obj), actions.append(keyframes[-1]), phases.append(Phase.PLACE_RETRACT)
    return ExpertEpisode(
        seed=seed,
        states=np.stack(states),
        env_states=np.stack(objects),
        actions=np.stack(actions).astype(np.float32),
        phases=np.asarray(phases, dtype=np.int64),
        keyframes=np.stack(keyframes),
        keyframe_states=np.stack(kf_states).astype(np.float32),
        success=True,
        info={"recoveries": list(expert.recoveries), "perturbations": base.pnp_task.perturbations_fired},
    )


def _dense_segment(env_cfg, physics, start: np.ndarray, target: np.ndarray, cfg: ExpertConfig) -> list[np.ndarray]:
    """Dense actions executing one keyframe: interpolated arm setpoints, a settle, then the gripper."""
    fps = env_cfg.fps
    carry = env_cfg.carry_min_time if env_cfg.carry_min_time > 0 and physics.object_in_grasp() else 0.0
    arm = joint_trajectory(start[:7], target[:7], fps, env_cfg.speed, ik=physics.path_ik, min_time=carry)
    steps = [np.append(q, start[7]) for q in arm]
    steps += [np.append(target[:7], start[7])] * math.ceil(cfg.settle_time * fps)
    if target[7] != start[7]:
        steps += [target.copy()] * math.ceil(cfg.gripper_time * fps)
    return [np.asarray(s, dtype=np.float32) for s in steps]
