"""DART (Laskey et al., CoRL 2017, "DART: Noise Injection for Robust Imitation Learning"): the expert
demonstrates with noise injected into the commands it executes, and every visited state is labelled with its
clean command. The noisy execution drives the expert into states its clean demonstrations never visit (a grasp
a few centimetres off, an object dropped by a gripper that opened), and its FSM recovers from them; the
policy learns those recoveries from the clean labels.

Here it is one setting of the DAgger rollouts (``DaggerConfig.dart``): when a rollout step executes the
expert's label (the mixture's ``beta``; ``beta = 1``: every step), the executed action is ``DartNoise.apply``
of it. The noise comes from a generator seeded by the rollout's seed (``rng_for``), separate from the
mixture's draws, so a rollout is deterministic and turning the noise on does not change who acts when.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError

# The noise generator of a rollout is seeded by (rollout seed, this stream id): independent of the mixture's.
_NOISE_STREAM = 1


@dataclass
class DartNoise:
    """The noise added to the expert's executed commands.

    Args:
        sigma: Standard deviation (rad) of independent Gaussian noise on each of the 7 joint targets (clipped
            to the joint limits, as the env clips any action).
        gripper_flip: Probability, per executed expert step, that the gripper command is inverted (open <->
            closed): what makes a grasp miss or an object drop on a task whose demonstrations never do.
    """

    sigma: float = 0.0
    gripper_flip: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma) and self.sigma >= 0.0):
            raise ConfigError(f"dart.sigma must be a finite number >= 0 (rad), got {self.sigma}")
        if not 0.0 <= self.gripper_flip <= 1.0:
            raise ConfigError(f"dart.gripper_flip must be a probability in [0, 1], got {self.gripper_flip}")

    @property
    def active(self) -> bool:
        return self.sigma > 0.0 or self.gripper_flip > 0.0

    def key(self) -> dict:
        """The settings as they enter a rollout stage's key (empty when off: keys of noiseless runs unchanged)."""
        return {"dart": asdict(self)} if self.active else {}

    @staticmethod
    def rng_for(seed: int) -> np.random.Generator:
        return np.random.default_rng([seed, _NOISE_STREAM])

    def apply(self, command: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """``command`` (7 joint targets + gripper) with the noise; the clean command itself when off."""
        out = np.array(command, np.float32)
        if self.sigma > 0.0:
            joints = out[: robot.N_JOINTS] + rng.normal(0.0, self.sigma, robot.N_JOINTS)
            out[: robot.N_JOINTS] = np.clip(joints, robot.JOINT_LOWER, robot.JOINT_UPPER)
        if self.gripper_flip > 0.0 and rng.random() < self.gripper_flip:
            open_ = out[robot.N_JOINTS] > 0.5
            out[robot.N_JOINTS] = robot.GRIPPER_CLOSED if open_ else robot.GRIPPER_OPEN
        return out
