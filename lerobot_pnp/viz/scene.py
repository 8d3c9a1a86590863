"""The MuJoCo model as Rerun geometry: every geom of the scene, under its body's entity, coloured by part.

The viewer draws the robot from the same MJCF the simulator steps (no separate mesh set to keep in sync):
each geom's primitive (box, cylinder, capsule, sphere, ellipsoid, plane) is logged once, static, in its body's
frame; a body that moves gets its world pose (the simulator's forward kinematics) per sample, so the arm
moves exactly as simulated. In the MJCF every arm link has the same red; here the links are coloured by
part (shoulder, elbow, forearm, wrist, gripper, fingers) so the arm's structure reads at a glance.
"""

from __future__ import annotations

import logging

import mujoco
import numpy as np

from lerobot_pnp import robot

logger = logging.getLogger(__name__)

# Arm parts in kinematic order: (body name prefix after "left_", colour). Baxter's red for the big links,
# shading toward amber along the chain; the gripper dark, the fingers light, so the jaw is visible.
PART_COLORS: dict[str, tuple[int, int, int]] = {
    "upper_shoulder": (150, 22, 28),
    "lower_shoulder": (196, 36, 40),
    "upper_elbow": (214, 64, 44),
    "lower_elbow": (226, 96, 50),
    "upper_forearm": (232, 128, 56),
    "lower_forearm": (238, 156, 64),
    "wrist": (244, 186, 72),
    "hand": (70, 74, 82),
    "gripper_base": (70, 74, 82),
    "finger": (176, 184, 196),
    "finger_tip": (40, 42, 48),
}
BODY_PART_COLORS = {
    **{f"left_{part}": color for part, color in PART_COLORS.items() if "finger" not in part},
    "l_finger": PART_COLORS["finger"],
    "r_finger": PART_COLORS["finger"],
    "l_finger_tip": PART_COLORS["finger_tip"],
    "r_finger_tip": PART_COLORS["finger_tip"],
}
OBJECT_COLOR = (46, 160, 67)  # the cube: green, distinct from the arm's warm colours and the cyan target
TARGET_COLOR = (40, 200, 220)
FLOOR_COLOR = (52, 60, 70)
FLOOR_HALF_SIZE = 1.2  # m: the MJCF floor is 6 m wide; a smaller one keeps the 3D view's bounds on the scene


def quat_xyzw(q_wxyz: np.ndarray) -> np.ndarray:
    """MuJoCo quaternions are (w, x, y, z); Rerun's are (x, y, z, w)."""
    return np.asarray(q_wxyz, dtype=np.float64)[..., [1, 2, 3, 0]]


def rgb_u8(rgba: np.ndarray) -> tuple[int, ...]:
    return tuple(round(float(c) * 255) for c in np.clip(rgba, 0, 1))


class SceneModel:
    """Maps the MuJoCo model's bodies to entity paths and logs its geometry (paths: see ``lerobot_pnp.viz``)."""

    def __init__(self, model: mujoco.MjModel):
        self.model = m = model
        torso = m.body("torso").id
        self.object_body = m.body(robot.CUBE_BODY).id
        self.ee_site = m.site(robot.EE_SITE).id
        self.target_site = m.site(robot.TARGET_SITE).id
        self.entity: dict[int, str] = {}
        for b in range(m.nbody):
            name = m.body(b).name or f"body_{b}"
            if self._in_subtree(b, torso):
                self.entity[b] = f"world/robot/{name}"
            elif b == self.object_body:
                self.entity[b] = "world/cube"
            else:
                self.entity[b] = f"world/scene/{name}"
        # Bodies that move (not welded to the world) get a pose per sample; the rest one static pose.
        self.dynamic = [b for b in range(1, m.nbody) if m.body_weldid[b] != 0]
        self.static = [b for b in range(1, m.nbody) if m.body_weldid[b] == 0]
        self._qadr = [m.joint(n).qposadr[0] for n in robot.JOINT_NAMES]  # for FK on a scratch MjData only

    def _in_subtree(self, b: int, root: int) -> bool:
        while b > 0:
            if b == root:
                return True
            b = int(self.model.body_parentid[b])
        return False

    def geom_color(self, g: int) -> tuple[int, ...]:
        m = self.model
        body = m.body(int(m.geom_bodyid[g])).name
        if body in BODY_PART_COLORS:
            return BODY_PART_COLORS[body]
        if int(m.geom_bodyid[g]) == self.object_body:
            return OBJECT_COLOR
        mat = m.geom_matid[g]
        return rgb_u8(m.mat_rgba[mat] if mat >= 0 else m.geom_rgba[g])[:3]

    def geom_archetype(self, g: int):
        """The Rerun archetype drawing geom ``g`` in its own frame (None for types not drawn)."""
        import rerun as rr

        m = self.model
        size, kind = m.geom_size[g], m.geom_type[g]
        color, solid = [self.geom_color(g)], rr.components.FillMode.Solid
        if kind == mujoco.mjtGeom.mjGEOM_BOX:
            return rr.Boxes3D(half_sizes=[size], colors=color, fill_mode=solid)
        if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
            return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], colors=color, fill_mode=solid)
        if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            return rr.Capsules3D(
                lengths=[2 * size[1]], radii=[size[0]], translations=[[0, 0, -size[1]]], colors=color, fill_mode=solid
            )
        if kind in (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_ELLIPSOID):
            half = [size[0]] * 3 if kind == mujoco.mjtGeom.mjGEOM_SPHERE else size
            return rr.Ellipsoids3D(half_sizes=[half], colors=color, fill_mode=solid)
        if kind == mujoco.mjtGeom.mjGEOM_PLANE:
            half = min(FLOOR_HALF_SIZE, size[0]), min(FLOOR_HALF_SIZE, size[1]), 1e-4
            return rr.Boxes3D(half_sizes=[half], colors=[FLOOR_COLOR], fill_mode=solid)
        logger.warning("viz: geom %s of type %s is not drawn", m.geom(g).name, mujoco.mjtGeom(kind).name)
        return None

    def log_static(self, rec, run: str, data: mujoco.MjData) -> None:
        """Geometry (static, in body frames), the static bodies' poses, the place target, view coordinates."""
        import rerun as rr

        m = self.model
        rec.log(f"{run}/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for b in self.static:
            pose = rr.Transform3D(translation=data.xpos[b], quaternion=quat_xyzw(data.xquat[b]))
            rec.log(f"{run}/{self.entity[b]}", pose, static=True)
        for g in range(m.ngeom):
            arch = self.geom_archetype(g)
            if arch is None:
                continue
            b = int(m.geom_bodyid[g])
            name = m.geom(g).name or f"geom_{g}"
            path = f"{run}/world/scene/{name}" if b == 0 else f"{run}/{self.entity[b]}/{name}"
            local = rr.Transform3D(translation=m.geom_pos[g], quaternion=quat_xyzw(m.geom_quat[g]))
            rec.log(path, local, static=True)
            rec.log(path, arch, static=True)
        s = self.target_site
        rec.log(
            f"{run}/world/target",
            rr.Cylinders3D(
                lengths=[max(2 * m.site_size[s][1], 2e-3)],
                radii=[m.site_size[s][0]],
                centers=[data.site_xpos[s]],
                colors=[TARGET_COLOR],
                fill_mode=rr.components.FillMode.Solid,
                labels=["place target"],
                show_labels=False,
            ),
            static=True,
        )

    def ee_position(self, qpos: np.ndarray, q: np.ndarray, scratch: mujoco.MjData) -> np.ndarray:
        """Forward kinematics of the end-effector site for arm joints ``q`` (the rest of ``qpos`` as given).

        Works on ``scratch`` (a private MjData of this model), never on the simulation's data.
        """
        scratch.qpos[:] = qpos
        scratch.qpos[self._qadr] = q[: robot.N_JOINTS]
        mujoco.mj_kinematics(self.model, scratch)
        return scratch.site_xpos[self.ee_site].copy()
