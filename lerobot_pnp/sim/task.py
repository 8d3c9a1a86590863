"""The pick-and-place task on top of the physics: reset distribution, perturbations, observations, success.

``PickPlaceTask`` reads its numbers from the env config (``env_config.BaxterPnPEnvConfig``, the one
description of the task) and acts on a ``physics.BaxterPhysics``. It never steps the simulation itself
except through the physics' primitives, and it draws every random number from the generator it is given
(the env's seeded ``np_random``), always in the same order, so an episode is a function of its seed.
"""

from __future__ import annotations

import math

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, ResetOptionError, UnreachableError
from lerobot_pnp.robot import Phase
from lerobot_pnp.sim.disturbances import Disturbances
from lerobot_pnp.sim.physics import BaxterPhysics

RESET_OPTIONS = ("arm_qpos", "object_pos", "object_yaw")
_START_TRIES = 20
_OBJECT_TRIES = 10_000  # rejection draws for an object position outside the excluded box

_REACHABLE: set[tuple] = set()  # the regions check_reachable has found reachable in this process

FAILURE_CAUSES = ("not_grasped", "dropped", "not_transported", "not_placed", "not_released")


class PickPlaceTask:
    """Where things start, what disturbs them, what the policy observes and what counts as success."""

    def __init__(self, config):
        self.config = config
        self.place_xy = np.asarray(config.place_low, dtype=float)
        self.disturbances = Disturbances(config)
        self._bias = np.zeros(3)
        self._history: list[dict] = []
        self.latest_observation: dict[str, np.ndarray] | None = None
        self._furthest = 0
        self._was_grasped = False
        # The episode's visual variation (``scene_variation.SceneVariation``), set by the env when its task varies
        # what the cameras see; drawn from generators spawned from ``rng``, so it takes no draw from it.
        self.scene = None

    @property
    def perturbations_fired(self) -> list[str]:
        """Names of the perturbations applied so far in this episode (in order)."""
        return list(self.disturbances.fired)

    # ------------------------------------------------------------------ set-up
    def check_reachable(self, physics: BaxterPhysics) -> None:
        """Raise ConfigError if any corner of the object box (grasp and hover) or the place region is unreachable.

        A pass is remembered for the process (``_REACHABLE``): a vector env builds one env per episode slot from
        the same config, and the answer depends only on the regions checked and the arm (IK on its own data)."""
        c = self.config
        yaws = sorted({c.yaw_range[0], c.yaw_range[1]} if c.yaw_range[1] - c.yaw_range[0] < np.pi / 2 else {0.0})
        corners = [(x, y) for x in (c.object_low[0], c.object_high[0]) for y in (c.object_low[1], c.object_high[1])]
        places = {(x, y) for x in (c.place_low[0], c.place_high[0]) for y in (c.place_low[1], c.place_high[1])}
        checks = [("object box corner", p, yaw) for p in corners for yaw in yaws]
        checks += [("place region corner", p, 0.0) for p in sorted(places)]
        if c.landing_low != c.landing_high:  # a disturbed object may land anywhere in it, with any yaw
            landing = [
                (x, y) for x in (c.landing_low[0], c.landing_high[0]) for y in (c.landing_low[1], c.landing_high[1])
            ]
            checks += [("landing box corner", p, yaw) for p in landing for yaw in (-np.pi / 4, 0.0, np.pi / 4)]
        heights = (robot.CUBE_REST_Z + c.hover_height, robot.TABLE_TOP_Z + c.size_range[0] / 2)
        key = (tuple((x, y, yaw) for _, (x, y), yaw in checks), heights)
        if key in _REACHABLE:
            return
        for what, (x, y), yaw in checks:
            seed = robot.NEUTRAL_Q
            try:
                for z in heights:
                    seed = physics.ik.solve(np.array([x, y, z]), grasp_yaw(yaw), seed)
            except UnreachableError as err:
                raise ConfigError(
                    f"env: {what} ({x:.3f}, {y:.3f}) with hover {c.hover_height} m is out of the arm's reach: {err}"
                ) from None
        _REACHABLE.add(key)

    def initialize_episode(self, physics: BaxterPhysics, rng: np.random.Generator, options: dict | None) -> None:
        """Sample (or take from ``options``) the object pose, the target and the start pose; reset the physics.

        Random numbers are drawn only for the features a task enables, so the paper's task draws exactly the
        numbers it always drew (its datasets do not change when features are added).
        """
        # LeRobot's own signals (e.g. "lerobot_new_rollout" from lerobot-eval) are not ours to check.
        options = {k: v for k, v in (options or {}).items() if not str(k).startswith("lerobot_")}
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise ResetOptionError(f"unknown reset option(s) {unknown}; valid options: {list(RESET_OPTIONS)}")
        c = self.config
        xy = self._sample_object_xy(rng)
        yaw = float(rng.uniform(*c.yaw_range)) if c.yaw_range[1] > c.yaw_range[0] else c.yaw_range[0]
        object_pos = np.array([xy[0], xy[1], 0.0])
        if "object_pos" in options:
            object_pos = _vector_option(options, "object_pos", 3)
        if "object_yaw" in options:
            yaw = float(_vector_option(options, "object_yaw", 1)[0])
        if "arm_qpos" in options:
            q = _vector_option(options, "arm_qpos", robot.N_JOINTS)
            outside = (q < robot.JOINT_LOWER - 1e-6) | (q > robot.JOINT_UPPER + 1e-6)
            if outside.any():
                names = [robot.JOINT_NAMES[i] for i in np.flatnonzero(outside)]
                raise ResetOptionError(f"reset option 'arm_qpos' is outside the joint limits at {names}")
        else:
            q = self._sample_start_q(physics, rng)
        self.place_xy = _uniform(rng, c.place_low, c.place_high)
        mass, friction = _uniform(rng, *c.mass_range), _uniform(rng, *c.friction_range)
        size = float(_uniform(rng, *c.size_range))
        given_z, object_pos[2] = object_pos[2], physics.object_rest_z(size)
        if "object_pos" in options:  # checked before anything in the model changes
            if given_z != 0.0 and abs(given_z - object_pos[2]) > 1e-3:
                raise ResetOptionError(
                    f"reset option 'object_pos' z={given_z:.4f} is not the object's rest height {object_pos[2]:.4f} "
                    "(it starts resting on the table): pass z = 0 or the rest height"
                )
            self._check_object_option(physics, object_pos, size)
        if (mass, friction) != physics.object_properties():
            physics.set_object_properties(float(mass), float(friction))
        if size != physics.object_size:
            physics.set_object_size(size)
        self._bias = np.zeros(3)

        def draw_bias():
            if c.obs_bias_object > 0:
                angle = rng.uniform(0, 2 * np.pi)
                self._bias[:2] = c.obs_bias_object * np.array([np.cos(angle), np.sin(angle)])

        self.disturbances.reset(rng, draw_bias)
        self._history, self._furthest, self._was_grasped = [], 0, False
        physics.set_place_target(self.place_xy)
        physics.disturb, physics.carry_min_time = None, c.carry_min_time
        if self.scene is not None:  # before the reset: its forward pass places the moved cameras and lights
            self.scene.reset(rng, object_pos[:2], self.place_xy)
        physics.reset(q, object_pos, yaw)
        self.disturbances.attach(self, physics)

    def _sample_object_xy(self, rng: np.random.Generator) -> np.ndarray:
        """Uniform in the object box outside the excluded box (rejection sampling: exactly uniform on the band,
        and without an excluded box the first draw is taken, so the paper's task draws what it always drew)."""
        c = self.config
        lo, hi = np.asarray(c.object_exclude_low), np.asarray(c.object_exclude_high)
        for _ in range(_OBJECT_TRIES):
            xy = rng.uniform(c.object_low, c.object_high)
            if not np.all((lo < xy) & (xy < hi)):
                return xy
        raise ConfigError(
            f"env.object_exclude_low/high {list(c.object_exclude_low)}..{list(c.object_exclude_high)} leaves almost "
            f"none of the object box {list(c.object_low)}..{list(c.object_high)} ({_OBJECT_TRIES} draws rejected)"
        )

    def _check_object_option(self, physics: BaxterPhysics, pos: np.ndarray, size: float) -> None:
        c = self.config
        if np.linalg.norm(pos[:2] - self.place_xy) <= c.success_xy_tol + size / 2:
            raise ResetOptionError(
                f"reset option 'object_pos' {np.round(pos[:2], 3).tolist()} is on the place target "
                f"{np.round(self.place_xy, 3).tolist()}: the episode would start solved"
            )
        try:
            physics.ik.solve(pos + [0, 0, c.hover_height], 0.0, robot.NEUTRAL_Q)
            physics.ik.solve(pos, 0.0, robot.NEUTRAL_Q)
        except UnreachableError:
            raise ResetOptionError(
                f"reset option 'object_pos' {np.round(pos[:2], 3).tolist()} is out of the arm's reach "
                f"(the object box is {list(c.object_low)}..{list(c.object_high)})"
            ) from None

    def _sample_start_q(self, physics: BaxterPhysics, rng: np.random.Generator) -> np.ndarray:
        c = self.config
        for _ in range(_START_TRIES):
            start = rng.uniform(c.start_low, c.start_high)
            try:
                return physics.ik.solve(start, 0.0, robot.NEUTRAL_Q)
            except UnreachableError:
                continue
        raise UnreachableError(f"no reachable start pose found in the box {c.start_low}..{c.start_high}")

    # ------------------------------------------------------------------ perturbations
    def after_step(self, physics: BaxterPhysics, step_count: int, rng: np.random.Generator) -> None:
        """Apply the perturbations due after env step ``step_count`` (``disturbances.Disturbances``).

        nudge: the resting object is pushed before the grasp (the paper's feedback test).
        grasp_miss: the object slides out of the open gripper at the object, or slips out during the lift.
        drop: the held object is knocked out of the fingers in transport and falls to the table.
        displace: the object was placed and released -> it is pushed off the target.
        """
        self.disturbances.after_step(self, physics, step_count, rng)

    # ------------------------------------------------------------------ observations
    def observe(self, physics: BaxterPhysics, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """The policy's view: ``agent_pos`` (joints + gripper) and ``environment_state`` (object xyz [+ yaw
        features] [+ goal xy] [+ phase one-hot]), with the configured noise, bias and latency."""
        c = self.config
        state = physics.state_vector()
        object_pos, yaw = physics.object_pose()
        if c.obs_noise_joints > 0:
            state[: robot.N_JOINTS] += rng.normal(0, c.obs_noise_joints, robot.N_JOINTS).astype(np.float32)
        if c.obs_noise_object > 0:
            object_pos = object_pos + rng.normal(0, c.obs_noise_object, 3)
        env_state = [object_pos + self._bias]
        if c.observe_yaw:
            env_state.append([np.sin(4 * yaw), np.cos(4 * yaw)])
        if c.observe_goal:
            env_state.append(self.place_xy)
        if c.observe_phase:  # privileged: from the true state, never noisy (latency still applies)
            env_state.append(np.eye(robot.N_KEYFRAMES)[self.infer_phase(physics)])
        obs = {"agent_pos": state, "environment_state": np.concatenate(env_state).astype(np.float32)}
        self.latest_observation = obs  # what an observer without latency sees now (DAgger records it)
        longest = max(c.obs_latency, c.obs_latency_max)
        if longest <= 0:
            return obs
        latency = self.disturbances.observed_latency(rng)
        self._history.append(obs)
        del self._history[: -(longest + 1)]
        return self._history[max(0, len(self._history) - 1 - latency)]

    # ------------------------------------------------------------------ progress and success
    def object_placed(self, physics: BaxterPhysics) -> bool:
        """The object rests on the table within tolerance of the target."""
        pos, _ = physics.object_pose()
        on_target = np.linalg.norm(pos[:2] - self.place_xy) <= self.config.success_xy_tol
        resting = abs(pos[2] - physics.object_rest_z()) < 0.005
        return bool(on_target and resting and physics.object_speed() < 0.02)

    @staticmethod
    def gripper_released(physics: BaxterPhysics) -> bool:
        """Fingers off the object, gripper open, and the pads clear above the object's top."""
        pos, _ = physics.object_pose()
        object_top = pos[2] + physics.object_size / 2
        return bool(
            not physics.gripper_touches_object()
            and physics.gripper_opening() > 0.5
            and physics.pad_bottom_z() > object_top + 0.01
        )

    def is_success(self, physics: BaxterPhysics) -> bool:
        # The contact query is skipped unless the object is placed (most steps).
        return self.object_placed(physics) and self.gripper_released(physics)

    def infer_phase(self, physics: BaxterPhysics) -> Phase:
        """The FSM state the physical situation corresponds to. A pure query (no state of the task changes)."""
        obj, _ = physics.object_pose()
        ee, _ = physics.ee_pose()
        at_target = np.linalg.norm(obj[:2] - self.place_xy) <= self.config.success_xy_tol
        if physics.object_in_grasp():
            if obj[2] < physics.object_rest_z() + 0.01:
                return Phase.PLACE_DESCEND if at_target else Phase.PICK_CLOSE
            return Phase.PLACE_APPROACH if np.linalg.norm(obj[:2] - self.place_xy) < 0.03 else Phase.PICK_RETRACT
        if self.object_placed(physics):
            return Phase.PLACE_RETRACT if self.gripper_released(physics) else Phase.PLACE_OPEN
        if np.linalg.norm(ee[:2] - obj[:2]) < 0.02:
            above = physics.pad_bottom_z() < obj[2] + physics.object_size / 2
            return Phase.PICK_GRASP if above else Phase.PICK_APPROACH
        return Phase.PICK_START

    def step_info(self, physics: BaxterPhysics, success: bool, truncated: bool) -> dict:
        """``info`` entries: the inferred phase, the furthest reached, the perturbations, the failure cause.

        The env calls it once per reset and per step, on the state it then observes, so it is the one place that
        records whether the object was ever held (for the ``dropped`` / ``not_grasped`` cause). The phases are
        plain ints in ``info``: gymnasium's vector envs stack ``info`` values by their exact type.
        """
        self._was_grasped |= physics.object_in_grasp()
        phase = self.infer_phase(physics)
        self._furthest = max(self._furthest, phase)
        cause = None
        if truncated and not success:
            if phase >= Phase.PLACE_OPEN:
                cause = "not_released"
            elif phase >= Phase.PLACE_APPROACH:
                cause = "not_placed"
            elif phase >= Phase.PICK_CLOSE:
                cause = "not_transported"
            else:
                cause = "dropped" if self._was_grasped else "not_grasped"
        return {
            "phase": int(phase),
            "furthest_phase": int(self._furthest),
            "perturbations": ",".join(self.disturbances.fired),
            "failure_cause": cause or "",
        }


def _uniform(rng: np.random.Generator, low, high):
    """A uniform draw, or ``low`` itself (no draw) when the range is a single value."""
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    if np.all(low == high):
        return low.copy() if low.ndim else float(low)
    value = rng.uniform(low, high)
    return value if low.ndim else float(value)


def grasp_yaw(object_yaw: float) -> float:
    """The gripper yaw closest to 0 that aligns the fingers with the cube's faces (90 deg symmetry)."""
    return (object_yaw + math.pi / 4) % (math.pi / 2) - math.pi / 4


def _vector_option(options: dict, key: str, size: int) -> np.ndarray:
    try:
        value = np.asarray(options[key], dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ResetOptionError(f"reset option {key!r} must be {size} finite number(s), got {options[key]!r}") from None
    if value.shape != (size,) or not np.all(np.isfinite(value)):
        raise ResetOptionError(f"reset option {key!r} must be {size} finite number(s), got {options[key]!r}")
    return value
