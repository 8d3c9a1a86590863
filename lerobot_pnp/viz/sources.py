"""Dataset episodes for the viewer: open the dataset, read an episode, replay it in the task it was made with.

The env a dataset episode is replayed in is built from the task recorded with the dataset
(``meta/baxter_pnp_env.json``, written by ``lerobot-pnp generate``), so a dataset generated with another
object region or place target is shown in that task with no flag. An older dataset without the file is
replayed in the paper's task, with a one-line warning.

An episode that records its ``episode.seed`` is *re-simulated*: the env is reset with that seed and the
recorded actions are stepped, while a ``Sampler`` watches every control tick, so the motion between frames is
the simulator's. The replayed observations are compared with the recorded ones (``replay_max_state_error``).
An episode without a seed is posed frame by frame from its recorded states (``physics.set_state``).
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE

from lerobot_pnp import robot
from lerobot_pnp.errors import DatasetError
from lerobot_pnp.evaluation.checkpoints import ENV_STATE_WIDTHS
from lerobot_pnp.integration.recorded_task import read_recorded
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.viz.sampling import Frames, Run, Sampler, run_events
from lerobot_pnp.viz.scene import SceneModel

logger = logging.getLogger(__name__)

PHASE_INDEX, EPISODE_SEED, SUCCESS = "phase.index", "episode.seed", "next.success"
# Fields of the recorded env config that are not task fields but shape the motion (and its length).
MOTION_FIELDS = ("control_mode", "fps", "speed", "straight_paths", "episode_length")
REPLAY_TOLERANCE = 1e-3  # rad / opening: a larger replay error means the episode was made in another env


class DatasetNotFoundError(DatasetError):
    """No dataset at the given repo id / root."""


class EpisodeNotFoundError(DatasetError):
    """The dataset has no episode with the requested index."""


class IncompatibleDatasetError(DatasetError):
    """The dataset lacks the features this viewer needs (observation.state (8,), action (8,), ...)."""


@dataclass
class EpisodeData:
    """One dataset episode as recorded."""

    index: int
    fps: int
    frame_index: np.ndarray
    timestamp: np.ndarray
    state: np.ndarray
    object: np.ndarray
    action: np.ndarray
    phase: np.ndarray
    success: np.ndarray
    seed: int | None


def open_dataset(repo_id: str, root: str | None):
    """Open a LeRobotDataset; a missing local folder is a ``DatasetNotFoundError`` (no Hub download)."""
    from lerobot_pnp.dataset import open_local_dataset
    from lerobot_pnp.dataset.layout import is_dataset

    if root is not None and not is_dataset(root):
        raise DatasetNotFoundError(
            f"no LeRobot dataset at root={root!r} (no meta/info.json); generate one with `lerobot-pnp generate`"
        )

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return open_local_dataset(repo_id, root)
    except DatasetError:
        raise
    except Exception as err:  # LeRobot / Hub errors for a repo id that is neither local nor cached
        raise DatasetNotFoundError(f"cannot open dataset repo_id={repo_id!r} root={root!r}: {err}") from None


def replay_config(ds) -> BaxterPnPEnvConfig:
    """The env config a dataset was generated with (its recorded task), for replaying its episodes."""
    root = Path(ds.root)
    recorded = read_recorded(root)
    if recorded is not None:
        motion = {k: recorded[k] for k in MOTION_FIELDS if recorded.get(k) is not None}
        return BaxterPnPEnvConfig.from_source(str(root), cameras=[], **motion)
    fps = int(ds.fps)
    mode = "keyframe" if fps <= robot.KEYFRAME_FPS else "dense"
    logger.warning(
        "viz: %s records no task (no meta/baxter_pnp_env.json, an older dataset): replaying in the paper's task", root
    )
    return BaxterPnPEnvConfig(preset="paper", control_mode=mode, fps=None if mode == "keyframe" else fps, cameras=[])


def _env_state_dim(features: dict) -> int:
    """Width of the recorded environment state: object xyz [+ yaw features] [+ goal]; anything else is checked
    (and rejected) as the paper's 3."""
    shape = tuple(features.get(OBS_ENV_STATE, {}).get("shape", ()))
    return shape[0] if len(shape) == 1 and shape[0] in ENV_STATE_WIDTHS else robot.OBJECT_DIM


def _check_features(ds) -> None:
    features = ds.meta.features
    env_dim = _env_state_dim(features)
    for key, dim in ((OBS_STATE, robot.STATE_DIM), (ACTION, robot.ACTION_DIM), (OBS_ENV_STATE, env_dim)):
        if key not in features:
            raise IncompatibleDatasetError(
                f"dataset {ds.repo_id!r} has no {key!r} feature (has {sorted(features)}): not a Baxter pnp dataset"
            )
        if tuple(features[key]["shape"]) != (dim,):
            raise IncompatibleDatasetError(
                f"dataset {ds.repo_id!r}: feature {key!r} has shape {tuple(features[key]['shape'])}, expected ({dim},)"
            )


def load_episode(ds, episode_index: int) -> EpisodeData:
    """The recorded columns of one episode (``EpisodeNotFoundError`` names the valid indices)."""
    _check_features(ds)
    ranges = {
        int(row["episode_index"]): (int(row["dataset_from_index"]), int(row["dataset_to_index"]))
        for row in ds.meta.episodes
    }
    if episode_index not in ranges:
        avail = sorted(ranges)
        shown = f"0..{avail[-1]}" if avail == list(range(len(avail))) else str(avail[:20])
        raise EpisodeNotFoundError(
            f"dataset {ds.repo_id!r} has no episode {episode_index} ({len(avail)} episodes: {shown})"
        )
    lo, hi = ranges[episode_index]
    rows = ds.hf_dataset.with_format(None).select(range(lo, hi)).to_dict()
    n = hi - lo

    def col(key, dim=None, dtype=np.float32, default=None):
        if key not in rows:
            return default
        arr = np.asarray(rows[key], dtype=dtype)
        return arr.reshape(len(arr), dim) if dim else arr.reshape(len(arr))

    seeds = col(EPISODE_SEED, dtype=np.int64)
    return EpisodeData(
        index=episode_index,
        fps=int(ds.fps),
        frame_index=col("frame_index", dtype=np.int64, default=np.arange(n)),
        timestamp=col("timestamp", dtype=np.float64, default=np.arange(n) / ds.fps),
        state=col(OBS_STATE, robot.STATE_DIM),
        object=col(OBS_ENV_STATE, _env_state_dim(ds.meta.features))[:, : robot.OBJECT_DIM],  # xyz
        action=col(ACTION, robot.ACTION_DIM),
        phase=col(PHASE_INDEX, dtype=np.int64, default=np.full(n, -1)),
        success=col(SUCCESS, dtype=np.float64, default=np.zeros(n)),
        seed=int(seeds[0]) if seeds is not None else None,
    )


def replay_episode(ep: EpisodeData, config: BaxterPnPEnvConfig, hz: float) -> Run:
    """Re-simulate (or pose) a dataset episode in the env of ``config``, sampled at ``hz`` (see module doc)."""
    from lerobot_pnp.dataset.episodes import PixelRecorder

    env = PixelRecorder(make_env(config, render_mode=None))
    base = env.unwrapped
    physics = base.physics
    scene = SceneModel(physics.model)
    sampler = Sampler(physics, scene, base.is_success, hz)
    n = len(ep.frame_index)
    events: list = []
    info: dict = {"frames": n, "place_target": physics.place_target().round(4).tolist()}
    frame_samples = []
    try:
        if ep.seed is not None:
            obs, _ = env.reset(seed=ep.seed)
            sampler.start()
            physics.on_control_tick = sampler
            replayed = []
            for k in range(n):
                frame_samples.append(sampler.sample())
                replayed.append(np.concatenate([obs["agent_pos"], obs["environment_state"][: robot.OBJECT_DIM]]))
                if k < n - 1:
                    obs, *_ = env.step(ep.action[k])
            physics.on_control_tick = None
            err = float(np.max(np.abs(np.stack(replayed) - np.concatenate([ep.state, ep.object], axis=1))))
            info.update(mode="replay", seed=ep.seed, replay_max_state_error=err)
            events = run_events(env.infos)  # the perturbations the re-simulation applied, the outcome
            if err > REPLAY_TOLERANCE:
                logger.warning(
                    "viz: episode %d re-simulated with seed %d deviates from the dataset by up to %.3g; the 3D "
                    "motion is the re-simulation, the plots at frames are the dataset's",
                    ep.index,
                    ep.seed,
                    err,
                )
        else:  # no seed: pose the model from the recorded states, one sample per frame
            env.reset(seed=0)
            sampler.start()
            for k in range(n):
                physics.set_state(ep.state[k, : robot.N_JOINTS], ep.state[k, robot.N_JOINTS], ep.object[k])
                frame_samples.append(sampler.sample(t=float(ep.timestamp[k] - ep.timestamp[0])))
            info.update(mode="kinematic (no episode.seed column)")
        qpos = physics.data.qpos.copy()
    finally:
        physics.on_control_tick = None
        env.close()
    frames = Frames(
        frame_index=ep.frame_index,
        sample=np.asarray(frame_samples, dtype=np.int64),
        state=ep.state,
        object=ep.object,
        action=ep.action,
        phase=ep.phase,
        success=ep.success,
    )
    info["success"] = bool(ep.success[-1] > 0.5) if len(ep.success) else False
    samples = sampler.arrays()
    info["samples"] = len(samples["t"])
    info["events"] = [f"frame {k}: {text}" for k, _, text in events]
    return Run(
        name=f"episode_{ep.index}", scene=scene, qpos=qpos, samples=samples, frames=frames, info=info, events=events
    )
