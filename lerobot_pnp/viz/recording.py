"""Logging runs to a Rerun recording: the motion, the plots, keyframe markers, and the blueprint.

Timelines: ``time`` (duration, simulated seconds since reset) carries every sample; ``frame_index``
(sequence) carries the rows logged at a run's frames, whose values are the dataset's own (at frame ``k``,
``plots/joints/<j>`` equals ``observation.state[k]``). Entity paths are listed in ``lerobot_pnp.viz``.

Keyframe markers (``keyframe_markers``) are labelled once per place.
"""

from __future__ import annotations

import mujoco
import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.viz.keyframe_markers import keyframes_reached, log_keyframes
from lerobot_pnp.viz.keypoints import keypoint_points
from lerobot_pnp.viz.sampling import Run, phase_name
from lerobot_pnp.viz.scene import quat_xyzw

EXPERT_COLOR, EE_COLOR = (90, 220, 90), (255, 200, 0)
# One colour per joint (and the gripper), the same in every plot, so a joint is found across panels.
SERIES_COLORS = (
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (188, 189, 34),
)
# The 3D view's initial eye: from the front right of the robot, above the table, looking at the workspace.
EYE_POSITION = (1.6, -0.92, 0.78)
EYE_TARGET = (0.42, 0.15, 0.06)


def _scalars(rec, path: str, indexes, values) -> None:
    import rerun as rr

    rec.send_columns(path, indexes=indexes, columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)))


def _indexes(times: np.ndarray, frames: np.ndarray | None = None) -> list:
    import rerun as rr

    idx = [rr.TimeColumn("time", duration=np.asarray(times, dtype=np.float64))]
    if frames is not None:
        idx.insert(0, rr.TimeColumn("frame_index", sequence=np.asarray(frames, dtype=np.int64)))
    return idx


def _style(rec, path: str, color, name: str, *, points: bool = False, steps: bool = False) -> None:
    """Static series style: a line (``steps``: held until the next value) or cross markers."""
    import rerun as rr

    if points:
        style = rr.SeriesPoints(colors=[color], names=[name], markers=["cross"], marker_sizes=[5.0])
    else:
        style = rr.SeriesLines(colors=[color], names=[name], interpolation_mode="StepAfter" if steps else None)
    rec.log(path, style, static=True)


def log_run(rec, run: Run) -> None:
    """One run's continuous samples (``time``), its frames (``frame_index`` + ``time``) and its keyframes."""
    import rerun as rr

    name, scene, samples, frames = run.name, run.scene, run.samples, run.frames
    t = samples["t"]
    ft = t[frames.sample]
    tick_idx, frame_idx = _indexes(t), _indexes(ft, frames.frame_index)
    for j, b in enumerate(scene.dynamic):
        for idx, rows in ((tick_idx, slice(None)), (frame_idx, frames.sample)):
            rec.send_columns(
                f"{name}/{scene.entity[b]}",
                indexes=idx,
                columns=rr.Transform3D.columns(
                    translation=samples["xpos"][rows, j], quaternion=quat_xyzw(samples["xquat"][rows, j])
                ),
            )
    for idx, rows in ((tick_idx, slice(None)), (frame_idx, frames.sample)):
        pts = samples["ee"][rows]
        rec.send_columns(
            f"{name}/world/ee", indexes=idx, columns=[*rr.Points3D.columns(positions=pts).partition([1] * len(pts))]
        )
    rec.log(f"{name}/world/ee", rr.Points3D.from_fields(radii=[0.01], colors=[EE_COLOR]), static=True)
    rec.log(f"{name}/world/ee_path", rr.LineStrips3D([samples["ee"]], colors=[EE_COLOR], radii=[0.003]), static=True)
    # Time series: the continuous samples (simulated, noise-free) ...
    for j, joint in enumerate(robot.JOINT_NAMES):
        _style(rec, f"{name}/plots/joints/{joint}", SERIES_COLORS[j], joint)
        _scalars(rec, f"{name}/plots/joints/{joint}", tick_idx, samples["q"][:, j])
    _style(rec, f"{name}/plots/gripper", SERIES_COLORS[robot.N_JOINTS], "gripper opening")
    _style(rec, f"{name}/plots/success", (90, 220, 120), "success", steps=True)
    _scalars(rec, f"{name}/plots/gripper", tick_idx, samples["gripper"])
    for j, axis in enumerate("xyz"):
        _style(rec, f"{name}/plots/object/{axis}", ((230, 80, 80), (80, 200, 80), (80, 140, 255))[j], axis)
        _scalars(rec, f"{name}/plots/object/{axis}", tick_idx, samples["object"][:, j])
    _scalars(rec, f"{name}/plots/success", tick_idx, samples["success"])
    # ... and the frames, with the recorded values.
    for j, joint in enumerate(robot.JOINT_NAMES):
        _scalars(rec, f"{name}/plots/joints/{joint}", frame_idx, frames.state[:, j])
    _scalars(rec, f"{name}/plots/gripper", frame_idx, frames.state[:, robot.N_JOINTS])
    for j, axis in enumerate("xyz"):
        _scalars(rec, f"{name}/plots/object/{axis}", frame_idx, frames.object[:, j])
    # success is the env's check of the simulated state (the dataset's next.success marks only the last frame)
    _scalars(rec, f"{name}/plots/success", frame_idx, samples["success"][frames.sample])
    valid = np.all(np.isfinite(frames.action), axis=1)
    if valid.any():
        act_idx = _indexes(ft[valid], frames.frame_index[valid])
        for j, action in enumerate(robot.ACTION_NAMES):
            _scalars(rec, f"{name}/plots/action/{action}", act_idx, frames.action[valid, j])
    known = frames.phase >= 0
    if known.any():
        idx = _indexes(ft[known], frames.frame_index[known])
        # The phase log: one line each time a phase is entered (dense runs spend many frames in each).
        entered = known & (np.r_[-2, frames.phase[:-1]] != frames.phase)
        texts = [phase_name(p) for p in frames.phase[entered]]
        rec.send_columns(
            f"{name}/plots/phase",
            indexes=_indexes(ft[entered], frames.frame_index[entered]),
            columns=rr.TextLog.columns(text=texts, level=["INFO"] * len(texts)),
        )
        _style(rec, f"{name}/plots/phase_index", (200, 200, 200), "phase index", steps=True)
        _scalars(rec, f"{name}/plots/phase_index", tick_idx, _phase_per_sample(len(t), frames.sample, frames.phase))
        _scalars(rec, f"{name}/plots/phase_index", idx, frames.phase[known])
        pos, phases = keyframes_reached(run)
        log_keyframes(rec, f"{name}/world/keyframes", pos, phases)


def _phase_per_sample(n: int, frame_samples: np.ndarray, phases: np.ndarray) -> np.ndarray:
    out = np.full(n, float(max(phases[0], 0)))
    for s, p in zip(frame_samples, phases):
        if p >= 0:
            out[s:] = p
    return out


def log_policy_comparison(rec, run: Run) -> None:
    """Predicted keyframes (3D, labelled) and, with an expert reference, the expert's (3D) and the differences."""
    import rerun as rr

    name, frames, expert = run.name, run.frames, run.expert
    scratch = mujoco.MjData(run.scene.model)
    n = int(np.sum(np.all(np.isfinite(frames.action), axis=1)))
    pred = frames.action[:n]
    pred_ee = np.array([run.scene.ee_position(run.qpos, a, scratch) for a in pred]).reshape(-1, 3)
    # Action k commands the phase of the next observation (k + 1).
    reached = [int(p) for p in frames.phase[1 : n + 1]]
    log_keyframes(rec, f"{name}/world/keyframes", pred_ee, reached)
    if expert is None or "actions" not in expert:
        return
    own = expert["actions"]  # the expert's own run from the same start: its keyframes and path in 3D
    own_ee = np.array([run.scene.ee_position(run.qpos, a, scratch) for a in own]).reshape(-1, 3)
    own_phases = [min(k + 1, robot.N_KEYFRAMES - 1) for k in range(len(own))]
    log_keyframes(rec, f"{name}/world/expert_keyframes", own_ee, own_phases, color=EXPERT_COLOR, labelled=False)
    if len(expert["ee_path"]):
        path = rr.LineStrips3D([expert["ee_path"]], colors=[EXPERT_COLOR], radii=[0.002])
        rec.log(f"{name}/world/expert_ee_path", path, static=True)
    # The panels compare each prediction with the expert's label at the state the policy was in (after a
    # recovery or a perturbation the two runs are in different states, and step k of one says nothing of the other).
    ref = expert["labels"] if expert.get("labels") is not None else own
    ref_ee = np.array([_ee_or_nan(run, a, scratch) for a in ref]).reshape(-1, 3)
    m = min(n, len(ref))
    if m == 0:
        return
    idx = _indexes(run.samples["t"][frames.sample[:m]], frames.frame_index[:m])
    for j, action in enumerate(robot.ACTION_NAMES):
        _style(rec, f"{name}/policy/pred/{action}", SERIES_COLORS[j], f"policy {action}", steps=True)
        _style(rec, f"{name}/policy/expert/{action}", SERIES_COLORS[j], f"expert {action}", points=True)
        _scalars(rec, f"{name}/policy/pred/{action}", idx, pred[:m, j])
        _scalars(rec, f"{name}/policy/expert/{action}", idx, ref[:m, j])
    err = np.abs(pred[:m] - ref[:m])
    for j, joint in enumerate(robot.JOINT_NAMES):
        _style(rec, f"{name}/policy/error/joints/{joint}", SERIES_COLORS[j], joint)
        _scalars(rec, f"{name}/policy/error/joints/{joint}", idx, err[:, j])
    _scalars(rec, f"{name}/policy/error/gripper", idx, err[:, robot.N_JOINTS])
    ee_err = np.linalg.norm(pred_ee[:m] - ref_ee[:m], axis=1)
    _scalars(rec, f"{name}/policy/error/ee_pos", idx, ee_err)
    labelled = np.isfinite(ee_err)
    if labelled.any():
        run.info["mean_joint_error_rad"] = float(err[labelled, : robot.N_JOINTS].mean())
        run.info["mean_ee_error_m"] = float(ee_err[labelled].mean())
        run.info["max_ee_error_m"] = float(ee_err[labelled].max())


def _ee_or_nan(run: Run, action: np.ndarray, scratch) -> np.ndarray:
    if not np.all(np.isfinite(action)):
        return np.full(3, np.nan)
    return run.scene.ee_position(run.qpos, action, scratch)


def log_cameras_and_events(rec, run: Run) -> None:
    """The camera images of each frame (``<run>/cameras/<camera>``), on them the keypoints the policy computed
    (``<run>/cameras/<camera>/keypoints``, one colour per keypoint; none on the final observation, which it did not
    act on), and the run's events (``<run>/events``)."""
    import rerun as rr

    t = run.samples["t"][run.frames.sample]
    for cam, images in run.images.items():
        keypoints = run.keypoints.get(cam, [])
        for k, image in enumerate(images[: len(t)]):
            rec.set_time("frame_index", sequence=int(run.frames.frame_index[k]))
            rec.set_time("time", duration=float(t[k]))
            rec.log(f"{run.name}/cameras/{cam}", rr.Image(image))
            if k < len(keypoints):
                rec.log(f"{run.name}/cameras/{cam}/keypoints", keypoint_points(keypoints[k]))
            elif keypoints:  # the final observation, which the policy did not act on: no points carried over
                rec.log(f"{run.name}/cameras/{cam}/keypoints", rr.Points2D(np.zeros((0, 2), np.float32)))
    if run.events:
        ks = np.array([k for k, _, _ in run.events])
        rec.send_columns(
            f"{run.name}/events",
            indexes=_indexes(t[ks], run.frames.frame_index[ks]),
            columns=rr.TextLog.columns(text=[e[2] for e in run.events], level=[e[1] for e in run.events]),
        )
    rec.reset_time()


def _scene_column(run: str, view3d, cameras: list[str], keypoints: list[str]):
    """The 3D view with the camera images in a column beside it (large enough to read the keypoints drawn on
    them), and the event log below."""
    import rerun.blueprint as rrb

    events = rrb.TextLogView(origin=f"{run}/events", name="events: perturbations, failure cause, success")
    if not cameras:
        return rrb.Vertical(view3d, events, row_shares=[4, 1])
    views = [
        rrb.Spatial2DView(
            origin=f"{run}/cameras/{cam}", name=f"camera: {cam} · keypoints" if cam in keypoints else f"camera: {cam}"
        )
        for cam in cameras
    ]
    scene = rrb.Horizontal(view3d, rrb.Vertical(*views), column_shares=[2, 1])
    return rrb.Vertical(scene, events, row_shares=[5, 1])


def make_blueprint(runs: list[tuple[str, bool, list[str]]], keypoints: dict[str, list[str]] | None = None):
    """One tab per run (name, is a policy rollout, cameras): the 3D view framed on the workspace with the camera
    images and the event log beside it, and plots titled with what they show.

    ``keypoints`` (run -> the cameras it has policy keypoints on): where any run has them, the viewer opens on the
    first frame, paused; the final observation, which a policy does not act on, is the one frame without them."""
    import rerun.blueprint as rrb

    keypoints = {run: cams for run, cams in (keypoints or {}).items() if cams}
    tabs = []
    for run, is_policy, cameras in runs:
        phase = rrb.Tabs(
            rrb.TimeSeriesView(
                origin=f"{run}/plots/phase_index",
                name=f"FSM phase (0 {robot.PHASE_NAMES[0]} .. {robot.N_KEYFRAMES - 1} {robot.PHASE_NAMES[-1]})",
            ),
            rrb.TextLogView(origin=f"{run}/plots/phase", name="FSM phase entered (time, name)"),
        )
        plots = [
            rrb.TimeSeriesView(origin=f"{run}/plots/joints", name="joint angles (rad)"),
            rrb.TimeSeriesView(
                name="gripper opening (0 closed, 1 open) · success (0/1)",
                contents=[f"{run}/plots/gripper", f"{run}/plots/success"],
            ),
            rrb.TimeSeriesView(origin=f"{run}/plots/object", name="object position x, y, z (m)"),
        ]
        if is_policy:
            plots += [
                rrb.TimeSeriesView(
                    name="keyframe targets: policy (steps) vs expert (crosses), 7 joints (rad) + gripper",
                    contents=[f"{run}/policy/pred/**", f"{run}/policy/expert/**"],
                ),
                rrb.TimeSeriesView(
                    origin=f"{run}/policy/error/joints", name="policy - expert: joint target error, absolute (rad)"
                ),
                rrb.TimeSeriesView(
                    name="policy - expert: keyframe end-effector distance (m) · gripper command error",
                    contents=[f"{run}/policy/error/ee_pos", f"{run}/policy/error/gripper"],
                ),
            ]
        else:
            plots.append(phase)
        what = "policy (labelled, orange/cyan) vs expert (green)" if is_policy else "replay"
        view3d = rrb.Spatial3DView(
            origin=f"{run}/world",
            name=f"{run}: {what} · end-effector path (yellow) · keyframes",
            background=(28, 32, 38),
            eye_controls=rrb.EyeControls3D(position=EYE_POSITION, look_target=EYE_TARGET, eye_up=(0, 0, 1)),
        )
        left = _scene_column(run, view3d, cameras, keypoints.get(run, []))
        tabs.append(rrb.Horizontal(left, rrb.Vertical(*plots), column_shares=[3, 2], name=run))
    return rrb.Blueprint(
        rrb.Tabs(*tabs),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        # Open on the end of the run (the whole path drawn, the object placed), or on its first frame to show what
        # a policy saw (see above); scrub or press play from there.
        rrb.TimePanel(state="collapsed", play_state="paused" if keypoints else "following"),
    )
