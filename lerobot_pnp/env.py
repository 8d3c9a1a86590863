"""The gymnasium env: MuJoCo physics of Baxter's left arm, the cube and the place target.

This is the only module that steps MuJoCo. Two control modes share one joint-space interpolator:
``keyframe`` (the paper's: one step = move to a commanded joint keyframe, then gripper, then settle) and
``dense`` (one step = one control period at ``fps``). Task logic (reset distribution, success) lives in
``lerobot_pnp.task``; this module applies it to the physics.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, UnreachableError
from lerobot_pnp.ik import ArmIK
from lerobot_pnp.interpolation import PATH_KINDS, joint_trajectory
from lerobot_pnp.task import TaskConfig

CONTROL_MODES = ("keyframe", "dense")
CAMERAS = ("front", "overhead", "wrist")
DEFAULT_MAX_STEPS = {"keyframe": 10, "dense": 400}


class BaxterPnPEnv(gym.Env):
    """Baxter left-arm pick-and-place.

    Observation (dict): ``agent_pos`` (7 joint angles + gripper opening in [0, 1]), ``environment_state``
    (cube xyz in the base frame) and, when ``cameras`` is non-empty, ``pixels`` ({camera: HxWx3 uint8}).
    Action: 7 joint targets (rad) + gripper command (0 close, 1 open); joint targets are clipped to the limits.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(
        self,
        control_mode: str = "keyframe",
        fps: int = 20,
        cameras: tuple[str, ...] | list[str] = (),
        image_size: tuple[int, int] = (240, 320),
        render_mode: str | None = "rgb_array",
        speed: float = 1.0,
        path: str = "straight",
        task_config: TaskConfig | dict | None = None,
        **task_kwargs,
    ):
        if control_mode not in CONTROL_MODES:
            raise ConfigError(f"control_mode must be one of {CONTROL_MODES}, got {control_mode!r}")
        if not (isinstance(fps, int | np.integer) and 1 <= fps <= 500):
            raise ConfigError(f"fps must be an integer in [1, 500], got {fps!r}")
        if not 0 < speed <= 1:
            raise ConfigError(f"speed (fraction of Baxter's joint velocity limits) must be in (0, 1], got {speed}")
        if path not in PATH_KINDS:
            raise ConfigError(f"path must be one of {PATH_KINDS}, got {path!r}")
        unknown = [c for c in cameras if c not in CAMERAS]
        if unknown:
            raise ConfigError(f"unknown camera(s) {unknown}; available: {CAMERAS}")
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode must be 'rgb_array' or None, got {render_mode!r}")
        if isinstance(task_config, dict):
            task_config = TaskConfig(**task_config, **task_kwargs)
        elif task_config is None:
            task_config = TaskConfig(**task_kwargs)
        elif task_kwargs:
            raise ConfigError(f"pass task options either in task_config or as keywords, not both: {task_kwargs}")

        self.control_mode = control_mode
        self.fps = int(fps)
        self.cameras = tuple(cameras)
        self.image_size = tuple(image_size)
        self.render_mode = render_mode
        self.speed = float(speed)
        self.task_config = task_config
        self.task = robot.TASK
        self.task_description = robot.TASK
        self.metadata = {**self.metadata, "render_fps": self.fps}

        self.model = mujoco.MjModel.from_xml_path(str(robot.scene_path()))
        self.data = mujoco.MjData(self.model)
        self.ik = ArmIK(self.model)
        self.task_config.check_reachable(self.ik)
        self.path = path
        self._path_ik = self.ik if path == "straight" else None

        m = self.model
        self._qadr = np.array([m.joint(n).qposadr[0] for n in robot.JOINT_NAMES])
        self._dofadr = np.array([m.joint(n).dofadr[0] for n in robot.JOINT_NAMES])
        self._finger_qadr = np.array([m.joint(n).qposadr[0] for n in ("l_gripper_l_finger_joint", "l_gripper_r_finger_joint")])
        self._finger_dofadr = np.array([m.joint(n).dofadr[0] for n in ("l_gripper_l_finger_joint", "l_gripper_r_finger_joint")])
        self._arm_act = np.array([m.actuator(n).id for n in robot.JOINT_NAMES])
        self._grip_act = m.actuator("gripper").id
        cube_joint = m.joint(robot.CUBE_JOINT)
        self._cube_qadr, self._cube_dofadr = cube_joint.qposadr[0], cube_joint.dofadr[0]
        self._cube_body = m.body(robot.CUBE_BODY).id
        self._cube_geom = m.geom("cube").id
        self._pad_geoms = {m.geom("l_pad").id, m.geom("r_pad").id}
        self._is_finger_body = np.zeros(m.nbody, dtype=bool)
        self._is_finger_body[[m.body(n).id for n in ("l_finger", "r_finger", "l_finger_tip", "r_finger_tip")]] = True
        self._ee_site = m.site(robot.EE_SITE).id
        target = m.site(robot.TARGET_SITE).id
        m.site_pos[target][:2] = self.task_config.place_xy

        self.control_dt = 0.01  # interpolator update period in keyframe mode (100 Hz)
        self._substeps_keyframe = round(self.control_dt / m.opt.timestep)
        self._substeps_dense = max(1, round(1.0 / (self.fps * m.opt.timestep)))
        self._renderer = None
        self._step_count = 0
        # Optional observer called after every control tick (100 Hz in keyframe mode, fps in dense mode),
        # e.g. by the viewer to record the continuous motion between keyframes. It must not change the state.
        self.on_control_tick = None

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
            "environment_state": spaces.Box(-3.0, 3.0, (robot.OBJECT_DIM,), np.float32),
        }
        if self.cameras:
            h, w = self.image_size
            obs_spaces["pixels"] = spaces.Dict(
                {c: spaces.Box(0, 255, (h, w, 3), np.uint8) for c in self.cameras}
            )
        self.observation_space = spaces.Dict(obs_spaces)

    # ------------------------------------------------------------------ public state queries (the expert's API)
    def arm_qpos(self) -> np.ndarray:
        return self.data.qpos[self._qadr].copy()

    def gripper_opening(self) -> float:
        """Measured opening, 0 (closed) .. 1 (fully open)."""
        opening = 0.5 * (self.data.qpos[self._finger_qadr[0]] - self.data.qpos[self._finger_qadr[1]])
        return float(np.clip(opening / robot.FINGER_TRAVEL, 0.0, 1.0))

    def object_pose(self) -> tuple[np.ndarray, float]:
        """Cube position and yaw (rad) in the base frame (ground truth, no observation noise)."""
        pos = self.data.xpos[self._cube_body].copy()
        rot = self.data.xmat[self._cube_body].reshape(3, 3)
        return pos, float(math.atan2(rot[1, 0], rot[0, 0]))

    def ee_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return self.data.site_xpos[self._ee_site].copy(), self.data.site_xmat[self._ee_site].reshape(3, 3).copy()

    def _cube_contacts(self) -> np.ndarray:
        """Geoms in contact with the cube."""
        pairs = self.data.contact.geom[: self.data.ncon]
        mask = (pairs == self._cube_geom).any(axis=1)
        return pairs[mask].sum(axis=1) - self._cube_geom

    def object_in_grasp(self) -> bool:
        """Both finger pads touch the cube."""
        return self._pad_geoms.issubset(self._cube_contacts().tolist())

    def _gripper_touches_object(self) -> bool:
        return bool(self._is_finger_body[self.model.geom_bodyid[self._cube_contacts()]].any())

    def is_success(self) -> bool:
        """The task's success test (see TaskConfig.cube_placed / gripper_released) on the current state."""
        cube_pos = self.data.xpos[self._cube_body]
        cube_speed = float(np.linalg.norm(self.data.qvel[self._cube_dofadr : self._cube_dofadr + 3]))
        if not self.task_config.cube_placed(cube_pos, cube_speed):
            return False
        pad_bottom = self.data.site_xpos[self._ee_site][2] - 0.0035
        return self.task_config.gripper_released(
            cube_pos, self._gripper_touches_object(), self.gripper_opening(), pad_bottom
        )

    def state_vector(self) -> np.ndarray:
        """Noise-free agent state: joints + gripper opening."""
        return np.append(self.arm_qpos(), self.gripper_opening()).astype(np.float32)

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Seeded reset. ``options`` may pin the start: ``arm_qpos`` (7,), ``object_pos`` (3,), ``object_yaw``."""
        super().reset(seed=seed)
        options = options or {}
        rng = self.np_random
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        cube_pos, yaw = self.task_config.sample_object(rng)
        if "object_pos" in options:
            cube_pos = self._checked_option(options, "object_pos", 3)
            cube_pos[2] = robot.CUBE_REST_Z
        yaw = float(options.get("object_yaw", yaw))
        if "arm_qpos" in options:
            q = np.clip(self._checked_option(options, "arm_qpos", robot.N_JOINTS), robot.JOINT_LOWER, robot.JOINT_UPPER)
        else:
            q = self._sample_start_q(rng)
        d.qpos[self._qadr] = q
        d.qpos[self._finger_qadr] = (robot.FINGER_TRAVEL, -robot.FINGER_TRAVEL)
        d.qpos[self._cube_qadr : self._cube_qadr + 3] = cube_pos
        d.qpos[self._cube_qadr + 3 : self._cube_qadr + 7] = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
        d.ctrl[self._arm_act] = q
        d.ctrl[self._grip_act] = robot.FINGER_TRAVEL
        mujoco.mj_forward(m, d)
        mujoco.mj_step(m, d, round(0.1 / m.opt.timestep))  # let contacts settle (0.1 s)
        self._step_count = 0
        return self._get_obs(), self._get_info()

    def _sample_start_q(self, rng: np.random.Generator) -> np.ndarray:
        for _ in range(20):
            start = self.task_config.sample_start(rng)
            try:
                return self.ik.solve(start, 0.0, robot.NEUTRAL_Q)
            except UnreachableError:
                continue
        raise UnreachableError(
            f"no reachable start pose found in the box {self.task_config.start_low}..{self.task_config.start_high}"
        )

    @staticmethod
    def _checked_option(options: dict, key: str, size: int) -> np.ndarray:
        value = np.asarray(options[key], dtype=float).reshape(-1)
        if value.shape != (size,) or not np.all(np.isfinite(value)):
            raise ValueError(f"reset option {key!r} must be {size} finite numbers, got {options[key]!r}")
        return value

    def step(self, action):
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        if action.shape != (robot.ACTION_DIM,):
            raise ValueError(f"action must have shape ({robot.ACTION_DIM},) (7 joint targets + gripper), got {action.shape}")
        if not np.all(np.isfinite(action)):
            raise ValueError(f"action contains NaN/inf: {action.tolist()}")
        q_target = np.clip(action[: robot.N_JOINTS], robot.JOINT_LOWER, robot.JOINT_UPPER)
        grip = float(np.clip(action[-1], 0.0, 1.0))
        if self.control_mode == "keyframe":
            self._move_to_keyframe(q_target, grip)
        else:
            self._dense_step(q_target, grip)
        self._step_count += 1
        if self.task_config.nudge_max > 0 and self._step_count == self.task_config.nudge_at_step:
            self._nudge_object()
        self._check_physics()
        info = self._get_info()
        return self._get_obs(), float(info["is_success"]), bool(info["is_success"]), False, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        return self._render_camera("front")

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ control
    def _run(self, substeps: int) -> None:
        mujoco.mj_step(self.model, self.data, substeps)
        if self.on_control_tick is not None:
            self.on_control_tick(self)

    def _move_to_keyframe(self, q_target: np.ndarray, grip: float) -> None:
        """Interpolate the arm to ``q_target`` (min-jerk, within the joint velocity limits), settle, then grip."""
        d = self.data
        for setpoint in joint_trajectory(
            d.ctrl[self._arm_act], q_target, 1.0 / self.control_dt, self.speed, ik=self._path_ik
        ):
            d.ctrl[self._arm_act] = setpoint
            self._run(self._substeps_keyframe)
        self._settle(lambda: np.max(np.abs(d.qvel[self._dofadr])) < 0.02, max_time=1.0)
        grip_ctrl = grip * robot.FINGER_TRAVEL
        if abs(grip_ctrl - d.ctrl[self._grip_act]) > 1e-9:
            d.ctrl[self._grip_act] = grip_ctrl
            self._run(round(0.1 / self.model.opt.timestep))
            self._settle(lambda: np.max(np.abs(d.qvel[self._finger_dofadr])) < 1e-3, max_time=0.8)

    def _settle(self, done, max_time: float) -> None:
        for _ in range(math.ceil(max_time / self.control_dt)):
            if done():
                return
            self._run(self._substeps_keyframe)

    def _dense_step(self, q_target: np.ndarray, grip: float) -> None:
        """One control period: joint setpoints rate-limited by the velocity limits, then physics."""
        d = self.data
        max_delta = robot.JOINT_VEL_LIMIT * self.speed / self.fps
        q_prev = d.ctrl[self._arm_act]
        d.ctrl[self._arm_act] = q_prev + np.clip(q_target - q_prev, -max_delta, max_delta)
        d.ctrl[self._grip_act] = grip * robot.FINGER_TRAVEL
        self._run(self._substeps_dense)

    def _nudge_object(self) -> None:
        """Displace the cube (only while it rests on the table, i.e. before the grasp)."""
        if self.object_in_grasp():
            return
        offset = self.task_config.sample_nudge(self.np_random)
        self.data.qpos[self._cube_qadr : self._cube_qadr + 3] += offset
        self.data.qvel[self._cube_dofadr : self._cube_dofadr + 6] = 0
        mujoco.mj_forward(self.model, self.data)

    def _check_physics(self) -> None:
        if not np.all(np.isfinite(self.data.qpos)):
            raise RuntimeError("physics diverged (non-finite state); this is a bug, please report the seed and actions")

    # ------------------------------------------------------------------ observations
    def _get_obs(self) -> dict:
        state = self.state_vector()
        cube_pos, _ = self.object_pose()
        tc = self.task_config
        if tc.obs_noise_joints > 0:
            state[: robot.N_JOINTS] += self.np_random.normal(0, tc.obs_noise_joints, robot.N_JOINTS).astype(np.float32)
        if tc.obs_noise_object > 0:
            cube_pos = cube_pos + self.np_random.normal(0, tc.obs_noise_object, 3)
        obs = {"agent_pos": state, "environment_state": cube_pos.astype(np.float32)}
        if self.cameras:
            obs["pixels"] = {c: self._render_camera(c) for c in self.cameras}
        return obs

    def _get_info(self) -> dict:
        return {"is_success": self.is_success()}

    def _render_camera(self, camera: str) -> np.ndarray:
        if self._renderer is None:
            os.environ.setdefault("MUJOCO_GL", "egl")
            h, w = self.image_size
            self._renderer = mujoco.Renderer(self.model, height=h, width=w)
        self._renderer.update_scene(self.data, camera=camera)
        return self._renderer.render().copy()

    def config_dict(self) -> dict:
        """Everything needed to rebuild this env (saved beside datasets and results)."""
        return {
            "control_mode": self.control_mode,
            "fps": self.fps,
            "cameras": list(self.cameras),
            "image_size": list(self.image_size),
            "speed": self.speed,
            "path": self.path,
            "task_config": asdict(self.task_config),
        }
