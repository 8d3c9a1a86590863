"""The one source of truth for the robot, the scene and the keyframe layout.

Joint names, limits, the MJCF path and the names of every state/action dimension are defined here
and imported by the env, the expert, the dataset writer and the viewer. The policy never imports
this module (it knows LeRobot features only).
"""

from __future__ import annotations

from enum import IntEnum
from importlib import resources
from pathlib import Path

import numpy as np

# Baxter left arm, in kinematic order (Rethink's names).
JOINT_NAMES: tuple[str, ...] = (
    "left_s0",
    "left_s1",
    "left_e0",
    "left_e1",
    "left_w0",
    "left_w1",
    "left_w2",
)
JOINT_LOWER = np.array([-1.70167993878, -2.147, -3.05417993878, -0.05, -3.059, -1.57079632679, -3.059])
JOINT_UPPER = np.array([1.70167993878, 1.047, 3.05417993878, 2.618, 3.059, 2.094, 3.059])
JOINT_VEL_LIMIT = np.array([1.5, 1.5, 1.5, 1.5, 4.0, 4.0, 4.0])  # rad/s
N_JOINTS = len(JOINT_NAMES)

# Rethink's "neutral" left-arm pose.
NEUTRAL_Q = np.array([0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0])

# Gripper: one normalised dimension. In observations it is the measured opening (0 = closed,
# 1 = fully open); in actions it is the command (0 = close, 1 = open).
GRIPPER_NAME = "gripper"
FINGER_TRAVEL = 0.020833  # m, per finger (URDF slide limit)
JAW_GAP_CLOSED = 0.036  # m, between the paddle pads with the fingers in the wide slot (77.7 mm fully open)
GRIPPER_OPEN = 1.0
GRIPPER_CLOSED = 0.0

STATE_NAMES: tuple[str, ...] = (*JOINT_NAMES, GRIPPER_NAME)
ACTION_NAMES: tuple[str, ...] = STATE_NAMES
OBJECT_NAMES: tuple[str, ...] = ("object_x", "object_y", "object_z")
# Optional parts of the environment state (tasks with a random yaw / a random place target):
# the yaw as (sin 4 yaw, cos 4 yaw), which is the same for the cube's four symmetric faces, and the goal xy.
OBJECT_YAW_NAMES: tuple[str, ...] = ("object_yaw_sin4", "object_yaw_cos4")
GOAL_NAMES: tuple[str, ...] = ("goal_x", "goal_y")
STATE_DIM = len(STATE_NAMES)
ACTION_DIM = len(ACTION_NAMES)
OBJECT_DIM = len(OBJECT_NAMES)

# The paper's two finite-state machines, 5 states each. One keyframe episode = these 10 states.
PICK_PHASES: tuple[str, ...] = ("start", "approach", "grasp", "close", "retract")
PLACE_PHASES: tuple[str, ...] = ("start", "approach", "descend", "open", "retract")
SUBTASKS: tuple[str, ...] = ("pick", "place")
PHASE_NAMES: tuple[str, ...] = tuple(f"pick/{p}" for p in PICK_PHASES) + tuple(f"place/{p}" for p in PLACE_PHASES)
N_PHASES_PER_SUBTASK = 5
N_KEYFRAMES = len(PHASE_NAMES)


class Phase(IntEnum):
    """An FSM state of the expert, the task's inferred phase and the dataset's ``phase.index``.

    An ``IntEnum``, so it serialises as today's plain ints (JSON, ``np.int64`` arrays, f-strings): the
    dataset content does not depend on it being typed.
    """

    PICK_START = 0
    PICK_APPROACH = 1
    PICK_GRASP = 2
    PICK_CLOSE = 3
    PICK_RETRACT = 4
    PLACE_START = 5
    PLACE_APPROACH = 6
    PLACE_DESCEND = 7
    PLACE_OPEN = 8
    PLACE_RETRACT = 9

    @property
    def label(self) -> str:
        """The phase's name in ``PHASE_NAMES`` (``"pick/start"`` ...)."""
        return PHASE_NAMES[self]

    @property
    def subtask(self) -> int:
        """Index into ``SUBTASKS`` (0 pick, 1 place): the dataset's ``phase.subtask``."""
        return self // N_PHASES_PER_SUBTASK


def phase_name(index: int, unknown: str = "unknown") -> str:
    """The name of FSM phase ``index`` (``Phase.label``); ``unknown`` for -1 or any other index outside ``Phase``."""
    index = int(index)
    return Phase(index).label if 0 <= index < len(Phase) else unknown


KEYFRAME_FPS = 1  # nominal frame rate of a keyframe stream (dataset and env): one FSM state per frame

# Scene facts (Baxter base frame = MuJoCo world frame; provenance in docs/baxter.md).
TABLE_TOP_Z = -0.155  # world z 0.775 with the base at 0.93
CUBE_SIZE = 0.05
CUBE_REST_Z = TABLE_TOP_Z + CUBE_SIZE / 2
TASK = "Pick the cube and place it on the target."

# MuJoCo names used by the env, the expert and the viewer.
EE_SITE = "left_gripper"
CUBE_BODY = "cube"
CUBE_JOINT = "cube_free"
TARGET_SITE = "place_target"
SCENE_FILE = "baxter_pnp.xml"


def scene_path() -> Path:
    """Path of the MJCF scene shipped inside the package (``envs/`` in the source tree)."""
    path = Path(str(resources.files("lerobot_pnp.assets") / SCENE_FILE))
    if not path.is_file():
        raise FileNotFoundError(f"MJCF scene not found at {path}; is the package installed correctly?")
    return path
