"""Rerun viewer for dataset episodes and policy rollouts (``lerobot-pnp viz``).

What it shows
-------------
Every dataset episode is *re-simulated*: the env is reset with the episode's ``episode.seed`` and the stored
actions are replayed through the env's interpolator, observed after every control tick
(``env.on_control_tick``) and logged at ``log_hz``, so the motion between keyframes is continuous. A dataset
without ``episode.seed`` is posed kinematically from its stored states instead (one pose per frame).
A policy checkpoint (``policy_path``) is run closed loop in the env, seeded like ``lerobot-eval``; the FSM
expert is run from the same seed (same start state and object position) and its keyframes are logged beside
the policy's, with the per-joint and end-effector position errors.

The robot is drawn from the MuJoCo model itself: each geom's primitive (box, cylinder, capsule, sphere,
plane) is logged once, static, under its body's entity, and the body's world pose (the simulator's forward
kinematics) is logged per sample as a ``Transform3D``.

Timelines
---------
``frame_index`` (sequence): the dataset frame / policy step (for keyframe data: the FSM state reached).
``time`` (duration, s): simulated time since ``env.reset``; continuous samples and frames both carry it.
Rows logged at a dataset frame carry both timelines (their values are the dataset's own: at frame ``k``,
``plots/joints/<j>`` equals ``observation.state[k]``); continuous samples carry ``time`` only.
For dense datasets ``time`` of frame ``k`` is ``k / fps`` (the dataset's ``timestamp``); for keyframe datasets
(nominal 1 fps) it is when the FSM state was actually reached.

Entity paths (stable; ``<run>`` is ``episode_<N>`` for dataset episode N, ``rollout_<i>`` for policy rollout i)
-----------------------------------------------------------------------------------------------------
``<run>/world``                              view coordinates (right-handed, Z up; Baxter base frame)
``<run>/world/robot/<body>``                 Transform3D: world pose of a robot body (per sample)
``<run>/world/robot/<body>/<geom>``          static primitive in the body frame (fingers: gripper opening)
``<run>/world/cube``, ``.../cube/<geom>``    the object (pose per sample)
``<run>/world/scene/<body>/<geom>``          static scene: floor, table
``<run>/world/target``                       the place target (static disc)
``<run>/world/ee``                           Points3D: end-effector position (per sample)
``<run>/world/ee_path``                      LineStrips3D: the whole end-effector path (static)
``<run>/world/keyframes``                    Points3D labelled pick/start ... place/retract (static)
``<run>/plots/joints/<joint>``               Scalars: the 7 joint angles (rad)
``<run>/plots/gripper``                      Scalars: measured gripper opening (0 closed .. 1 open)
``<run>/plots/action/<name>``                Scalars at frames: the commanded keyframe (7 joints + gripper)
``<run>/plots/object/{x,y,z}``               Scalars: object position (m)
``<run>/plots/phase``                        TextLog at frames: FSM state name; ``plots/phase_index`` Scalars
``<run>/plots/success``                      Scalars 0/1
Policy rollouts add:
``<run>/world/expert_keyframes``             Points3D: the FSM expert's keyframes (end-effector positions)
``<run>/world/expert_ee_path``               LineStrips3D: the expert's end-effector path from the same start
``<run>/policy/pred/<name>``, ``<run>/policy/expert/<name>``   Scalars at frames: predicted vs expert keyframe
``<run>/policy/error/joints/<joint>``        Scalars at frames: |predicted - expert| (rad)
``<run>/policy/error/gripper``, ``<run>/policy/error/ee_pos``  gripper command error; EE position error (m)
``<run>/world/keyframes`` of a rollout are the *predicted* keyframes (forward kinematics of each action).
"""

from __future__ import annotations

import json
import logging
import math
import os
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.env_config import DENSE_FPS
from lerobot_pnp.errors import ConfigError, PnPError

logger = logging.getLogger(__name__)

APPLICATION_ID = "lerobot_pnp"
from lerobot.utils.constants import ACTION, OBS_STATE  # noqa: E402
from lerobot.utils.constants import OBS_ENV_STATE as OBS_ENV  # noqa: E402

PHASE_INDEX, EPISODE_SEED, SUCCESS = "phase.index", "episode.seed", "next.success"
# Where the env settings of a dataset are looked for (``lerobot-pnp generate`` writes the first one).
ENV_CONFIG_FILES = ("meta/pnp_generate.json", "meta/env_config.json")
PICK_COLOR, PLACE_COLOR, EXPERT_COLOR = (230, 160, 30), (40, 200, 220), (120, 220, 120)
FLOOR_COLOR = (64, 77, 90, 255)


# ---------------------------------------------------------------------------------------------- errors
class VizError(ConfigError):
    """Bad input to the viewer (base class of the errors below)."""


class DatasetNotFoundError(VizError):
    """No dataset at the given repo id / root."""


class EpisodeNotFoundError(VizError):
    """The dataset has no episode with the requested index."""


class IncompatibleDatasetError(VizError):
    """The dataset lacks the features this viewer needs (observation.state (8,), action (8,), ...)."""


# ---------------------------------------------------------------------------------------------- config
@dataclass
class PolicyRef:
    """``--policy.path`` (LeRobot's spelling) is accepted as well as ``--policy_path``."""

    path: str | None = None


@dataclass
class VizConfig:
    """``lerobot-pnp viz``: inspect dataset episodes and/or policy rollouts in Rerun.

    Without ``save`` a Rerun viewer is spawned (needs a display); with ``save`` a ``.rrd`` file is written
    headless (open it later with ``rerun out.rrd``).
    """

    repo_id: str | None = None  # dataset to show (local ``root`` first, then the Hub cache)
    root: str | None = None  # dataset folder
    episode_index: int | list[int] = 0  # one index or a list, e.g. --episode_index "[0, 3]"
    save: str | None = None  # write the recording to this .rrd file instead of spawning a viewer
    policy_path: str | None = None  # a LeRobot checkpoint (pretrained_model folder) to run in the env
    policy: PolicyRef = field(default_factory=PolicyRef)
    n_rollouts: int = 1  # policy rollouts, seeds seed .. seed + n_rollouts - 1
    seed: int = 0
    control_mode: str = "keyframe"  # env mode for policy rollouts
    compare_expert: bool = True  # run the FSM expert from each rollout's start state and log the errors
    log_hz: float = 25.0  # rate of the continuous samples (simulated time)
    device: str = "cpu"

    def __post_init__(self) -> None:
        if isinstance(self.policy, dict):
            self.policy = PolicyRef(**self.policy)
        if self.policy.path and self.policy_path and self.policy.path != self.policy_path:
            raise ConfigError(f"policy_path={self.policy_path!r} and policy.path={self.policy.path!r} disagree")
        self.policy_path = self.policy_path or self.policy.path
        self.policy.path = self.policy_path
        self.episode_index = _episode_list(self.episode_index)
        if self.n_rollouts < 1:
            raise ConfigError(f"n_rollouts must be >= 1, got {self.n_rollouts}")
        if not 1 <= self.log_hz <= 500:
            raise ConfigError(f"log_hz must be in [1, 500], got {self.log_hz}")
        if self.control_mode not in ("keyframe", "dense"):
            raise ConfigError(f"control_mode must be 'keyframe' or 'dense', got {self.control_mode!r}")
        if self.save is not None and not str(self.save).endswith(".rrd"):
            raise ConfigError(f"save must be a path ending in .rrd, got {self.save!r}")


def _episode_list(value: Any) -> list[int]:
    if isinstance(value, str):
        text = value.strip().strip("[]")
        parts = [p for p in text.replace(",", " ").split() if p]
        try:
            value = [int(p) for p in parts]
        except ValueError as err:
            raise ConfigError(f"episode_index must be integers, got {value!r}") from err
    if isinstance(value, int | np.integer):
        value = [int(value)]
    value = [int(v) for v in value]
    if not value:
        raise ConfigError("episode_index is empty")
    if any(v < 0 for v in value):
        raise ConfigError(f"episode_index must be >= 0, got {value}")
    return value


# ---------------------------------------------------------------------------------------------- scene
def _quat_xyzw(q_wxyz: np.ndarray) -> np.ndarray:
    q = np.asarray(q_wxyz, dtype=np.float64)
    return q[..., [1, 2, 3, 0]]


def _rgba_u8(rgba: np.ndarray) -> list[int]:
    return [int(round(float(c) * 255)) for c in np.clip(rgba, 0, 1)]


class SceneModel:
    """Maps the MuJoCo model to entity paths and logs its geometry (see the module docstring)."""

    def __init__(self, model: mujoco.MjModel):
        self.model = model
        m = model
        torso = m.body("torso").id
        self.cube = m.body(robot.CUBE_BODY).id
        self.ee_site = m.site(robot.EE_SITE).id
        self.target_site = m.site(robot.TARGET_SITE).id
        self.entity: dict[int, str] = {}
        for b in range(m.nbody):
            name = m.body(b).name or f"body_{b}"
            if self._in_subtree(b, torso):
                self.entity[b] = f"world/robot/{name}"
            elif b == self.cube:
                self.entity[b] = "world/cube"
            else:
                self.entity[b] = f"world/scene/{name}"
        # Bodies that move (not welded to the world) get a pose per sample; the rest one static pose.
        self.dynamic = [b for b in range(1, m.nbody) if m.body_weldid[b] != 0]
        self.static = [b for b in range(m.nbody) if b not in self.dynamic]

    def _in_subtree(self, b: int, root: int) -> bool:
        while b > 0:
            if b == root:
                return True
            b = int(self.model.body_parentid[b])
        return False

    def geom_archetype(self, g: int):
        import rerun as rr

        m = self.model
        size = m.geom_size[g]
        mat = m.geom_matid[g]
        rgba = m.mat_rgba[mat] if mat >= 0 else m.geom_rgba[g]
        color = _rgba_u8(rgba)
        kind = m.geom_type[g]
        solid = rr.components.FillMode.Solid
        if kind == mujoco.mjtGeom.mjGEOM_BOX:
            return rr.Boxes3D(half_sizes=[size], colors=[color], fill_mode=solid)
        if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
            return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], colors=[color], fill_mode=solid)
        if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            return rr.Capsules3D(
                lengths=[2 * size[1]],
                radii=[size[0]],
                translations=[[0, 0, -size[1]]],
                colors=[color],
                fill_mode=solid,
            )
        if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=[color], fill_mode=solid)
        if kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
            return rr.Ellipsoids3D(half_sizes=[size], colors=[color], fill_mode=solid)
        if kind == mujoco.mjtGeom.mjGEOM_PLANE:
            textured = mat >= 0 and m.mat_texid[mat].max() >= 0
            return rr.Boxes3D(
                half_sizes=[[size[0], size[1], 1e-4]], colors=[FLOOR_COLOR if textured else color], fill_mode=solid
            )
        logger.warning("viz: geom %s of type %s is not drawn", m.geom(g).name, mujoco.mjtGeom(kind).name)
        return None

    def log_static(self, rec, run: str, data: mujoco.MjData) -> None:
        """Geometry (static, in body frames), static body poses, the target and view coordinates."""
        import rerun as rr

        m = self.model
        rec.log(f"{run}/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for b in self.static:
            if b == 0:
                continue  # the world body is the world frame itself
            rec.log(
                f"{run}/{self.entity[b]}",
                rr.Transform3D(translation=data.xpos[b], quaternion=_quat_xyzw(data.xquat[b])),
                static=True,
            )
        for g in range(m.ngeom):
            arch = self.geom_archetype(g)
            if arch is None:
                continue
            b = int(m.geom_bodyid[g])
            name = m.geom(g).name or f"geom_{g}"
            path = f"{run}/{self.entity[b]}/{name}"
            if b == 0:
                path = f"{run}/world/scene/{name}"
            rec.log(path, rr.Transform3D(translation=m.geom_pos[g], quaternion=_quat_xyzw(m.geom_quat[g])), static=True)
            rec.log(path, arch, static=True)
        s = self.target_site
        mat = m.site_matid[s]
        rgba = m.mat_rgba[mat] if mat >= 0 else m.site_rgba[s]
        rec.log(
            f"{run}/world/target",
            rr.Cylinders3D(
                lengths=[max(2 * m.site_size[s][1], 1e-3)],
                radii=[m.site_size[s][0]],
                centers=[data.site_xpos[s]],
                colors=[_rgba_u8(rgba)],
                fill_mode=rr.components.FillMode.Solid,
                labels=["place target"],
            ),
            static=True,
        )

    def ee_position(self, data: mujoco.MjData, q: np.ndarray, scratch: mujoco.MjData | None = None) -> np.ndarray:
        """Forward kinematics of the end-effector site for arm joints ``q`` (on a scratch copy)."""
        scratch = scratch or mujoco.MjData(self.model)
        scratch.qpos[:] = data.qpos
        qadr = [self.model.joint(n).qposadr[0] for n in robot.JOINT_NAMES]
        scratch.qpos[qadr] = q[: robot.N_JOINTS]
        mujoco.mj_kinematics(self.model, scratch)
        return scratch.site_xpos[self.ee_site].copy()


# ---------------------------------------------------------------------------------------------- sampling
class Sampler:
    """Samples the simulation state (body poses, joints, gripper, object, EE) at ``hz`` of simulated time.

    Install as ``env.unwrapped.on_control_tick``; ``sample(force=True)`` takes a sample now (at frames).
    """

    def __init__(self, env, scene: SceneModel, hz: float):
        self.env = env
        self.scene = scene
        self.period = 1.0 / hz
        self.rows: dict[str, list] = {}
        self.t0 = 0.0
        self._next = 0.0

    def start(self) -> None:
        self.rows = {k: [] for k in ("t", "xpos", "xquat", "q", "gripper", "cube", "ee", "success")}
        self.t0 = float(self.env.data.time)
        self._next = 0.0

    def __call__(self, env) -> None:
        if env.data.time - self.t0 >= self._next - 1e-9:
            self.sample()

    def sample(self, force: bool = False) -> int:
        env, d = self.env, self.env.data
        t = float(d.time - self.t0)
        if self.rows["t"] and abs(self.rows["t"][-1] - t) < 1e-9:
            return len(self.rows["t"]) - 1
        dyn = self.scene.dynamic
        self.rows["t"].append(t)
        self.rows["xpos"].append(d.xpos[dyn].copy())
        self.rows["xquat"].append(d.xquat[dyn].copy())
        self.rows["q"].append(env.arm_qpos())
        self.rows["gripper"].append(env.gripper_opening())
        self.rows["cube"].append(env.object_pose()[0])
        self.rows["ee"].append(env.ee_pose()[0])
        self.rows["success"].append(float(env.is_success()))
        self._next = (math.floor(t / self.period + 1e-6) + 1) * self.period
        return len(self.rows["t"]) - 1

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v) for k, v in self.rows.items()}


# ---------------------------------------------------------------------------------------------- logging
@dataclass
class FrameTable:
    """Per-frame values of one run (dataset episode or policy rollout)."""

    frame_index: np.ndarray  # (F,)
    sample: np.ndarray  # (F,) index of the sample taken at the frame (for its time and poses)
    state: np.ndarray  # (F, 8) as recorded
    env_state: np.ndarray  # (F, 3)
    action: np.ndarray  # (F, 8) (policy: the prediction at that step; NaN after the last step)
    phase: np.ndarray  # (F,) int, -1 when unknown
    success: np.ndarray  # (F,) float


def _send_scalars(rec, path: str, indexes, values: np.ndarray) -> None:
    import rerun as rr

    rec.send_columns(path, indexes=indexes, columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)))


def _indexes(times: np.ndarray, frames: np.ndarray | None = None):
    import rerun as rr

    idx = [rr.TimeColumn("time", duration=np.asarray(times, dtype=np.float64))]
    if frames is not None:
        idx.insert(0, rr.TimeColumn("frame_index", sequence=np.asarray(frames, dtype=np.int64)))
    return idx


def log_run(rec, run: str, scene: SceneModel, samples: dict[str, np.ndarray], frames: FrameTable) -> None:
    """Log one run's continuous samples (``time``) and its frames (``frame_index`` + ``time``)."""
    import rerun as rr

    t = samples["t"]
    ft = t[frames.sample]
    tick_idx, frame_idx = _indexes(t), _indexes(ft, frames.frame_index)
    # 3D: body poses.
    for j, b in enumerate(scene.dynamic):
        path = f"{run}/{scene.entity[b]}"
        for idx, rows in ((tick_idx, slice(None)), (frame_idx, frames.sample)):
            rec.send_columns(
                path,
                indexes=idx,
                columns=rr.Transform3D.columns(
                    translation=samples["xpos"][rows, j], quaternion=_quat_xyzw(samples["xquat"][rows, j])
                ),
            )
    for idx, rows in ((tick_idx, slice(None)), (frame_idx, frames.sample)):
        pts = samples["ee"][rows]
        rec.send_columns(
            f"{run}/world/ee",
            indexes=idx,
            columns=[*rr.Points3D.columns(positions=pts).partition([1] * len(pts))],
        )
    rec.log(f"{run}/world/ee", rr.Points3D.from_fields(radii=[0.012], colors=[(255, 200, 0)]), static=True)
    rec.log(
        f"{run}/world/ee_path",
        rr.LineStrips3D([samples["ee"]], colors=[(255, 200, 0)], radii=[0.003]),
        static=True,
    )
    # Time series: continuous samples (simulated, noise-free) ...
    for j, name in enumerate(robot.JOINT_NAMES):
        _send_scalars(rec, f"{run}/plots/joints/{name}", tick_idx, samples["q"][:, j])
    _send_scalars(rec, f"{run}/plots/gripper", tick_idx, samples["gripper"])
    for j, axis in enumerate("xyz"):
        _send_scalars(rec, f"{run}/plots/object/{axis}", tick_idx, samples["cube"][:, j])
    _send_scalars(rec, f"{run}/plots/success", tick_idx, samples["success"])
    # ... and the frames, with the recorded values.
    for j, name in enumerate(robot.JOINT_NAMES):
        _send_scalars(rec, f"{run}/plots/joints/{name}", frame_idx, frames.state[:, j])
    _send_scalars(rec, f"{run}/plots/gripper", frame_idx, frames.state[:, robot.N_JOINTS])
    for j, axis in enumerate("xyz"):
        _send_scalars(rec, f"{run}/plots/object/{axis}", frame_idx, frames.env_state[:, j])
    _send_scalars(rec, f"{run}/plots/success", frame_idx, frames.success)
    valid = np.all(np.isfinite(frames.action), axis=1)
    if valid.any():
        act_idx = _indexes(ft[valid], frames.frame_index[valid])
        for j, name in enumerate(robot.ACTION_NAMES):
            _send_scalars(rec, f"{run}/plots/action/{name}", act_idx, frames.action[valid, j])
    # Phase: text per frame + a step scalar over the continuous samples.
    known = frames.phase >= 0
    if known.any():
        rec.send_columns(
            f"{run}/plots/phase",
            indexes=_indexes(ft[known], frames.frame_index[known]),
            columns=rr.TextLog.columns(
                text=[_phase_name(p) for p in frames.phase[known]], level=["INFO"] * int(known.sum())
            ),
        )
        sample_phase = _phase_per_sample(len(t), frames.sample[known], frames.phase[known])
        _send_scalars(rec, f"{run}/plots/phase_index", tick_idx, sample_phase)
        _send_scalars(
            rec, f"{run}/plots/phase_index", _indexes(ft[known], frames.frame_index[known]), frames.phase[known]
        )


def _phase_name(p: int) -> str:
    return robot.PHASE_NAMES[int(p)] if 0 <= int(p) < robot.N_KEYFRAMES else f"phase {int(p)}"


def _phase_per_sample(n: int, frame_samples: np.ndarray, phases: np.ndarray) -> np.ndarray:
    out = np.full(n, float(phases[0]))
    for s, p in zip(frame_samples, phases):
        out[s:] = p
    return out


def _phase_color(p: int) -> tuple[int, int, int]:
    return PICK_COLOR if int(p) < robot.N_PHASES_PER_SUBTASK else PLACE_COLOR


def log_keyframes(rec, path: str, positions: np.ndarray, labels: list[str], colors=None, radius: float = 0.015) -> None:
    import rerun as rr

    if len(positions) == 0:
        return
    rec.log(path, rr.Points3D(positions, labels=labels, colors=colors, radii=[radius], show_labels=True), static=True)


def keyframe_markers(frames: FrameTable, samples: dict[str, np.ndarray]) -> tuple[np.ndarray, list[str], list]:
    """EE positions where each FSM state was reached (first frame of each phase), labelled with its name."""
    pos, labels, colors = [], [], []
    seen = set()
    for k, p in enumerate(frames.phase):
        if p < 0 or int(p) in seen:
            continue
        seen.add(int(p))
        pos.append(samples["ee"][frames.sample[k]])
        labels.append(_phase_name(p))
        colors.append(_phase_color(p))
    return np.asarray(pos).reshape(-1, 3), labels, colors


# ---------------------------------------------------------------------------------------------- dataset
@dataclass
class EpisodeData:
    index: int
    fps: int
    frame_index: np.ndarray
    timestamp: np.ndarray
    state: np.ndarray
    env_state: np.ndarray
    action: np.ndarray
    phase: np.ndarray
    success: np.ndarray
    seed: int | None
    env_kwargs: dict


def open_dataset(repo_id: str, root: str | None):
    """Open a LeRobotDataset; a missing local folder is a ``DatasetNotFoundError`` (no Hub download)."""
    if root is not None:
        info = Path(root).expanduser() / "meta" / "info.json"
        if not info.is_file():
            raise DatasetNotFoundError(
                f"no LeRobot dataset at root={root!r} (missing {info}); generate one with `lerobot-pnp generate`"
            )
    try:
        from lerobot_pnp.dataset import open_local_dataset

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return open_local_dataset(repo_id, root)
    except Exception as err:
        raise DatasetNotFoundError(f"cannot open dataset repo_id={repo_id!r} root={root!r}: {err}") from err


def _dataset_env_kwargs(ds) -> dict:
    """Env settings the dataset was generated with (a JSON file beside it), else inferred from its fps."""
    root = Path(ds.root)
    for rel in ENV_CONFIG_FILES:
        path = root / rel
        if path.is_file():
            cfg = json.loads(path.read_text())
            cfg = cfg.get("env", cfg)
            keep = ("control_mode", "fps", "speed", "path", "task_config")
            return {k: cfg[k] for k in keep if k in cfg}
    fps = int(ds.fps)
    return (
        {"control_mode": "keyframe", "fps": robot.KEYFRAME_FPS}
        if fps <= robot.KEYFRAME_FPS
        else {"control_mode": "dense", "fps": fps}
    )


def load_episode(ds, episode_index: int) -> EpisodeData:
    features = ds.meta.features
    missing = [k for k in (OBS_STATE, OBS_ENV, ACTION) if k not in features]
    if missing:
        raise IncompatibleDatasetError(f"dataset {ds.repo_id!r} lacks features {missing} (has {sorted(features)})")
    for key, dim in ((OBS_STATE, robot.STATE_DIM), (ACTION, robot.ACTION_DIM), (OBS_ENV, robot.OBJECT_DIM)):
        if tuple(features[key]["shape"]) != (dim,):
            raise IncompatibleDatasetError(
                f"dataset feature {key!r} has shape {features[key]['shape']}, expected ({dim},)"
            )
    ranges = {}
    for row in ds.meta.episodes:
        ranges[int(row["episode_index"])] = (int(row["dataset_from_index"]), int(row["dataset_to_index"]))
    if episode_index not in ranges:
        avail = sorted(ranges)
        shown = f"0..{avail[-1]}" if avail == list(range(len(avail))) else str(avail[:20])
        raise EpisodeNotFoundError(
            f"dataset {ds.repo_id!r} has no episode {episode_index} ({len(avail)} episodes: {shown})"
        )
    lo, hi = ranges[episode_index]
    hf = ds.hf_dataset.with_format(None)
    rows = hf.select(range(lo, hi)).to_dict()

    def col(key, dim=None, dtype=np.float32, default=None):
        if key not in rows:
            return default
        arr = np.asarray(rows[key], dtype=dtype)
        return arr.reshape(len(arr), dim) if dim else arr.reshape(len(arr))

    n = hi - lo
    seeds = col(EPISODE_SEED, dtype=np.int64)
    return EpisodeData(
        index=episode_index,
        fps=int(ds.fps),
        frame_index=col("frame_index", dtype=np.int64, default=np.arange(n)),
        timestamp=col("timestamp", dtype=np.float64, default=np.arange(n) / ds.fps),
        state=col(OBS_STATE, robot.STATE_DIM),
        env_state=col(OBS_ENV, robot.OBJECT_DIM),
        action=col(ACTION, robot.ACTION_DIM),
        phase=col(PHASE_INDEX, dtype=np.int64, default=np.full(n, -1)),
        success=col(SUCCESS, dtype=np.float64, default=np.zeros(n)),
        seed=int(seeds[0]) if seeds is not None else None,
        env_kwargs=_dataset_env_kwargs(ds),
    )


def make_env(env_kwargs: dict):
    from lerobot_pnp.env import BaxterPnPEnv

    kwargs = dict(env_kwargs)
    kwargs["cameras"] = ()
    kwargs["render_mode"] = None
    return BaxterPnPEnv(**kwargs)


def replay_episode(ep: EpisodeData, scene_env, hz: float) -> tuple[SceneModel, dict, FrameTable, dict]:
    """Re-simulate a dataset episode (reset with its seed, step its actions) and sample it continuously."""
    env = scene_env
    scene = SceneModel(env.model)
    sampler = Sampler(env, scene, hz)
    n = len(ep.frame_index)
    info: dict[str, Any] = {"frames": n}
    frame_samples = []
    if ep.seed is not None:
        obs, _ = env.reset(seed=ep.seed)
        env.on_control_tick = sampler
        sampler.start()
        replayed = []
        try:
            for k in range(n):
                frame_samples.append(sampler.sample(force=True))
                replayed.append(np.asarray(obs["agent_pos"], np.float32))
                if k < n - 1:
                    obs, *_ = env.step(ep.action[k])
        finally:
            env.on_control_tick = None
        err = float(np.max(np.abs(np.stack(replayed) - ep.state)))
        info.update(mode="replay", seed=ep.seed, replay_max_state_error=err)
        if err > 1e-3:
            logger.warning(
                "viz: episode %d re-simulated with seed %d deviates from the dataset by up to %.4g "
                "(different env settings?); the 3D motion is the re-simulation, the plots at frames are the dataset's",
                ep.index,
                ep.seed,
                err,
            )
    else:  # no seed: pose the model from the recorded states, one sample per frame
        env.reset(seed=0)
        sampler.start()
        m, d = env.model, env.data
        for k in range(n):
            d.qpos[env._qadr] = ep.state[k, : robot.N_JOINTS]
            opening = float(ep.state[k, robot.N_JOINTS]) * robot.FINGER_TRAVEL
            d.qpos[env._finger_qadr] = (opening, -opening)
            d.qpos[env._cube_qadr : env._cube_qadr + 3] = ep.env_state[k]
            d.time = sampler.t0 + float(ep.timestamp[k] - ep.timestamp[0])
            mujoco.mj_forward(m, d)
            frame_samples.append(sampler.sample(force=True))
        info.update(mode="kinematic (no episode.seed column)")
    frames = FrameTable(
        frame_index=ep.frame_index,
        sample=np.asarray(frame_samples, dtype=np.int64),
        state=ep.state,
        env_state=ep.env_state,
        action=ep.action,
        phase=ep.phase,
        success=ep.success,
    )
    samples = sampler.arrays()
    info["samples"] = len(samples["t"])
    info["success"] = bool(ep.success[-1] > 0.5) if len(ep.success) else False
    return scene, samples, frames, info


# ---------------------------------------------------------------------------------------------- policy
def rollout_with_expert(loaded, seed: int, control_mode: str, hz: float, compare_expert: bool):
    """Run the policy from ``seed`` (sampled continuously) and, optionally, the FSM expert from the same start."""
    from lerobot_pnp.env import DEFAULT_MAX_STEPS
    from lerobot_pnp.rollout import run_policy_episode

    env_kwargs = {"control_mode": control_mode, "fps": robot.KEYFRAME_FPS if control_mode == "keyframe" else DENSE_FPS}
    env = make_env(env_kwargs)
    scene = SceneModel(env.model)
    sampler = Sampler(env, scene, hz)
    frame_samples: list[int] = []
    started = []

    def on_step(k, obs, action):
        if not started:
            sampler.start()
            env.on_control_tick = sampler
            started.append(True)
        frame_samples.append(sampler.sample(force=True))

    try:
        pe = run_policy_episode(env, loaded, seed, max_steps=DEFAULT_MAX_STEPS[control_mode], on_step=on_step)
        frame_samples.append(sampler.sample(force=True))  # the final observation
    finally:
        env.on_control_tick = None
    n_steps = pe.num_steps
    actions = np.full((n_steps + 1, robot.ACTION_DIM), np.nan, np.float32)
    actions[:n_steps] = pe.actions
    phases = np.arange(n_steps + 1) if control_mode == "keyframe" else np.full(n_steps + 1, -1)
    phases = np.where(phases < robot.N_KEYFRAMES, phases, robot.N_KEYFRAMES - 1)
    success = np.concatenate([[0.0], pe.successes.astype(float)])
    frames = FrameTable(
        frame_index=np.arange(n_steps + 1),
        sample=np.asarray(frame_samples, dtype=np.int64),
        state=pe.states,
        env_state=pe.object_positions,
        action=actions,
        phase=phases,
        success=success,
    )
    info: dict[str, Any] = {"seed": seed, "steps": n_steps, "success": pe.success}
    expert = None
    if compare_expert and control_mode == "keyframe":
        expert = _expert_reference(env_kwargs, seed, scene, hz)
        info["expert_success"] = expert["success"]
        if expert.get("error"):
            info["expert_error"] = expert["error"]
    env_data = env.data
    samples = sampler.arrays()
    info["samples"] = len(samples["t"])
    return scene, samples, frames, info, expert, env_data, pe


def _expert_reference(env_kwargs: dict, seed: int, scene: SceneModel, hz: float) -> dict:
    """The FSM expert's keyframes (and EE path) from the start state ``seed`` gives."""
    from lerobot_pnp.expert import run_expert_episode

    env = make_env(env_kwargs)
    path: list[np.ndarray] = []
    env.on_control_tick = lambda e: path.append(e.ee_pose()[0])
    out: dict[str, Any] = {"success": False}
    try:
        ep = run_expert_episode(env, seed)
        out.update(success=ep.success, actions=ep.actions, keyframes=ep.keyframes)
    except PnPError as err:  # the expert failed (unreachable / dropped): nothing to compare against
        out["error"] = str(err)
    finally:
        env.on_control_tick = None
    out["ee_path"] = np.asarray(path[:: max(1, round(100 / hz))]).reshape(-1, 3)
    return out


def log_policy_comparison(
    rec, run: str, scene: SceneModel, data, times: np.ndarray, frames: FrameTable, expert: dict | None, info: dict
) -> None:
    """Predicted keyframes (3D + scalars) and, with an expert reference, the expert's and the errors."""
    import rerun as rr

    scratch = mujoco.MjData(scene.model)
    n = int(np.sum(np.all(np.isfinite(frames.action), axis=1)))
    pred = frames.action[:n]
    pred_ee = np.array([scene.ee_position(data, a, scratch) for a in pred]).reshape(-1, 3)
    # Action k commands the next FSM state (k + 1).
    labels = [f"pred {_phase_name(min(k + 1, robot.N_KEYFRAMES - 1))}" for k in range(n)]
    colors = [_phase_color(min(k + 1, robot.N_KEYFRAMES - 1)) for k in range(n)]
    log_keyframes(rec, f"{run}/world/keyframes", pred_ee, labels, colors)
    if expert is None or "actions" not in expert:
        return
    ref = expert["actions"]
    m = min(n, len(ref))
    ref_ee = np.array([scene.ee_position(data, a, scratch) for a in ref]).reshape(-1, 3)
    log_keyframes(
        rec,
        f"{run}/world/expert_keyframes",
        ref_ee,
        [f"expert {_phase_name(min(k + 1, robot.N_KEYFRAMES - 1))}" for k in range(len(ref))],
        [EXPERT_COLOR] * len(ref),
        radius=0.01,
    )
    if len(expert["ee_path"]):
        rec.log(
            f"{run}/world/expert_ee_path",
            rr.LineStrips3D([expert["ee_path"]], colors=[EXPERT_COLOR], radii=[0.002]),
            static=True,
        )
    if m == 0:
        return
    idx = _indexes(times[frames.sample[:m]], frames.frame_index[:m])
    for j, name in enumerate(robot.ACTION_NAMES):
        _send_scalars(rec, f"{run}/policy/pred/{name}", idx, pred[:m, j])
        _send_scalars(rec, f"{run}/policy/expert/{name}", idx, ref[:m, j])
    err = np.abs(pred[:m] - ref[:m])
    for j, name in enumerate(robot.JOINT_NAMES):
        _send_scalars(rec, f"{run}/policy/error/joints/{name}", idx, err[:, j])
    _send_scalars(rec, f"{run}/policy/error/gripper", idx, err[:, robot.N_JOINTS])
    ee_err = np.linalg.norm(pred_ee[:m] - ref_ee[:m], axis=1)
    _send_scalars(rec, f"{run}/policy/error/ee_pos", idx, ee_err)
    info["mean_joint_error_rad"] = float(err[:, : robot.N_JOINTS].mean())
    info["mean_ee_error_m"] = float(ee_err.mean())
    info["max_ee_error_m"] = float(ee_err.max())


# ---------------------------------------------------------------------------------------------- blueprint
def make_blueprint(runs: list[tuple[str, bool]]):
    import rerun.blueprint as rrb

    tabs = []
    for run, is_policy in runs:
        plots = [
            rrb.TimeSeriesView(origin=f"{run}/plots/joints", name="joint angles (rad)"),
            rrb.TimeSeriesView(
                name="gripper / phase / success",
                contents=[f"{run}/plots/gripper", f"{run}/plots/phase_index", f"{run}/plots/success"],
            ),
            rrb.TimeSeriesView(origin=f"{run}/plots/object", name="object position (m)"),
        ]
        if is_policy:
            plots.append(rrb.TimeSeriesView(origin=f"{run}/policy/error", name="policy vs expert error"))
        plots.append(rrb.TextLogView(origin=f"{run}/plots/phase", name="FSM phase"))
        tabs.append(
            rrb.Horizontal(
                rrb.Spatial3DView(origin=f"{run}/world", name=f"{run} 3D"),
                rrb.Vertical(*plots),
                column_shares=[3, 2],
                name=run,
            )
        )
    return rrb.Blueprint(rrb.Tabs(*tabs), collapse_panels=False)


# ---------------------------------------------------------------------------------------------- entry point
def _has_display() -> bool:
    if sys.platform != "linux":
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def visualize(cfg: VizConfig) -> dict:
    """Log the requested dataset episodes and/or policy rollouts to Rerun; returns a summary."""
    import rerun as rr

    if cfg.repo_id is None and cfg.policy_path is None:
        raise ConfigError("nothing to show: give --repo_id (with --root) for dataset episodes and/or --policy_path")
    if cfg.save is None and not _has_display():
        raise ConfigError(
            "no display to spawn the Rerun viewer on: pass --save out.rrd and open it with `rerun out.rrd`"
        )

    # Load and check everything before opening the recording, so bad input fails fast and writes nothing.
    episodes: list[EpisodeData] = []
    if cfg.repo_id is not None:
        ds = open_dataset(cfg.repo_id, cfg.root)
        episodes = [load_episode(ds, i) for i in cfg.episode_index]
    loaded = None
    if cfg.policy_path is not None:
        from lerobot_pnp.rollout import load_policy

        loaded = load_policy(cfg.policy_path, device=cfg.device)
    runs = [(f"episode_{ep.index}", False) for ep in episodes]
    seeds = [cfg.seed + i for i in range(cfg.n_rollouts)] if loaded is not None else []
    runs += [(f"rollout_{i}", True) for i in range(len(seeds))]

    rec = rr.RecordingStream(APPLICATION_ID, recording_id=None)
    blueprint = make_blueprint(runs)
    if cfg.save is not None:
        Path(cfg.save).expanduser().parent.mkdir(parents=True, exist_ok=True)
        rec.save(str(Path(cfg.save).expanduser()), default_blueprint=blueprint)
    else:
        rec.spawn(default_blueprint=blueprint)
    title = cfg.repo_id or Path(cfg.policy_path).name
    rec.send_recording_name(f"{title} ({', '.join(r for r, _ in runs)})")

    summary: dict[str, Any] = {"recording": str(cfg.save) if cfg.save else "spawned viewer", "runs": []}
    for ep in episodes:
        env = make_env(ep.env_kwargs)
        run = f"episode_{ep.index}"
        scene, samples, frames, info = replay_episode(ep, env, cfg.log_hz)
        scene.log_static(rec, run, env.data)
        log_run(rec, run, scene, samples, frames)
        pos, labels, colors = keyframe_markers(frames, samples)
        log_keyframes(rec, f"{run}/world/keyframes", pos, labels, colors)
        summary["runs"].append({"run": run, **info})
        env.close()
    for i, seed in enumerate(seeds):
        run = f"rollout_{i}"
        scene, samples, frames, info, expert, data, _ = rollout_with_expert(
            loaded, seed, cfg.control_mode, cfg.log_hz, cfg.compare_expert
        )
        scene.log_static(rec, run, data)
        log_run(rec, run, scene, samples, frames)
        log_policy_comparison(rec, run, scene, data, samples["t"], frames, expert, info)
        summary["runs"].append({"run": run, "policy": str(loaded.path), **info})
    rec.flush()
    if cfg.save is not None:
        rec.disconnect()
    return summary


# ---------------------------------------------------------------------------------------------- still picture
def render_picture(
    out: str | Path,
    seed: int = 0,
    step: int = 3,
    fraction: float = 0.5,
    camera: str = "view",
    size: tuple[int, int] = (480, 640),
) -> dict:
    """MuJoCo offscreen render of the viewer's scene (for the README, where no Rerun viewer can run).

    Runs the FSM expert from ``seed``, poses the scene ``fraction`` of the way through keyframe step ``step``
    (3: lifting the grasped cube), and draws the end-effector path and the labelled FSM keyframes on top.
    ``camera`` is one of the model's cameras ("front", "overhead", "wrist") or "view": a free camera framing
    the arm and the table from the front right. Needs an OpenGL backend (``MUJOCO_GL=egl``, or ``osmesa``).
    """
    os.environ.setdefault("MUJOCO_GL", "egl")
    from PIL import Image

    from lerobot_pnp.expert import run_expert_episode

    env = make_env({"control_mode": "keyframe", "fps": robot.KEYFRAME_FPS})
    ticks: list[tuple[int, np.ndarray, np.ndarray]] = []
    env.on_control_tick = lambda e: ticks.append((e._step_count, e.data.qpos.copy(), e.ee_pose()[0]))
    ep = run_expert_episode(env, seed)
    env.on_control_tick = None
    in_step = [t for t in ticks if t[0] == step]
    if not in_step:
        raise ConfigError(f"step must be in 0..{ticks[-1][0]}, got {step}")
    _, qpos, _ = in_step[min(len(in_step) - 1, int(fraction * len(in_step)))]
    scene = SceneModel(env.model)
    m, d = env.model, env.data
    scratch = mujoco.MjData(m)
    kf_ee = [scene.ee_position(d, s[: robot.N_JOINTS], scratch) for s in ep.keyframe_states]
    path = np.asarray([t[2] for t in ticks])[::4]
    d.qpos[:] = qpos
    mujoco.mj_forward(m, d)

    h, w = size
    renderer = mujoco.Renderer(m, height=h, width=w)
    if camera == "view":
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = (0.55, 0.2, 0.0)
        cam.distance, cam.azimuth, cam.elevation = 1.6, 120.0, -25.0
        renderer.update_scene(d, camera=cam)
    else:
        renderer.update_scene(d, camera=camera)
    scn = renderer.scene
    scn.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0  # shadow acne on the large table top at this resolution

    def add(kind, size3, pos, rgba, label=""):
        if scn.ngeom >= scn.maxgeom:
            return None
        g = scn.geoms[scn.ngeom]
        mujoco.mjv_initGeom(
            g, kind, np.asarray(size3, float), np.asarray(pos, float), np.eye(3).ravel(), np.asarray(rgba, np.float32)
        )
        g.label = label
        scn.ngeom += 1
        return g

    for a, b in zip(path[:-1], path[1:]):
        g = add(mujoco.mjtGeom.mjGEOM_CAPSULE, [0, 0, 0], a, [1.0, 0.78, 0.0, 1.0])
        if g is not None:
            mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_CAPSULE, 0.003, a, b)
    for k, p in enumerate(kf_ee):
        # States at (nearly) the same place, e.g. grasp/close: stack their markers so every label shows.
        offset = sum(np.linalg.norm(p - q) < 0.03 for q in kf_ee[:k])
        color = np.asarray(_phase_color(k), float) / 255
        add(mujoco.mjtGeom.mjGEOM_SPHERE, [0.012] * 3, p + [0, 0, 0.045 * offset], [*color, 1.0], robot.PHASE_NAMES[k])
    img = renderer.render().copy()
    renderer.close()
    env.close()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(img).save(out, optimize=True)
    if out.stat().st_size > 300_000:
        Image.fromarray(img).quantize(colors=256).save(out, optimize=True)
    return {
        "path": str(out),
        "bytes": out.stat().st_size,
        "seed": seed,
        "step": step,
        "mujoco_gl": os.environ["MUJOCO_GL"],
    }
