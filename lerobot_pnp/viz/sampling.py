"""What the viewer records of a run: continuous samples of the simulation and the run's frames.

A keyframe step moves the arm for a second or more, so one row per step would show the arm jumping between
keyframes. ``Sampler`` is installed as ``physics.on_control_tick`` (an observer the physics calls after every
control tick) and keeps a sample every ``1 / hz`` s of simulated time: body poses, joints, gripper, object,
end effector. ``Run`` pairs those samples with the run's frames (dataset frames or policy steps), each frame
pointing at the sample taken when it was observed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.viz.scene import SceneModel

SAMPLE_KEYS = ("t", "xpos", "xquat", "q", "gripper", "object", "ee", "success")


@dataclass
class Frames:
    """Per-frame values of one run (a dataset episode or a policy rollout), as recorded / observed."""

    frame_index: np.ndarray  # (F,)
    sample: np.ndarray  # (F,) index of the sample taken at the frame (its time and body poses)
    state: np.ndarray  # (F, 8) observation.state
    object: np.ndarray  # (F, 3) observation.environment_state (object xyz)
    action: np.ndarray  # (F, 8) (policy rollouts: the prediction at that step; NaN after the last step)
    phase: np.ndarray  # (F,) int FSM phase, -1 when unknown
    success: np.ndarray  # (F,) float 0/1


@dataclass
class Run:
    """One run to log: its entity prefix, the simulation samples, its frames and a summary."""

    name: str  # entity prefix: episode_<N> / rollout_<i>
    scene: SceneModel
    qpos: np.ndarray  # a full qpos of the run (for forward kinematics of keyframes on a scratch MjData)
    samples: dict[str, np.ndarray]
    frames: Frames
    info: dict = field(default_factory=dict)
    is_rollout: bool = False  # a policy rollout (else a dataset episode)
    expert: dict | None = None  # policy rollouts: the FSM expert's reference from the same start
    images: dict[str, list[np.ndarray]] = field(default_factory=dict)  # camera -> one HWC image per frame
    # policy rollouts: camera -> the (K, 2) keypoints (pixel column, row) the policy computed on each frame it acted on
    keypoints: dict[str, list[np.ndarray]] = field(default_factory=dict)
    events: list[tuple[int, str, str]] = field(default_factory=list)  # (frame, level, text): perturbations, failure


def run_events(infos: list[dict]) -> list[tuple[int, str, str]]:
    """Perturbations as they fire and the outcome, from the env's ``info`` of each frame (reset + steps).

    ``info["perturbations"]`` lists what fired so far (``task.PickPlaceTask.step_info``), so a new name at frame
    ``k`` fired during the step that led to it; the last frame carries ``failure_cause`` when the episode ended
    unsolved."""
    events, seen = [], []
    for k, info in enumerate(infos):
        fired = [p for p in str(info.get("perturbations") or "").split(",") if p]
        for name in fired[len(seen) :]:
            events.append((k, "WARN", f"perturbation: {name}"))
        seen = fired
    if infos:
        last = infos[-1]
        if last.get("failure_cause"):
            events.append((len(infos) - 1, "ERROR", f"failure: {last['failure_cause']}"))
        elif last.get("is_success"):
            events.append((len(infos) - 1, "INFO", "success"))
    return events


class Sampler:
    """Samples the simulation at ``hz`` of simulated time (see module doc).

    ``start()`` at the run's first observation, install as ``physics.on_control_tick``, and call ``sample()``
    at frames to take a sample now (for kinematic replays, with the frame's time ``t``).
    """

    def __init__(self, physics, scene: SceneModel, success_fn, hz: float):
        self.physics = physics
        self.scene = scene
        self.success_fn = success_fn
        self.period = 1.0 / hz
        self.rows: dict[str, list] = {k: [] for k in SAMPLE_KEYS}
        self.t0 = 0.0
        self._next = 0.0

    def start(self) -> None:
        self.rows = {k: [] for k in SAMPLE_KEYS}
        self.t0 = float(self.physics.data.time)
        self._next = 0.0

    def __call__(self, physics) -> None:
        if physics.data.time - self.t0 >= self._next - 1e-9:
            self.sample()

    def sample(self, t: float | None = None) -> int:
        """Record the current state (at simulated time ``t``, default the physics clock); returns its index."""
        p, d = self.physics, self.physics.data
        t = float(d.time - self.t0) if t is None else float(t)
        if self.rows["t"] and abs(self.rows["t"][-1] - t) < 1e-9:
            return len(self.rows["t"]) - 1
        dyn = self.scene.dynamic
        self.rows["t"].append(t)
        self.rows["xpos"].append(d.xpos[dyn].copy())
        self.rows["xquat"].append(d.xquat[dyn].copy())
        self.rows["q"].append(p.arm_qpos())
        self.rows["gripper"].append(p.gripper_opening())
        self.rows["object"].append(p.object_pose()[0])
        self.rows["ee"].append(p.ee_pose()[0])
        self.rows["success"].append(float(self.success_fn()))
        self._next = (math.floor(t / self.period + 1e-6) + 1) * self.period
        return len(self.rows["t"]) - 1

    def arrays(self) -> dict[str, np.ndarray]:
        out = {k: np.asarray(v) for k, v in self.rows.items()}
        out["object"] = out["object"].reshape(-1, 3)
        out["ee"] = out["ee"].reshape(-1, 3)
        return out


def phase_name(p: int) -> str:
    """The viewer's label of FSM phase ``p``: its name, or ``phase <p>`` for an index outside ``robot.Phase``."""
    return robot.phase_name(p, unknown=f"phase {int(p)}")
