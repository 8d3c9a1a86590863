"""The gymnasium env: a thin layer of spaces, reset and step over the physics and the task.

Built only from the env config (``env_config.make_env`` / LeRobot's ``create_envs``). Two control modes share
the physics' interpolator: ``keyframe`` (the paper's: one step = move to a commanded joint keyframe, then
the gripper, then settle) and ``dense`` (one step = one control period at ``fps``).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.sim import visual
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.physics import BaxterPhysics
from lerobot_pnp.sim.scene_variation import SceneVariation
from lerobot_pnp.sim.task import PickPlaceTask


class BaxterPnPEnv(gym.Env):
    """Baxter left-arm pick-and-place.

    Observation (dict): ``agent_pos`` (7 joint angles + gripper opening in [0, 1]), ``environment_state``
    (object xyz in the base frame) and, with cameras, ``pixels`` ({camera: HxWx3 uint8}).
    Action: 7 joint targets (rad) + gripper command (0 close, 1 open); joint targets are clipped to the limits.

    ``config`` is a ``BaxterPnPEnvConfig`` or its ``to_dict()``; keyword ``changes`` override its fields
    (``gym.make("lerobot_pnp/BaxterPnP-v0", nudge_max=0.03)``).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1}

    def __init__(
        self, config: BaxterPnPEnvConfig | dict | None = None, render_mode: str | None = "rgb_array", **changes
    ):
        if isinstance(config, BaxterPnPEnvConfig):
            config = config.with_changes(**changes) if changes else config
        else:
            config = BaxterPnPEnvConfig.from_dict(config or {}, **changes)
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode must be 'rgb_array' or None, got {render_mode!r}")
        self.config = config
        self.render_mode = render_mode
        self.task = robot.TASK  # LeRobot reads the language task from these two attributes
        self.task_description = robot.TASK
        self.metadata = {**self.metadata, "render_fps": config.fps}
        self.physics = BaxterPhysics(config.straight_paths, distractor_slots=config.distractors_range[1])
        self.pnp_task = PickPlaceTask(config)
        if visual.is_varied(config):  # what the cameras see varies per episode; the scene as modelled otherwise
            self.pnp_task.scene = SceneVariation(config, self.physics)
        self.pnp_task.check_reachable(self.physics)
        self.physics.set_place_target(self.pnp_task.place_xy)  # before the first reset too (viewers, renders)
        self._step_count = 0
        # The one episode-length rule: the config's ``episode_length`` (LeRobot's eval reads this attribute).
        self._max_episode_steps = config.episode_length

        self.action_space = spaces.Box(
            low=np.append(robot.JOINT_LOWER, robot.GRIPPER_CLOSED).astype(np.float32),
            high=np.append(robot.JOINT_UPPER, robot.GRIPPER_OPEN).astype(np.float32),
            dtype=np.float32,
        )
        obs_spaces = {
            # Limits with a margin for observation noise; the gripper opening is in [0, 1].
            "agent_pos": spaces.Box(
                np.append(robot.JOINT_LOWER - 0.5, -0.5).astype(np.float32),
                np.append(robot.JOINT_UPPER + 0.5, 1.5).astype(np.float32),
                dtype=np.float32,
            ),
            # object xyz [+ (sin 4 yaw, cos 4 yaw)] [+ goal xy] [+ phase one-hot], see config.environment_state_names
            "environment_state": spaces.Box(-3.0, 3.0, (len(config.environment_state_names),), np.float32),
        }
        if config.cameras:
            h, w = config.image_height, config.image_width
            obs_spaces["pixels"] = spaces.Dict({c: spaces.Box(0, 255, (h, w, 3), np.uint8) for c in config.cameras})
        self.observation_space = spaces.Dict(obs_spaces)

    @property
    def control_mode(self) -> str:
        return self.config.control_mode

    @property
    def fps(self) -> int:
        return self.config.fps

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Seeded reset. ``options`` may pin the start: ``arm_qpos`` (7,), ``object_pos`` (3,), ``object_yaw``."""
        super().reset(seed=seed)
        self.pnp_task.initialize_episode(self.physics, self.np_random, options)
        self._step_count = 0
        return self._observation(), self._info(truncated=False)

    def step(self, action):
        action = _real_action(action)
        if action.shape != (robot.ACTION_DIM,):
            raise ConfigError(
                f"action must have shape ({robot.ACTION_DIM},) (7 joint targets + gripper), got {action.shape}"
            )
        if not np.all(np.isfinite(action)):
            raise ConfigError(
                f"action contains NaN/inf: {action.tolist()} (from a policy: check its checkpoint's weights and "
                "normalisation stats, e.g. with lerobot_pnp.evaluation.checkpoints.load_policy)"
            )
        q_target = np.clip(action[: robot.N_JOINTS], robot.JOINT_LOWER, robot.JOINT_UPPER)
        grip = float(np.clip(action[-1], 0.0, 1.0))
        if self.config.control_mode == "keyframe":
            self.physics.move_to_keyframe(q_target, grip, self.config.speed)
        else:
            self.physics.dense_step(q_target, grip, self.config.fps, self.config.speed)
        self._step_count += 1
        self.pnp_task.after_step(self.physics, self._step_count, self.np_random)
        self.physics.check_finite()
        success = self.pnp_task.is_success(self.physics)
        truncated = not success and self._step_count >= self._max_episode_steps
        info = self._info(truncated, success)
        return self._observation(), float(success), success, truncated, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        cfg = self.config
        return self.physics.render("front", cfg.image_height, cfg.image_width, cfg.render_effects)

    def close(self):
        self.physics.close()

    # ------------------------------------------------------------------ observations
    def _observation(self) -> dict:
        obs = self.pnp_task.observe(self.physics, self.np_random)
        if self.config.cameras:
            h, w = self.config.image_height, self.config.image_width
            fx = self.config.render_effects
            obs["pixels"] = {c: self.physics.render(c, h, w, fx) for c in self.config.cameras}
            if self.pnp_task.scene is not None:  # the sensor's blur and noise (the video's frames have none)
                obs["pixels"] = self.pnp_task.scene.images(obs["pixels"])
        return obs

    def _info(self, truncated: bool, success: bool | None = None) -> dict:
        """``is_success`` (LeRobot reads it), the inferred FSM ``phase``, the ``furthest_phase`` reached, the
        perturbations applied so far and, when the episode ends unsolved, the ``failure_cause``."""
        success = self.pnp_task.is_success(self.physics) if success is None else success
        return {"is_success": success, **self.pnp_task.step_info(self.physics, success, truncated)}

    def is_success(self) -> bool:
        return self.pnp_task.is_success(self.physics)


def _real_action(action) -> np.ndarray:
    """The action as float64 numbers; a non-numeric or complex action is one ConfigError naming it."""
    try:
        raw = np.asarray(action)
    except ValueError:  # ragged nesting
        raise ConfigError(f"action must be {robot.ACTION_DIM} real numbers, got {action!r}") from None
    if raw.dtype.kind not in "biuf":
        raise ConfigError(f"action must be {robot.ACTION_DIM} real numbers, got dtype {raw.dtype}: {action!r}")
    return raw.astype(np.float64).reshape(-1)
