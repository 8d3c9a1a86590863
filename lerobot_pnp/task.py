"""The pick-and-place task on top of the physics: reset distribution, perturbations, observations, success.

``PickPlaceTask`` reads its numbers from the env config (``env_config.BaxterPnPEnvConfig``, the one
description of the task) and acts on a ``physics.BaxterPhysics``. It never steps the simulation itself
except through the physics' primitives, and it draws every random number from the generator it is given
(the env's seeded ``np_random``), always in the same order, so an episode is a function of its seed.
"""

from __future__ import annotations

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, ResetOptionError, UnreachableError
from lerobot_pnp.physics import BaxterPhysics

RESET_OPTIONS = ("arm_qpos", "object_pos", "object_yaw")
_START_TRIES = 20


class PickPlaceTask:
    """Where things start, what disturbs them, what the policy observes and what counts as success."""

    def __init__(self, config):
        self.config = config

    # ------------------------------------------------------------------ set-up
    def check_reachable(self, physics: BaxterPhysics) -> None:
        """Raise ConfigError if any corner of the object box (grasp and hover) or the place target is unreachable."""
        c = self.config
        yaws = sorted(set(c.yaw_range))
        corners = [(x, y) for x in (c.object_low[0], c.object_high[0]) for y in (c.object_low[1], c.object_high[1])]
        checks = [("object box corner", p, yaw) for p in corners for yaw in yaws] + [("place target", c.place_xy, 0.0)]
        for what, (x, y), yaw in checks:
            seed = robot.NEUTRAL_Q
            try:
                for z in (robot.CUBE_REST_Z + c.hover_height, robot.CUBE_REST_Z):
                    seed = physics.ik.solve(np.array([x, y, z]), yaw, seed)
            except UnreachableError as err:
                raise ConfigError(
                    f"env: {what} ({x:.3f}, {y:.3f}) with hover {c.hover_height} m is out of the arm's reach: {err}"
                ) from None

    def initialize_episode(self, physics: BaxterPhysics, rng: np.random.Generator, options: dict | None) -> None:
        """Sample (or take from ``options``) the object pose and the start pose, and reset the physics."""
        options = dict(options or {})
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise ResetOptionError(f"unknown reset option(s) {unknown}; valid options: {list(RESET_OPTIONS)}")
        c = self.config
        xy = rng.uniform(c.object_low, c.object_high)
        yaw = float(rng.uniform(*c.yaw_range)) if c.yaw_range[1] > c.yaw_range[0] else c.yaw_range[0]
        object_pos = np.array([xy[0], xy[1], robot.CUBE_REST_Z])
        if "object_pos" in options:
            object_pos = _vector_option(options, "object_pos", 3)
            object_pos[2] = robot.CUBE_REST_Z
            self._check_object_option(physics, object_pos)
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
        physics.set_place_target(c.place_xy)
        physics.reset(q, object_pos, yaw)

    def _check_object_option(self, physics: BaxterPhysics, pos: np.ndarray) -> None:
        c = self.config
        if np.linalg.norm(pos[:2] - np.asarray(c.place_xy)) <= c.success_xy_tol + robot.CUBE_SIZE / 2:
            raise ResetOptionError(
                f"reset option 'object_pos' {np.round(pos[:2], 3).tolist()} is on the place target {list(c.place_xy)}: "
                "the episode would start solved"
            )
        try:
            physics.ik.solve(pos + [0, 0, c.hover_height], 0.0, robot.NEUTRAL_Q)
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

    # ------------------------------------------------------------------ during the episode
    def after_step(self, physics: BaxterPhysics, step_count: int, rng: np.random.Generator) -> None:
        """Apply the perturbations scheduled after env step ``step_count``."""
        c = self.config
        if c.nudge_max > 0 and step_count == c.nudge_at_step and not physics.object_in_grasp():
            angle = rng.uniform(0, 2 * np.pi)
            radius = c.nudge_max * np.sqrt(rng.uniform())
            physics.displace_object(np.array([radius * np.cos(angle), radius * np.sin(angle), 0.0]))

    def observe(self, physics: BaxterPhysics, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """The policy's view: ``agent_pos`` (joints + gripper) and ``environment_state`` (object xyz), noisy."""
        c = self.config
        state = physics.state_vector()
        object_pos, _ = physics.object_pose()
        if c.obs_noise_joints > 0:
            state[: robot.N_JOINTS] += rng.normal(0, c.obs_noise_joints, robot.N_JOINTS).astype(np.float32)
        if c.obs_noise_object > 0:
            object_pos = object_pos + rng.normal(0, c.obs_noise_object, 3)
        return {"agent_pos": state, "environment_state": object_pos.astype(np.float32)}

    # ------------------------------------------------------------------ success
    def object_placed(self, physics: BaxterPhysics) -> bool:
        """The object rests on the table within tolerance of the target."""
        pos, _ = physics.object_pose()
        on_target = np.linalg.norm(pos[:2] - np.asarray(self.config.place_xy)) <= self.config.success_xy_tol
        return bool(on_target and abs(pos[2] - robot.CUBE_REST_Z) < 0.005 and physics.object_speed() < 0.02)

    @staticmethod
    def gripper_released(physics: BaxterPhysics) -> bool:
        """Fingers off the object, gripper open, and the pads clear above the object's top."""
        pos, _ = physics.object_pose()
        object_top = pos[2] + robot.CUBE_SIZE / 2
        return bool(
            not physics.gripper_touches_object()
            and physics.gripper_opening() > 0.5
            and physics.pad_bottom_z() > object_top + 0.01
        )

    def is_success(self, physics: BaxterPhysics) -> bool:
        # The contact query is skipped unless the object is placed (most steps).
        return self.object_placed(physics) and self.gripper_released(physics)


def _vector_option(options: dict, key: str, size: int) -> np.ndarray:
    try:
        value = np.asarray(options[key], dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ResetOptionError(f"reset option {key!r} must be {size} finite number(s), got {options[key]!r}") from None
    if value.shape != (size,) or not np.all(np.isfinite(value)):
        raise ResetOptionError(f"reset option {key!r} must be {size} finite number(s), got {options[key]!r}")
    return value
