"""Task logic, separate from the physics wrapper: the reset distribution, perturbations and success.

Everything here is plain numbers and numpy; the env applies it to the MuJoCo state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError


@dataclass
class TaskConfig:
    """Where the cube and the arm start, where the cube goes, and what counts as success.

    Positions are in Baxter's base frame (metres). The default cube box is fully reachable with the
    gripper pointing down (grasp and hover); the place target lies outside it so no episode starts solved.
    """

    object_low: tuple[float, float] = (0.45, 0.10)
    object_high: tuple[float, float] = (0.75, 0.50)
    # Cube yaw range (rad). The paper varies position only, and the policy observes xyz only, so 0 by default.
    yaw_range: tuple[float, float] = (0.0, 0.0)
    place_xy: tuple[float, float] = (0.60, -0.05)
    # Random start: the gripper (pointing down) at a random point of this box above the table.
    start_low: tuple[float, float, float] = (0.45, 0.0, 0.05)
    start_high: tuple[float, float, float] = (0.75, 0.45, 0.25)
    hover_height: float = 0.15  # the paper's h: approach/retract height above the object
    success_xy_tol: float = 0.02
    # Perturbations (the paper's feedback claims): nudge the cube after `nudge_at_step` env steps by up to
    # `nudge_max` metres in xy; Gaussian observation noise on the object position and the joints.
    nudge_max: float = 0.0
    nudge_at_step: int = 1
    obs_noise_object: float = 0.0
    obs_noise_joints: float = 0.0

    def __post_init__(self):
        for name in ("object_low", "object_high", "yaw_range", "place_xy", "start_low", "start_high"):
            value = tuple(float(v) for v in getattr(self, name))
            if not np.all(np.isfinite(value)):
                raise ConfigError(f"TaskConfig.{name} must be finite, got {value}")
            setattr(self, name, value)
        for low, high in (("object_low", "object_high"), ("start_low", "start_high"), ("yaw_range", "yaw_range")):
            lo, hi = np.array(getattr(self, low)), np.array(getattr(self, high))
            if low == "yaw_range":
                lo, hi = lo[:1], lo[1:]
            if np.any(lo > hi):
                raise ConfigError(f"TaskConfig.{low} must be <= {high} elementwise, got {lo.tolist()} > {hi.tolist()}")
        if not self.hover_height > 0:
            raise ConfigError(f"TaskConfig.hover_height must be > 0 (metres above the object), got {self.hover_height}")
        if not self.success_xy_tol > 0:
            raise ConfigError(f"TaskConfig.success_xy_tol must be > 0, got {self.success_xy_tol}")
        for name in ("nudge_max", "obs_noise_object", "obs_noise_joints"):
            if not getattr(self, name) >= 0:
                raise ConfigError(f"TaskConfig.{name} must be >= 0, got {getattr(self, name)}")
        if self.nudge_at_step < 0:
            raise ConfigError(f"TaskConfig.nudge_at_step must be >= 0, got {self.nudge_at_step}")
        if self.start_low[2] < robot.TABLE_TOP_Z + 0.05:
            raise ConfigError(
                f"TaskConfig.start_low z={self.start_low[2]} puts the gripper within 5 cm of the table "
                f"(table top at z={robot.TABLE_TOP_Z})"
            )

    # The reachability check needs IK, which needs the model: the env calls this with its solver.
    def check_reachable(self, ik) -> None:
        """Raise ConfigError if any corner of the object box (grasp and hover) or the place target is unreachable."""
        from lerobot_pnp.errors import UnreachableError

        yaws = sorted(set(self.yaw_range))
        points = [(x, y) for x in (self.object_low[0], self.object_high[0]) for y in (self.object_low[1], self.object_high[1])]
        checks = [("object box corner", p, yaw) for p in points for yaw in yaws] + [("place target", self.place_xy, 0.0)]
        for what, (x, y), yaw in checks:
            seed = robot.NEUTRAL_Q
            try:
                for z in (robot.CUBE_REST_Z + self.hover_height, robot.CUBE_REST_Z):
                    seed = ik.solve(np.array([x, y, z]), yaw, seed)
            except UnreachableError as err:
                raise ConfigError(
                    f"{what} ({x:.3f}, {y:.3f}) with hover {self.hover_height} m is out of the arm's reach: {err}"
                ) from None

    def sample_object(self, rng: np.random.Generator) -> tuple[np.ndarray, float]:
        xy = rng.uniform(self.object_low, self.object_high)
        yaw = float(rng.uniform(*self.yaw_range)) if self.yaw_range[1] > self.yaw_range[0] else self.yaw_range[0]
        return np.array([xy[0], xy[1], robot.CUBE_REST_Z]), yaw

    def sample_start(self, rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(self.start_low, self.start_high)

    def sample_nudge(self, rng: np.random.Generator) -> np.ndarray:
        """A uniformly random xy offset of length <= nudge_max."""
        angle = rng.uniform(0, 2 * np.pi)
        radius = self.nudge_max * np.sqrt(rng.uniform())
        return np.array([radius * np.cos(angle), radius * np.sin(angle), 0.0])

    # Success = cube_placed and gripper_released (split so the env can skip the contact query when not placed).
    def cube_placed(self, cube_pos: np.ndarray, cube_speed: float) -> bool:
        """Cube resting on the table within tolerance of the target."""
        on_target = np.linalg.norm(cube_pos[:2] - np.asarray(self.place_xy)) <= self.success_xy_tol
        return bool(on_target and abs(cube_pos[2] - robot.CUBE_REST_Z) < 0.005 and cube_speed < 0.02)

    @staticmethod
    def gripper_released(cube_pos: np.ndarray, touching: bool, gripper_open: float, pad_bottom_z: float) -> bool:
        """Fingers off the cube, gripper open, and the pads clear above the cube's top."""
        cube_top = cube_pos[2] + robot.CUBE_SIZE / 2
        return bool(not touching and gripper_open > 0.5 and pad_bottom_z > cube_top + 0.01)
