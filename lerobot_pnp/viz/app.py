"""``visualize``: load what was asked for, log it, and show it (viewer, .rrd file and/or screenshot)."""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.outputs import TMP_SUFFIX, OutputFolder, remove_path
from lerobot_pnp.viz.config import COMMAND, VizConfig
from lerobot_pnp.viz.recording import log_cameras_and_events, log_policy_comparison, log_run, make_blueprint
from lerobot_pnp.viz.screenshot import take_screenshot

APPLICATION_ID = "lerobot_pnp"


def _has_display() -> bool:
    if sys.platform != "linux":
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def visualize(cfg: VizConfig) -> dict:
    """Log the requested dataset episodes and/or policy rollouts to Rerun; returns a summary."""
    import rerun as rr

    from lerobot_pnp.viz.rollouts import rollout_config, rollout_with_expert
    from lerobot_pnp.viz.sources import load_episode, open_dataset, replay_config, replay_episode

    if cfg.repo_id is None and cfg.policy_path is None:
        raise ConfigError("nothing to show: give --repo_id (with --root) for dataset episodes and/or --policy.path")
    if cfg.save is None and cfg.screenshot is None and not _has_display():
        raise ConfigError(
            "no display to spawn the Rerun viewer on: pass --save out.rrd (open it with `rerun out.rrd`) "
            "or --screenshot out.png"
        )
    destinations = {f: Path(p).expanduser() for f, p in (("save", cfg.save), ("screenshot", cfg.screenshot)) if p}
    for flag, path in destinations.items():
        check_destination(flag, path)
    # Load and check everything before opening the recording, so bad input fails fast and writes nothing.
    episodes, replay_cfg = [], None
    if cfg.repo_id is not None:
        ds = open_dataset(cfg.repo_id, cfg.root)
        episodes = [load_episode(ds, i) for i in cfg.episode_index]
        replay_cfg = replay_config(ds)
    loaded, policy_cfg = None, None
    if cfg.policy_path is not None:
        from lerobot_pnp.evaluation.checkpoints import check_policy_features, image_inputs, load_policy

        loaded = load_policy(cfg.policy_path, device=cfg.device)
        cams = image_inputs(loaded.policy.config)
        policy_cfg = rollout_config(str(loaded.path), cfg.task_source, cfg.control_mode, cfg.env_changes, cams)
        rendered = {c: (policy_cfg.image_height, policy_cfg.image_width) for c in policy_cfg.cameras}
        check_policy_features(loaded.policy.config, len(policy_cfg.environment_state_names), rendered)  # fits
    seeds = [cfg.seed + i for i in range(cfg.n_episodes)] if loaded is not None else []
    claim_destinations(destinations)  # a file of the user's there is refused before any rollout

    runs = [replay_episode(ep, replay_cfg, cfg.log_hz) for ep in episodes]
    runs += [
        rollout_with_expert(loaded, policy_cfg, seed, cfg.log_hz, cfg.compare_expert, name=f"rollout_{i}")
        for i, seed in enumerate(seeds)
    ]

    with tempfile.TemporaryDirectory(prefix="lerobot_pnp_viz_") as tmp:
        rrd = _recording_file(destinations["save"]) if cfg.save else Path(tmp) / "recording.rrd"
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=None)
        blueprint = make_blueprint(
            [(run.name, run.is_rollout, list(run.images)) for run in runs],
            keypoints={run.name: list(run.keypoints) for run in runs},
        )
        if cfg.save is not None or cfg.screenshot is not None:
            rrd.parent.mkdir(parents=True, exist_ok=True)
            rec.save(str(rrd), default_blueprint=blueprint)
        else:
            rec.spawn(default_blueprint=blueprint)
        title = cfg.repo_id or Path(cfg.policy_path).name
        rec.send_recording_name(f"{title} ({', '.join(run.name for run in runs)})")
        summary: dict = {"recording": str(cfg.save) if cfg.save else "spawned viewer", "runs": []}
        for run in runs:
            run.scene.log_static(rec, run.name, _posed_data(run))
            log_run(rec, run)
            log_cameras_and_events(rec, run)
            if run.is_rollout:
                log_policy_comparison(rec, run)
                run.info["policy"] = str(loaded.path)
            summary["runs"].append({"run": run.name, **run.info})
        rec.flush()
        if cfg.save is not None or cfg.screenshot is not None:
            rec.disconnect()
        if cfg.save is not None:
            rrd = _publish(rrd, destinations["save"])
        if cfg.save is None and cfg.screenshot is not None:
            summary["recording"] = None
        if cfg.screenshot is not None:
            summary["screenshot"] = str(take_screenshot(rrd, cfg.screenshot, cfg.window))
    return summary


def claim_destinations(destinations: dict[str, Path]) -> None:
    """Record each ``--save``/``--screenshot`` file as this command's in its folder's manifest
    (``lerobot_pnp.outputs``) before it is written; a file of that name the command did not write is refused."""
    for flag, path in destinations.items():
        with OutputFolder(path.parent, COMMAND, flag=f"--{flag}") as folder:
            folder.claim(path.name)


def _recording_file(dest: Path) -> Path:
    """Where the recording for ``--save dest`` is written until it is complete: ``dest`` + ``.tmp``."""
    tmp = dest.with_name(dest.name + TMP_SUFFIX)
    remove_path(tmp)  # a leftover of an interrupted run (a link is unlinked, never followed)
    return tmp


def _publish(tmp: Path, dest: Path) -> Path:
    """Move the complete recording ``tmp`` to ``dest`` in one rename, over a file only this command wrote."""
    with OutputFolder(dest.parent, COMMAND, flag="--save") as folder:
        final = folder.claim(dest.name)
        os.replace(tmp, final)
    return final


def check_destination(flag: str, path: Path) -> None:
    """Refuse, in one line, a file ``path`` that cannot be written, before any rollout runs (the recording is
    written only after all of them): a folder, an existing file without write permission, or a place whose
    nearest existing folder is a file, read-only or not writable by this user."""
    if path.is_dir():
        raise ConfigError(f"--{flag} {path} is a folder; give a file path")
    if path.exists() and not os.access(path, os.W_OK):
        raise ConfigError(f"--{flag} {path}: the file exists and cannot be written (read-only or permission denied)")
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ConfigError(f"--{flag} {path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(
            f"--{flag} {path}: cannot write into {parent} (read-only or permission denied); choose another place"
        )


def _posed_data(run):
    """An MjData of the run's model posed at its last state (for the static poses and the target)."""
    import mujoco

    data = mujoco.MjData(run.scene.model)
    data.qpos[:] = run.qpos
    mujoco.mj_kinematics(run.scene.model, data)
    return data
