"""Inverse kinematics for a gripper-down pose, with MuJoCo's own site Jacobian (damped least squares).

Works on its own ``MjData`` so solving never disturbs a running simulation. Seeded from the previous
keyframe, with a weak pull toward a comfortable posture in the null space, so consecutive solutions are
continuous (the arm is redundant: 7 joints for a 6-D pose).
"""

from __future__ import annotations

import mujoco
import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import UnreachableError


def gripper_down_rotation(yaw: float) -> np.ndarray:
    """World rotation of the gripper frame pointing straight down (z = -world z), rotated by ``yaw``.

    yaw = 0 is Rethink's overhead pose (180 deg about y): fingers travel along world y.
    """
    c, s = np.cos(yaw), np.sin(yaw)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    ry_pi = np.diag([-1.0, 1.0, -1.0])
    return rz @ ry_pi


class ArmIK:
    """Damped-least-squares IK of the ``left_gripper`` site over the 7 arm joints."""

    def __init__(
        self,
        model: mujoco.MjModel,
        pos_tol: float = 2e-4,
        rot_tol: float = 2e-3,
        max_iters: int = 200,
        damping: float = 1e-3,
    ):
        self.model = model
        self.data = mujoco.MjData(model)
        self.site_id = model.site(robot.EE_SITE).id
        self.qadr = np.array([model.joint(n).qposadr[0] for n in robot.JOINT_NAMES])
        self.dofadr = np.array([model.joint(n).dofadr[0] for n in robot.JOINT_NAMES])
        self.lower = robot.JOINT_LOWER
        self.upper = robot.JOINT_UPPER
        self.pos_tol, self.rot_tol, self.max_iters, self.damping = pos_tol, rot_tol, max_iters, damping
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))
        self._jac = np.zeros((6, robot.N_JOINTS))
        self._err = np.zeros(6)
        self._damp6 = damping * np.eye(6)
        self._eye7 = np.eye(robot.N_JOINTS)
        self.posture = robot.NEUTRAL_Q.copy()

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gripper site position and rotation matrix for arm joints ``q``."""
        self.data.qpos[self.qadr] = q
        mujoco.mj_kinematics(self.model, self.data)
        return self.data.site_xpos[self.site_id].copy(), self.data.site_xmat[self.site_id].reshape(3, 3).copy()

    def _task_error(self, q, pos, target_rot):
        """Set q, return (6-D pose error, 6x7 Jacobian)."""
        self.data.qpos[self.qadr] = q
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        rot = self.data.site_xmat[self.site_id].reshape(3, 3)
        # Rotation error 0.5 * sum_i rot[:, i] x target[:, i], i.e. the vee of the skew part below.
        skew = target_rot @ rot.T - rot @ target_rot.T
        self._err[:3] = pos - self.data.site_xpos[self.site_id]
        self._err[3:] = 0.5 * skew[2, 1], 0.5 * skew[0, 2], 0.5 * skew[1, 0]
        mujoco.mj_jacSite(self.model, self.data, self._jacp, self._jacr, self.site_id)
        self._jac[:3] = self._jacp[:, self.dofadr]
        self._jac[3:] = self._jacr[:, self.dofadr]
        return self._err, self._jac

    def refine(self, q: np.ndarray, pos: np.ndarray, target_rot: np.ndarray, iters: int = 2) -> np.ndarray:
        """A few damped Gauss-Newton steps from ``q`` toward a pose (no null-space pull): for path tracking."""
        q = np.asarray(q, dtype=float).copy()
        for _ in range(iters):
            err, jac = self._task_error(q, pos, target_rot)
            q = np.clip(q + jac.T @ np.linalg.solve(jac @ jac.T + self._damp6, err), self.lower, self.upper)
        return q

    def solve(self, pos: np.ndarray, yaw: float, seed: np.ndarray) -> np.ndarray:
        """Joint angles putting the gripper at ``pos`` pointing down with ``yaw``; raises UnreachableError."""
        pos = np.asarray(pos, dtype=float)
        target_rot = gripper_down_rotation(yaw)
        q = np.clip(np.asarray(seed, dtype=float).copy(), self.lower, self.upper)
        eye6 = np.eye(6)
        for _ in range(self.max_iters):
            err, jac = self._task_error(q, pos, target_rot)
            err_p, err_r = err[:3], err[3:]
            if np.linalg.norm(err_p) < self.pos_tol and np.linalg.norm(err_r) < self.rot_tol:
                return q
            jjt = jac @ jac.T + self.damping * eye6
            dq = jac.T @ np.linalg.solve(jjt, err)
            # Null-space pull toward a comfortable posture keeps solutions continuous and away from limits.
            # (exact projector J^T (J J^T)^-1 J for a full-rank J, so the pull never leaks into the task error)
            null = self._eye7 - jac.T @ np.linalg.solve(jac @ jac.T + 1e-12 * eye6, jac)
            dq += null @ (0.05 * (self.posture - q))
            step = np.max(np.abs(dq))
            if step > 0.3:
                dq *= 0.3 / step
            q = np.clip(q + dq, self.lower, self.upper)
        raise UnreachableError(
            f"IK did not converge for gripper position {np.round(pos, 4).tolist()} (yaw {yaw:.3f} rad): "
            f"residual {np.linalg.norm(err_p) * 1000:.1f} mm / {np.linalg.norm(err_r):.3f} rad "
            "(outside reach or blocked by joint limits)"
        )
