"""Policy rollouts for the viewer, each beside the FSM expert.

A checkpoint is run closed loop in the task it was trained on (``task_source`` = the checkpoint: its
training config names the dataset, whose recorded task is read back, cameras included), seeded like
``lerobot-eval``. At every state the policy visits, the expert's label for that state (the DAgger teacher,
``dagger.rollouts.Teacher``) is what the policy should have commanded there, so the comparison stays
meaningful after a recovery or a perturbation. The expert is also run in a second env from the same seed
(same start pose and object), for its own path in 3D. The camera images the env rendered (the frames the policy
received), the keypoints a keypoint encoder computed on them (``keypoints``), the perturbations that fired and
the failure cause are kept for the viewer.
"""

from __future__ import annotations

import logging

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.errors import PnPError
from lerobot_pnp.recorded_task import read_recorded
from lerobot_pnp.viz.keypoints import KeypointTap
from lerobot_pnp.viz.sampling import Frames, Run, Sampler, run_events
from lerobot_pnp.viz.scene import SceneModel

logger = logging.getLogger(__name__)


def rollout_config(
    checkpoint: str,
    task_source: str | None,
    control_mode: str | None,
    env_changes: dict | None = None,
    policy_cameras: dict[str, tuple[int, int]] | None = None,
) -> BaxterPnPEnvConfig:
    """The env a policy is shown in: the recorded task of ``task_source`` (default: the checkpoint's), with
    ``env_changes`` (task fields, cameras, image size) on top. The cameras a policy reads (``policy_cameras``,
    camera -> (height, width)) are always rendered, at the size it was trained on."""
    source = task_source or checkpoint
    recorded = read_recorded(source)
    changes = dict(env_changes or {})
    if policy_cameras:
        cams = list(changes.get("cameras", recorded.get("cameras", []) if recorded else []))
        changes["cameras"] = cams + [c for c in policy_cameras if c not in cams]
        (height, width) = next(iter(policy_cameras.values()))
        changes.setdefault("image_height", height)
        changes.setdefault("image_width", width)
    if recorded is None:
        logger.warning("viz: %s records no task (no dataset env config found): rollouts use the paper's task", source)
        return BaxterPnPEnvConfig(preset="paper", control_mode=control_mode or "keyframe", **changes)
    if control_mode is not None and control_mode != recorded.get("control_mode"):
        # a deliberate look at the policy in another control mode: that mode's own rate and episode length
        changes["control_mode"] = control_mode
    # with_changes derives the rate and episode length of a changed mode or keyframe budget
    return BaxterPnPEnvConfig.from_dict(recorded).with_changes(**changes)


def rollout_with_expert(
    loaded, config: BaxterPnPEnvConfig, seed: int, hz: float, compare_expert: bool, name: str = "rollout_0"
) -> Run:
    """Run the policy from ``seed`` (sampled continuously) and, optionally, the expert from the same start."""
    from lerobot_pnp.closed_loop import run_episode
    from lerobot_pnp.dagger.rollouts import Teacher
    from lerobot_pnp.dataset.episodes import PixelRecorder

    env = PixelRecorder(make_env(config, render_mode=None))
    base = env.unwrapped
    physics = base.physics
    scene = SceneModel(physics.model)
    sampler = Sampler(physics, scene, base.is_success, hz)
    frame_samples: list[int] = []
    labels: list[np.ndarray] = []
    teacher: list = []
    tap = KeypointTap(loaded.policy)

    def on_step(k, obs, action):
        tap.take()  # the policy has just acted on frame k
        if k == 0:
            sampler.start()
            physics.on_control_tick = sampler
            teacher.append(Teacher(env) if compare_expert and config.control_mode == "keyframe" else None)
        frame_samples.append(sampler.sample())
        if teacher[0] is not None:
            labels.append(_label(teacher[0]))

    try:
        with tap:
            pe = run_episode(env, loaded, seed, on_step=on_step)
        frame_samples.append(sampler.sample())  # the final observation
        qpos = physics.data.qpos.copy()
        place_target = physics.place_target().round(4).tolist()
    finally:
        physics.on_control_tick = None
        env.close()
    n = pe.num_steps
    actions = np.full((n + 1, robot.ACTION_DIM), np.nan, np.float32)
    actions[:n] = pe.actions
    # The phase a keyframe policy is in: the env's info["phase"] where it reports one, else the step index.
    if pe.phases is not None:
        phases = pe.phases
    else:
        phases = np.arange(n + 1) if config.control_mode == "keyframe" else np.full(n + 1, -1)
    frames = Frames(
        frame_index=np.arange(n + 1),
        sample=np.asarray(frame_samples, dtype=np.int64),
        state=pe.states,
        object=pe.env_states,
        action=actions,
        phase=np.minimum(np.asarray(phases), robot.N_KEYFRAMES - 1),
        success=np.concatenate([[0.0], pe.successes.astype(float)]),
    )
    info = {"seed": seed, "steps": n, "success": pe.success, "place_target": place_target}
    events = run_events(env.infos)
    info["events"] = [f"frame {k}: {text}" for k, _, text in events]
    images = {cam: [p[cam] for p in env.pixels] for cam in config.cameras}
    expert = None
    if compare_expert and config.control_mode == "keyframe":
        expert = expert_reference(config, seed, hz)
        expert["labels"] = np.asarray(labels, np.float32).reshape(-1, robot.ACTION_DIM)
        info["expert_success"] = expert["success"]
        if expert.get("error"):
            info["expert_error"] = expert["error"]
    samples = sampler.arrays()
    info["samples"] = len(samples["t"])
    return Run(
        name=name, scene=scene, qpos=qpos, samples=samples, frames=frames, info=info, is_rollout=True,
        expert=expert, images=images, events=events, keypoints=tap.per_frame,
    )  # fmt: skip


def _label(teacher) -> np.ndarray:
    """The expert's keyframe for the visited state (NaN where it has no IK solution: the object was pushed away)."""
    try:
        return np.asarray(teacher.label()[0], np.float32)
    except PnPError:
        return np.full(robot.ACTION_DIM, np.nan, np.float32)


def expert_reference(config: BaxterPnPEnvConfig, seed: int, hz: float) -> dict:
    """The FSM expert's actions and end-effector path from the start state ``seed`` gives."""
    from lerobot_pnp.expert import run_expert_episode

    env = make_env(config, render_mode=None)
    physics = env.unwrapped.physics
    path: list[np.ndarray] = []
    physics.on_control_tick = lambda p: path.append(p.ee_pose()[0])
    out: dict = {"success": False}
    try:
        ep = run_expert_episode(env, seed)
        out.update(success=ep.success, actions=ep.actions)
    except PnPError as err:  # the expert failed (unreachable / dropped): the path so far, no keyframes
        out["error"] = str(err)
    finally:
        physics.on_control_tick = None
        env.close()
    out["ee_path"] = np.asarray(path[:: max(1, round(100 / hz))]).reshape(-1, 3)
    return out
