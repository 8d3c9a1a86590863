"""The joint-space interpolator shared by the env's keyframe mode and dense demonstrations.

A min-jerk (quintic) profile from one joint keyframe to the next whose duration keeps every joint within
Baxter's velocity limits (scaled by ``speed``). Plain joint-space interpolation bows the gripper's path
sideways by 3-8 mm on a 15 cm descent, a large part of the 13.9 mm of clearance the open gripper has on
each side of a 5 cm cube (and the gripper's path is what a user sees and what a demonstration teaches),
so by default the path is straightened: at a few knots the joint path is corrected (two
Jacobian steps) onto the straight line between the two keyframes' gripper poses, and the correction is
interpolated between knots. Both ends stay exactly the keyframes.
"""

from __future__ import annotations

import math

import numpy as np

from lerobot_pnp import robot

MIN_MOVE_TIME = 0.2  # s
PATH_KINDS = ("straight", "joint")
_KNOTS = 8
_KNOT_S = np.linspace(0.0, 1.0, _KNOTS)


def min_jerk(s):
    """Quintic time scaling: zero velocity and acceleration at both ends (s in [0, 1])."""
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def move_duration(q0: np.ndarray, q1: np.ndarray, speed: float = 1.0, min_time: float = 0.0) -> float:
    """Shortest min-jerk duration within the velocity limits (peak velocity is 1.875 * delta / T), and at least
    ``min_time`` (a gentle carry: a short move at the velocity limit accelerates hard enough to shake a cube loose)."""
    delta = np.abs(np.asarray(q1) - np.asarray(q0))
    return max(MIN_MOVE_TIME, min_time, float(np.max(1.875 * delta / (robot.JOINT_VEL_LIMIT * speed))))


def joint_trajectory(q0, q1, rate_hz: float, speed: float = 1.0, ik=None, min_time: float = 0.0) -> np.ndarray:
    """Setpoints at ``rate_hz`` from ``q0`` (excluded) to ``q1`` (included), shape (n, 7); (0, 7) for a hold.

    With ``ik`` (an ``ArmIK``), the gripper follows a straight line between the two keyframes' poses.
    """
    q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    if np.array_equal(q0, q1):  # a hold (e.g. while the gripper acts): nothing to interpolate
        return np.empty((0, q0.size))
    n = math.ceil(move_duration(q0, q1, speed, min_time) * rate_hz)
    max_step = robot.JOINT_VEL_LIMIT * speed / rate_hz
    knot_offsets = None
    for _ in range(3):
        s = min_jerk(np.arange(1, n + 1) / n)
        path = q0 + s[:, None] * (q1 - q0)
        if ik is not None and np.max(np.abs(q1 - q0)) > 1e-6:
            if knot_offsets is None:
                knot_offsets = _straightening(q0, q1, ik)
            path += np.stack([np.interp(s, _KNOT_S, knot_offsets[:, j]) for j in range(7)], axis=1)
        # The straightening correction adds a little speed: stretch the move if a limit would be exceeded.
        ratio = float(np.max(np.abs(np.diff(np.vstack([q0, path]), axis=0)) / max_step))
        if ratio <= 1.0:
            break
        n = math.ceil(n * ratio) + 1
    return path


def _straightening(q0: np.ndarray, q1: np.ndarray, ik) -> np.ndarray:
    """Joint offsets at the knots (``_KNOT_S``) that put the path on the straight Cartesian segment."""
    p0, r0 = ik.forward(q0)
    p1, r1 = ik.forward(q1)
    slerp = _Slerp(r0, r1)
    offsets = np.zeros((_KNOTS, 7))
    for k in range(1, _KNOTS - 1):
        u = _KNOT_S[k]
        q = q0 + u * (q1 - q0) + offsets[k - 1]
        q = ik.refine(q, p0 + u * (p1 - p0), slerp(u), iters=2)
        offsets[k] = q - (q0 + u * (q1 - q0))
    return offsets


class _Slerp:
    """Rotations a fraction ``u`` of the way from r0 to r1 (about the relative rotation's fixed axis)."""

    def __init__(self, r0: np.ndarray, r1: np.ndarray):
        self.r0 = r0
        rel = r0.T @ r1
        self.angle = math.acos(np.clip((np.trace(rel) - 1) / 2, -1.0, 1.0))
        if self.angle < 1e-9:
            self.k = None
            return
        axis = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]]) / (
            2 * math.sin(self.angle)
        )
        self.k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        self.k2 = self.k @ self.k

    def __call__(self, u: float) -> np.ndarray:
        if self.k is None:
            return self.r0
        a = u * self.angle
        return self.r0 @ (np.eye(3) + math.sin(a) * self.k + (1 - math.cos(a)) * self.k2)
