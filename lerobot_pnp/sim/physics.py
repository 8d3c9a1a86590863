"""MuJoCo physics of Baxter's left arm, its gripper, the cube and the place target (no task, no gym).

``BaxterPhysics`` owns the ``MjModel`` / ``MjData`` and is the only code that steps MuJoCo. It offers
named queries (arm joints, gripper opening, end-effector pose, object pose, contacts) and control
primitives (move to a joint keyframe through the straight-path interpolator, one dense control period,
set the whole state, displace the object). The task (``task.py``) decides what happens; the gym env
(``env.py``) exposes it; the expert and the viewer use these public methods only.
"""

from __future__ import annotations

import math

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import PhysicsError
from lerobot_pnp.sim.interpolation import joint_trajectory
from lerobot_pnp.sim.mujoco_gl import check_mujoco_gl, default_mujoco_gl

default_mujoco_gl()  # MuJoCo reads MUJOCO_GL once, when imported: headless EGL on Linux unless the user chose
check_mujoco_gl()  # a value MuJoCo rejects is one line, not a traceback from inside ``import mujoco``

import mujoco  # noqa: E402

from lerobot_pnp.sim.distractors import scene_model  # noqa: E402  (imports MuJoCo too)
from lerobot_pnp.sim.ik import ArmIK  # noqa: E402  (imports MuJoCo too)

CONTROL_DT = 0.01  # interpolator update period in keyframe mode (100 Hz)
_FINGER_JOINTS = ("l_gripper_l_finger_joint", "l_gripper_r_finger_joint")
_FINGER_BODIES = ("l_finger", "r_finger", "l_finger_tip", "r_finger_tip")
_PAD_HALF_THICKNESS = 0.0035  # m, from the gripper site down to the pads' bottom face


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice when it is a run of consecutive addresses, else itself."""
    start = int(index[0])
    return slice(start, start + len(index)) if np.array_equal(index, np.arange(start, start + len(index))) else index


class BaxterPhysics:
    """The simulated scene. ``straight_paths`` makes keyframe moves follow straight Cartesian segments."""

    def __init__(self, straight_paths: bool = True, distractor_slots: int = 0):
        # ``distractor_slots``: visual-only distractor geoms added to the scene (``distractors.scene_model``)
        self.model = scene_model(distractor_slots)
        self.data = mujoco.MjData(self.model)
        self.ik = ArmIK(self.model)
        self.path_ik = self.ik if straight_paths else None
        m = self.model
        self._qadr = np.array([m.joint(n).qposadr[0] for n in robot.JOINT_NAMES])
        self._dofadr = np.array([m.joint(n).dofadr[0] for n in robot.JOINT_NAMES])
        self._finger_qadr = np.array([m.joint(n).qposadr[0] for n in _FINGER_JOINTS])
        self._finger_dofadr = np.array([m.joint(n).dofadr[0] for n in _FINGER_JOINTS])
        # The same addresses as views where they are contiguous (they are, in this scene): the settle checks
        # read them after every control tick, and a slice is cheaper than a gather.
        self._arm_dofs, self._finger_dofs = _as_slice(self._dofadr), _as_slice(self._finger_dofadr)
        self._arm_qpos = _as_slice(self._qadr)
        self._arm_act = np.array([m.actuator(n).id for n in robot.JOINT_NAMES])
        self._grip_act = m.actuator("gripper").id
        object_joint = m.joint(robot.CUBE_JOINT)
        self._object_qadr, self._object_dofadr = object_joint.qposadr[0], object_joint.dofadr[0]
        self._object_body = m.body(robot.CUBE_BODY).id
        self._object_geom = m.geom("cube").id
        self._pad_geoms = {m.geom("l_pad").id, m.geom("r_pad").id}
        finger_bodies = {m.body(n).id for n in _FINGER_BODIES}
        self._is_finger_geom = [int(body) in finger_bodies for body in m.geom_bodyid]
        self._ee_site = m.site(robot.EE_SITE).id
        self._target_site = m.site(robot.TARGET_SITE).id
        self._substeps_keyframe = round(CONTROL_DT / m.opt.timestep)
        self._renderers: dict[tuple[int, int, bool], mujoco.Renderer] = {}
        # Optional observer called after every control tick (100 Hz for keyframe moves, once per dense
        # period), e.g. by the viewer to record the motion between keyframes. It must not change the state.
        self.on_control_tick = None
        # Optional disturbance called after every control tick before the observer; unlike the observer it may
        # change the state (the task's perturbations that happen in the middle of a move).
        self.disturb = None
        # Keyframe moves with the object in the grasp last at least this long (s); 0 = the velocity limits alone.
        self.carry_min_time = 0.0
        self._object_half_size = float(m.geom_size[self._object_geom][0])
        self._fresh_state()

    def _fresh_state(self) -> None:
        """Forget the queries cached for the current state. Every method that steps MuJoCo or changes ``data``
        calls it: the task asks for the object's pose and contacts many times per control tick (its
        disturbance triggers, success and phase), and they only change when the state does."""
        self._grasp: tuple[bool, bool] | None = None  # (object in grasp, gripper touches object)
        self._object: tuple[np.ndarray, float] | None = None

    # ------------------------------------------------------------------ named queries
    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    def arm_qpos(self) -> np.ndarray:
        return self.data.qpos[self._arm_qpos].copy()

    def arm_command(self) -> np.ndarray:
        """The arm's current joint setpoints (what the servos are tracking)."""
        return self.data.ctrl[self._arm_act].copy()

    def gripper_command(self) -> float:
        """The gripper's current command, 0 (closed) .. 1 (open), as a keyframe's last entry gives it."""
        return float(self.data.ctrl[self._grip_act] / robot.FINGER_TRAVEL)

    def gripper_opening(self) -> float:
        """Measured opening, 0 (closed) .. 1 (fully open)."""
        qpos = self.data.qpos
        opening = 0.5 * (qpos[self._finger_qadr[0]] - qpos[self._finger_qadr[1]]) / robot.FINGER_TRAVEL
        return float(min(max(opening, 0.0), 1.0))

    def state_vector(self) -> np.ndarray:
        """Noise-free agent state: joints + gripper opening (float32, the ``agent_pos`` layout)."""
        state = np.empty(robot.N_JOINTS + 1, dtype=np.float32)
        state[: robot.N_JOINTS] = self.data.qpos[self._arm_qpos]
        state[robot.N_JOINTS] = self.gripper_opening()
        return state

    def object_pose(self) -> tuple[np.ndarray, float]:
        """Object position and yaw (rad) in the base frame (ground truth)."""
        if self._object is None:
            rot = self.data.xmat[self._object_body]  # row-major 3 x 3
            self._object = (self.data.xpos[self._object_body].copy(), float(math.atan2(rot[3], rot[0])))
        pos, yaw = self._object
        return pos.copy(), yaw

    def object_speed(self) -> float:
        return float(np.linalg.norm(self.data.qvel[self._object_dofadr : self._object_dofadr + 3]))

    def ee_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Gripper site position and rotation matrix."""
        return self.data.site_xpos[self._ee_site].copy(), self.data.site_xmat[self._ee_site].reshape(3, 3).copy()

    def pad_bottom_z(self) -> float:
        return float(self.data.site_xpos[self._ee_site][2] - _PAD_HALF_THICKNESS)

    def place_target(self) -> np.ndarray:
        return self.model.site_pos[self._target_site][:2].copy()

    def _grasp_contacts(self) -> tuple[bool, bool]:
        """(both finger pads touch the object, any finger touches it), from the contacts of the current state.
        Plain Python over the few contacts: it runs after every control tick, where numpy's per-call overhead
        on arrays this small costs more than the loop."""
        if self._grasp is None:
            ncon, g = self.data.ncon, self._object_geom
            touching = (
                [a + b - g for a, b in self.data.contact.geom[:ncon].tolist() if a == g or b == g] if ncon else []
            )
            self._grasp = (
                self._pad_geoms.issubset(touching),
                any(self._is_finger_geom[geom] for geom in touching),
            )
        return self._grasp

    def object_in_grasp(self) -> bool:
        """Both finger pads touch the object."""
        return self._grasp_contacts()[0]

    def gripper_touches_object(self) -> bool:
        return self._grasp_contacts()[1]

    def is_finite(self) -> bool:
        return bool(np.all(np.isfinite(self.data.qpos)))

    # ------------------------------------------------------------------ state
    def set_place_target(self, xy) -> None:
        self.model.site_pos[self._target_site][:2] = xy

    def set_state(
        self,
        arm_q: np.ndarray,
        gripper_opening: float,
        object_pos: np.ndarray,
        object_yaw: float = 0.0,
        hold_command: bool = True,
    ) -> None:
        """Put the arm, gripper and object in a given configuration (at rest) and recompute kinematics.

        With ``hold_command`` the servos' setpoints are set to the same configuration, so the state holds.
        Used by resets and by the viewer's replay of recorded frames.
        """
        d = self.data
        opening = float(gripper_opening) * robot.FINGER_TRAVEL
        d.qpos[self._qadr] = arm_q
        d.qpos[self._finger_qadr] = (opening, -opening)
        d.qpos[self._object_qadr : self._object_qadr + 3] = object_pos
        d.qpos[self._object_qadr + 3 : self._object_qadr + 7] = (
            math.cos(object_yaw / 2),
            0.0,
            0.0,
            math.sin(object_yaw / 2),
        )
        if hold_command:
            d.ctrl[self._arm_act] = arm_q
            d.ctrl[self._grip_act] = opening
        mujoco.mj_forward(self.model, d)
        self._fresh_state()

    def reset(self, arm_q: np.ndarray, object_pos: np.ndarray, object_yaw: float, settle_time: float = 0.1) -> None:
        """Fresh state: the arm at ``arm_q`` with the gripper open, the object at rest; contacts settle."""
        mujoco.mj_resetData(self.model, self.data)
        self.set_state(arm_q, robot.GRIPPER_OPEN, object_pos, object_yaw)
        mujoco.mj_step(self.model, self.data, round(settle_time / self.timestep))
        self._fresh_state()

    def set_object_properties(self, mass: float, friction: float) -> None:
        """Object mass (kg, inertia scaled with it) and sliding friction."""
        body = self._object_body
        scale = mass / self.model.body_mass[body]
        self.model.body_mass[body] = mass
        self.model.body_inertia[body] *= scale
        self.model.geom_friction[self._object_geom][0] = friction
        mujoco.mj_setConst(self.model, self.data)  # derived quantities (constraint scaling) from the new mass
        self._fresh_state()

    @property
    def object_size(self) -> float:
        """Edge length of the cube (m)."""
        return 2 * self._object_half_size

    def object_rest_z(self, size: float | None = None) -> float:
        """Height of the cube's centre when it rests on the table (for the current size, or ``size``)."""
        return robot.TABLE_TOP_Z + (self.object_size if size is None else size) / 2

    def set_object_size(self, size: float) -> None:
        """Cube edge length (m); the mass is kept, the inertia follows the new size."""
        self.model.geom_size[self._object_geom][:] = size / 2
        self.model.geom_rbound[self._object_geom] = np.sqrt(3) * size / 2
        self.model.body_inertia[self._object_body] = self.model.body_mass[self._object_body] * size**2 / 6
        mujoco.mj_setConst(self.model, self.data)
        self._object_half_size = float(self.model.geom_size[self._object_geom][0])
        self._fresh_state()

    def object_properties(self) -> tuple[float, float]:
        return float(self.model.body_mass[self._object_body]), float(self.model.geom_friction[self._object_geom][0])

    def wait(self, seconds: float) -> None:
        """Let the physics run with the current commands (e.g. a knocked object falls and comes to rest)."""
        for _ in range(max(1, round(seconds / CONTROL_DT))):
            self._run(self._substeps_keyframe)

    def displace_object(self, offset: np.ndarray) -> None:
        """Teleport the object by ``offset`` (m, base frame) and stop it."""
        self.data.qpos[self._object_qadr : self._object_qadr + 3] += offset
        self.data.qvel[self._object_dofadr : self._object_dofadr + 6] = 0
        mujoco.mj_forward(self.model, self.data)
        self._fresh_state()

    # ------------------------------------------------------------------ control primitives
    def _run(self, substeps: int) -> None:
        mujoco.mj_step(self.model, self.data, substeps)
        self._fresh_state()
        if self.disturb is not None:
            self.disturb(self)
        if self.on_control_tick is not None:
            self.on_control_tick(self)

    def move_to_keyframe(self, q_target: np.ndarray, grip: float, speed: float) -> None:
        """Interpolate the arm to ``q_target`` (min-jerk, within the joint velocity limits), settle, then grip."""
        d = self.data
        min_time = self.carry_min_time if self.carry_min_time > 0 and self.object_in_grasp() else 0.0
        q0 = d.ctrl[self._arm_act]
        for setpoint in joint_trajectory(q0, q_target, 1.0 / CONTROL_DT, speed, ik=self.path_ik, min_time=min_time):
            d.ctrl[self._arm_act] = setpoint
            self._run(self._substeps_keyframe)
        self._settle(lambda: np.abs(d.qvel[self._arm_dofs]).max() < 0.02, max_time=1.0)
        grip_ctrl = grip * robot.FINGER_TRAVEL
        if abs(grip_ctrl - d.ctrl[self._grip_act]) > 1e-9:
            d.ctrl[self._grip_act] = grip_ctrl
            self._run(round(0.1 / self.timestep))
            self._settle(lambda: np.abs(d.qvel[self._finger_dofs]).max() < 1e-3, max_time=0.8)

    def _settle(self, done, max_time: float) -> None:
        for _ in range(math.ceil(max_time / CONTROL_DT)):
            if done():
                return
            self._run(self._substeps_keyframe)

    def dense_step(self, q_target: np.ndarray, grip: float, fps: int, speed: float) -> None:
        """One control period: joint setpoints rate-limited by the velocity limits, then physics."""
        d = self.data
        max_delta = robot.JOINT_VEL_LIMIT * speed / fps
        q_prev = d.ctrl[self._arm_act]
        d.ctrl[self._arm_act] = q_prev + np.clip(q_target - q_prev, -max_delta, max_delta)
        d.ctrl[self._grip_act] = grip * robot.FINGER_TRAVEL
        self._run(max(1, round(1.0 / (fps * self.timestep))))

    def check_finite(self) -> None:
        if not self.is_finite():
            raise PhysicsError("physics diverged (non-finite state); this is a bug, please report the seed and actions")

    # ------------------------------------------------------------------ rendering
    def render(self, camera: str, height: int, width: int, effects: bool = True) -> np.ndarray:
        """An RGB image (HxWx3 uint8) from a named MJCF camera (headless EGL on Linux by default).

        ``effects``: MuJoCo's default visuals (shadows, reflections, multisampled anti-aliasing). Without them a
        software-rendered frame costs a fraction as much; the env's ``render_effects`` decides, per task.
        """
        key = (height, width, effects)
        if key not in self._renderers:
            # The offscreen framebuffer's size and multisampling are read once, when the renderer's GL context is
            # made: its framebuffer is the image's size (the MJCF's offwidth x offheight would cap the image size)
            visual = self.model.vis
            defaults = (visual.quality.offsamples, visual.global_.offwidth, visual.global_.offheight)
            if not effects:
                visual.quality.offsamples = 0
            visual.global_.offwidth, visual.global_.offheight = width, height
            try:
                self._renderers[key] = mujoco.Renderer(self.model, height=height, width=width)
            finally:
                visual.quality.offsamples, visual.global_.offwidth, visual.global_.offheight = defaults
        renderer = self._renderers[key]
        renderer.update_scene(self.data, camera=camera)
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = effects
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = effects
        return renderer.render().copy()

    def close(self) -> None:
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()
