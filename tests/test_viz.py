"""Tests of the Rerun viewer (lerobot_pnp/viz/) and the policy rollout helper (lerobot_pnp/evaluation/episodes.py).

Recordings are written headless (``save=...rrd``) and read back with Rerun's own reader
(``rerun.experimental.RrdReader``): entity paths, rows per timeline and logged values are checked against
the dataset they came from and against the simulator. The datasets (expert episodes, one of them in a
non-default task) and a tiny untrained ``pnp_lstm`` checkpoint are made here with LeRobot's writer.
"""

from __future__ import annotations

import logging
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, DatasetError, PnPError, PolicyError
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.sim.recorded_files import RECORDED_FILE, write_recorded

REPO_ID = "test/viz_keyframe"
SEEDS = (0, 1)
# A task other than the paper's: another object region and place target.
CUSTOM_TASK = {
    "object_low": (0.5, 0.2),
    "object_high": (0.6, 0.3),
    "place_low": (0.65, -0.1),
    "place_high": (0.65, -0.1),
}
PLACE = CUSTOM_TASK["place_low"]
ARM_BODIES = (
    "left_upper_shoulder",
    "left_lower_shoulder",
    "left_upper_elbow",
    "left_lower_elbow",
    "left_upper_forearm",
    "left_lower_forearm",
    "left_wrist",
    "left_hand",
    "left_gripper_base",
    "l_finger",
    "r_finger",
)


# ---------------------------------------------------------------------------------------------- fixtures
def _write_dataset(root: Path, config: BaxterPnPEnvConfig, seeds, record_task: bool = True) -> dict:
    """Expert episodes in ``config``'s task as a LeRobotDataset v3, with the task recorded as generate does."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_pnp.dataset import dataset_features
    from lerobot_pnp.sim.expert import run_expert_episode

    ds = LeRobotDataset.create(
        REPO_ID, fps=1, features=dataset_features(), root=root, robot_type="baxter", use_videos=False
    )
    env = make_env(config, render_mode=None)
    episodes = []
    for seed in seeds:
        ep = run_expert_episode(env, seed)
        for k in range(ep.num_frames):
            last = k == ep.num_frames - 1
            ds.add_frame(
                {
                    "observation.state": ep.states[k],
                    "observation.environment_state": ep.env_states[k],
                    "action": ep.actions[k],
                    "next.done": np.array([last]),
                    "next.success": np.array([last and ep.success]),
                    "phase.index": np.array([ep.phases[k]], dtype=np.int64),
                    "phase.subtask": np.array([ep.phases[k] // robot.N_PHASES_PER_SUBTASK], dtype=np.int64),
                    "episode.seed": np.array([seed], dtype=np.int64),
                    "task": robot.TASK,
                }
            )
        ds.save_episode()
        episodes.append(ep)
    ds.finalize()
    env.close()
    if record_task:
        write_recorded(config, root)
    return {"root": root, "episodes": episodes, "stats": ds.meta.stats}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Two keyframe expert episodes in the paper's task."""
    return _write_dataset(tmp_path_factory.mktemp("viz") / "dataset", BaxterPnPEnvConfig(preset="paper"), SEEDS)


@pytest.fixture(scope="module")
def custom_dataset(tmp_path_factory):
    """One expert episode in a non-default task (object region, place target), recorded in the dataset."""
    config = BaxterPnPEnvConfig(preset="paper").with_changes(**CUSTOM_TASK)
    return _write_dataset(tmp_path_factory.mktemp("viz") / "custom", config, (5,))


def _save_policy(path: Path, stats: dict, action_dim: int = 8, with_env: bool = True, weights: bool = True) -> Path:
    from lerobot.configs import FeatureType, PolicyFeature

    from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy, make_pnp_lstm_pre_post_processors

    inputs = {"observation.state": PolicyFeature(FeatureType.STATE, (8,))}
    if with_env:
        inputs["observation.environment_state"] = PolicyFeature(FeatureType.ENV, (3,))
    cfg = PnpLstmConfig(
        hidden_size=8,
        input_features=inputs,
        output_features={"action": PolicyFeature(FeatureType.ACTION, (action_dim,))},
    )
    if weights:
        PnpLstmPolicy(cfg).save_pretrained(path)
        pre, post = make_pnp_lstm_pre_post_processors(cfg, stats)
        pre.save_pretrained(path)
        post.save_pretrained(path)
    else:
        cfg.save_pretrained(path)
    return path


@pytest.fixture(scope="module")
def policy_dir(dataset, tmp_path_factory):
    """A tiny untrained pnp_lstm checkpoint (LeRobot pretrained_model layout, no recorded task)."""
    import torch

    torch.manual_seed(0)
    return _save_policy(tmp_path_factory.mktemp("viz") / "pretrained_model", dataset["stats"])


def _read(path: Path):
    from rerun.experimental import RrdReader

    reader = RrdReader(path)
    assert len(reader.recordings()) == 1
    store = reader.store()
    return set(store.schema().entity_paths()), store.stream().to_chunks()


def _rows(chunks, entity: str, timeline: str | None = None, static: bool = False) -> dict:
    """All rows of ``entity`` as columns, from the chunks that have ``timeline`` (or are static)."""
    out: dict[str, list] = {}
    for chunk in chunks:
        if chunk.entity_path != entity or chunk.is_static != static:
            continue
        if timeline is not None and timeline not in chunk.timeline_names:
            continue
        for key, values in chunk.to_record_batch().to_pydict().items():
            out.setdefault(key, []).extend(values)
    if timeline is not None and timeline in out:
        n = len(out[timeline])
        out = {k: v for k, v in out.items() if len(v) == n}  # columns every selected chunk has
        order = np.argsort(np.asarray(out[timeline]))
        out = {k: [v[i] for i in order] for k, v in out.items()}
    return out


def _seconds(values) -> np.ndarray:
    return np.array([v.total_seconds() if hasattr(v, "total_seconds") else v / 1e9 for v in values])


def _translations(rows) -> np.ndarray:
    return np.array([np.ravel(t) for t in rows["Transform3D:translation"]])


# ---------------------------------------------------------------------------------------------- dataset episodes
def test_dataset_episodes_recording(dataset, tmp_path):
    from lerobot_pnp.viz import VizConfig, visualize
    from lerobot_pnp.viz.keyframe_markers import LABEL_SPACING, MERGE_DISTANCE

    out = tmp_path / "episodes.rrd"
    summary = visualize(VizConfig(repo_id=REPO_ID, root=str(dataset["root"]), episode_index=[0, 1], save=str(out)))
    assert out.is_file()
    assert [r["run"] for r in summary["runs"]] == ["episode_0", "episode_1"]
    assert all(r["events"] == [f"frame {robot.N_KEYFRAMES - 1}: success"] for r in summary["runs"])  # no perturbation
    for run, ep in zip(summary["runs"], dataset["episodes"]):
        assert run["mode"] == "replay" and run["frames"] == ep.num_frames and run["success"]
        assert run["replay_max_state_error"] < 1e-5  # the seed + actions re-simulate the episode exactly

    paths, chunks = _read(out)
    for ep_i, ep in enumerate(dataset["episodes"]):
        run, n = f"/episode_{ep_i}", ep.num_frames
        expected = (
            [f"{run}/world/robot/{b}" for b in ARM_BODIES]
            + [
                f"{run}/world/robot/left_hand/hand",
                f"{run}/world/robot/l_finger_tip/l_pad",
                f"{run}/world/cube",
                f"{run}/world/cube/cube",
                f"{run}/world/target",
                f"{run}/world/scene/table/table_top",
                f"{run}/world/ee",
                f"{run}/world/ee_path",
                f"{run}/world/keyframes",
                f"{run}/plots/gripper",
                f"{run}/plots/phase",
                f"{run}/plots/phase_index",
                f"{run}/plots/success",
            ]
            + [f"{run}/plots/joints/{j}" for j in robot.JOINT_NAMES]
            + [f"{run}/plots/object/{a}" for a in "xyz"]
        )
        missing = [p for p in expected if p not in paths]
        assert not missing, missing

        # Frames: one row per dataset frame on `frame_index`, values equal to the dataset's.
        for j, name in enumerate(robot.JOINT_NAMES):
            rows = _rows(chunks, f"{run}/plots/joints/{name}", "frame_index")
            assert rows["frame_index"] == list(range(n))
            np.testing.assert_allclose(np.ravel(rows["Scalars:scalars"]), ep.states[:, j], atol=1e-6)
        grip = _rows(chunks, f"{run}/plots/gripper", "frame_index")
        np.testing.assert_allclose(np.ravel(grip["Scalars:scalars"]), ep.states[:, 7], atol=1e-6)
        act = _rows(chunks, f"{run}/plots/action/left_s0", "frame_index")
        np.testing.assert_allclose(np.ravel(act["Scalars:scalars"]), ep.actions[:, 0], atol=1e-6)
        phase = _rows(chunks, f"{run}/plots/phase", "frame_index")
        entered = [k for k in range(n) if k == 0 or ep.phases[k] != ep.phases[k - 1]]
        assert phase["frame_index"] == entered
        assert [t[0] for t in phase["TextLog:text"]] == [robot.PHASE_NAMES[ep.phases[k]] for k in entered]
        success = np.ravel(_rows(chunks, f"{run}/plots/success", "frame_index")["Scalars:scalars"])
        assert success[-1] == 1 and success[0] == 0  # the env's check: placed at the end, not at the start

        # The 3D replay (simulated, not copied from the dataset) puts the object where the dataset saw it.
        cube = _translations(_rows(chunks, f"{run}/world/cube", "frame_index"))
        np.testing.assert_allclose(cube, ep.env_states, atol=1e-4)

        # Continuous motion: many samples on `time` between the frames, no jumps between samples.
        all_rows = _rows(chunks, f"{run}/plots/joints/left_s1", "time")
        t = _seconds(all_rows["time"])
        assert len(t) > 8 * n and np.all(np.diff(t) >= 0)
        q = np.ravel(all_rows["Scalars:scalars"])
        assert np.max(np.abs(np.diff(q))) < 0.15  # rad between two 40 ms samples: continuous, not jumps
        tf = _rows(chunks, f"{run}/world/robot/left_wrist", "time")
        assert len(tf["time"]) == len(t) and "Transform3D:translation" in tf

        # Keyframe markers: every phase named exactly once, no two markers on top of each other, and the
        # drawn labels of nearby markers at different heights (stacked, not written over each other).
        kf = _rows(chunks, f"{run}/world/keyframes", static=True)
        labels, pos = kf["Points3D:labels"][0], np.array(kf["Points3D:positions"][0])
        named = [name.split(" ")[-1] for label in labels for name in label.split(" · ")]
        assert sorted(named) == sorted(p.split("/")[1] for p in robot.PHASE_NAMES)
        gaps = np.linalg.norm(pos[:, None] - pos[None], axis=-1) + np.eye(len(pos))
        assert gaps.min() >= MERGE_DISTANCE
        assert len(labels) < robot.N_KEYFRAMES  # coincident phases (grasp, close) share a label
        shown = _rows(chunks, f"{run}/world/keyframes/labels", static=True)
        assert shown["Points3D:labels"][0] == labels and shown["Points3D:show_labels"] == [[True]]
        anchors = np.array(shown["Points3D:positions"][0])
        for i in range(len(pos)):
            for j in range(i):
                if np.linalg.norm(pos[i, :2] - pos[j, :2]) < LABEL_SPACING:
                    assert abs((anchors[i, 2] - pos[i, 2]) - (anchors[j, 2] - pos[j, 2])) > 0.01


def test_merged_labels_group_coincident_keyframes():
    from lerobot_pnp.viz.keyframe_markers import PICK_COLOR, PLACE_COLOR, merged_labels

    pos = np.array([[0.5, 0.3, 0.2], [0.6, 0.3, 0.0], [0.6, 0.3, -0.1], [0.6, 0.3, -0.1], [0.6, 0.3, 0.0]])
    out, labels, colors = merged_labels(pos, [0, 1, 2, 3, 4])
    assert labels == ["start", "approach · retract", "grasp · close"] and colors == [PICK_COLOR] * 3
    np.testing.assert_allclose(out, pos[[0, 1, 2]])
    _, labels, colors = merged_labels(pos[[0, 1]], [4, 5])
    assert labels == ["retract", "start"] and colors == [PICK_COLOR, PLACE_COLOR]
    _, labels, _ = merged_labels(pos[[1, 4]], [4, 5])
    assert labels == ["retract · place start"]


def test_replay_uses_the_recorded_task(custom_dataset, tmp_path, caplog):
    """A dataset made in another task (object region, place target) is replayed in that task, no flag given."""
    from lerobot_pnp.viz import VizConfig, visualize

    root = custom_dataset["root"]
    out = tmp_path / "custom.rrd"
    summary = visualize(VizConfig(repo_id=REPO_ID, root=str(root), save=str(out)))
    run = summary["runs"][0]
    assert run["place_target"] == list(PLACE)
    assert run["replay_max_state_error"] < 1e-5
    _, chunks = _read(out)
    target = np.ravel(_rows(chunks, "/episode_0/world/target", static=True)["Cylinders3D:centers"][0])
    np.testing.assert_allclose(target[:2], PLACE, atol=1e-6)
    ep = custom_dataset["episodes"][0]
    cube = _translations(_rows(chunks, "/episode_0/world/cube", "frame_index"))
    np.testing.assert_allclose(cube, ep.env_states, atol=1e-4)
    assert np.all(cube[0, :2] >= CUSTOM_TASK["object_low"]) and np.all(cube[0, :2] <= CUSTOM_TASK["object_high"])
    np.testing.assert_allclose(cube[-1, :2], PLACE, atol=0.02)  # placed on the custom target

    # The same data without its recorded task (an older dataset) falls back to the paper's task, with a
    # warning, and the replay no longer reproduces it: the recorded task is what made the replay right.
    old = tmp_path / "old"
    shutil.copytree(root, old)
    (old / RECORDED_FILE).unlink()
    with caplog.at_level(logging.WARNING, logger="lerobot_pnp.viz.sources"):
        summary = visualize(VizConfig(repo_id=REPO_ID, root=str(old), save=str(tmp_path / "old.rrd")))
    assert "records no task" in caplog.text
    assert summary["runs"][0]["place_target"] != list(PLACE)
    assert summary["runs"][0]["replay_max_state_error"] > 1e-2


def test_kinematic_replay_without_seed(dataset):
    """An episode without ``episode.seed`` is posed frame by frame from its recorded states."""
    from lerobot_pnp.viz.sources import EpisodeData, replay_episode

    ep = dataset["episodes"][0]
    n = ep.num_frames
    data = EpisodeData(
        index=0,
        fps=1,
        frame_index=np.arange(n),
        timestamp=np.arange(n, dtype=np.float64),
        state=ep.states,
        object=ep.env_states,
        action=ep.actions,
        phase=ep.phases,
        success=np.zeros(n),
        seed=None,
    )
    run = replay_episode(data, BaxterPnPEnvConfig(preset="paper"), hz=25)
    assert run.info["mode"].startswith("kinematic")
    rows = run.frames.sample
    np.testing.assert_allclose(run.samples["object"][rows], ep.env_states, atol=1e-9)
    np.testing.assert_allclose(run.samples["q"][rows], ep.states[:, :7], atol=1e-9)
    np.testing.assert_allclose(run.samples["gripper"][rows], ep.states[:, 7], atol=1e-6)
    np.testing.assert_allclose(run.samples["t"][rows], np.arange(n))


# ---------------------------------------------------------------------------------------------- policy rollouts
def test_policy_rollout_recording(policy_dir, tmp_path):
    from lerobot_pnp.sim.expert import run_expert_episode
    from lerobot_pnp.viz import VizConfig, visualize

    out = tmp_path / "rollout.rrd"
    summary = visualize(VizConfig(policy_path=str(policy_dir), n_episodes=2, seed=3, save=str(out)))
    runs = summary["runs"]
    assert [r["run"] for r in runs] == ["rollout_0", "rollout_1"]
    assert [r["seed"] for r in runs] == [3, 4]
    assert all(r["steps"] == robot.N_KEYFRAMES and r["expert_success"] for r in runs)

    paths, chunks = _read(out)
    run = "/rollout_0"
    expected = [
        f"{run}/world/robot/left_wrist",
        f"{run}/world/cube",
        f"{run}/world/keyframes",
        f"{run}/world/expert_keyframes",
        f"{run}/world/expert_ee_path",
        f"{run}/policy/error/ee_pos",
        f"{run}/policy/error/gripper",
        f"{run}/policy/pred/left_s0",
        f"{run}/policy/expert/left_s0",
    ] + [f"{run}/policy/error/joints/{j}" for j in robot.JOINT_NAMES]
    missing = [p for p in expected if p not in paths]
    assert not missing, missing
    # 10 policy steps + the final observation on frame_index; 10 predicted keyframes compared.
    joints = _rows(chunks, f"{run}/plots/joints/left_s0", "frame_index")
    assert joints["frame_index"] == list(range(11))
    pred = _rows(chunks, f"{run}/policy/pred/left_s0", "frame_index")
    ref = _rows(chunks, f"{run}/policy/expert/left_s0", "frame_index")
    err = _rows(chunks, f"{run}/policy/error/joints/left_s0", "frame_index")
    assert pred["frame_index"] == list(range(10))
    pred_v, ref_v = np.ravel(pred["Scalars:scalars"]), np.ravel(ref["Scalars:scalars"])
    np.testing.assert_allclose(np.ravel(err["Scalars:scalars"]), np.abs(pred_v - ref_v), atol=1e-6)
    assert np.abs(pred_v - ref_v).max() > 1e-3  # an untrained policy does not reproduce the expert
    ee = np.ravel(_rows(chunks, f"{run}/policy/error/ee_pos", "frame_index")["Scalars:scalars"])
    assert ee.shape == (10,) and np.isclose(ee.mean(), runs[0]["mean_ee_error_m"])
    # The expert panels hold the expert's label at each state the policy visited: DAgger's labelled rollout
    # (another code path, the same teacher) gives the same labels. From the common start they agree with the
    # expert's own run; after the untrained policy's first step the states, and so the labels, differ.
    from lerobot_pnp.dagger.rollouts import labelled_rollout
    from lerobot_pnp.evaluation.checkpoints import load_policy

    dagger = labelled_rollout(
        make_env(BaxterPnPEnvConfig(preset="paper"), render_mode=None), load_policy(policy_dir), 3
    )
    np.testing.assert_allclose(ref_v, dagger.actions[:10, 0], atol=1e-6)
    expert = run_expert_episode(make_env(BaxterPnPEnvConfig(preset="paper"), render_mode=None), 3)
    assert np.isclose(ref_v[0], expert.actions[0, 0], atol=1e-6)
    assert not np.allclose(ref_v, expert.actions[:10, 0], atol=1e-3)
    kf = _rows(chunks, f"{run}/world/expert_keyframes", static=True)
    assert "grasp · close" in kf["Points3D:labels"][0]  # shown on hover only: the predicted ones are drawn
    assert f"{run}/world/keyframes/labels" in paths and f"{run}/world/expert_keyframes/labels" not in paths


def test_rollout_task_from_task_source(policy_dir, custom_dataset, tmp_path):
    """Rollouts run in a recorded task: the checkpoint's by default (none here: the paper's), or task_source."""
    from lerobot_pnp.viz import VizConfig, visualize

    cfg = VizConfig(policy_path=str(policy_dir), task_source=str(custom_dataset["root"]), compare_expert=False)
    cfg.save = str(tmp_path / "r.rrd")
    run = visualize(cfg)["runs"][0]
    assert run["place_target"] == list(PLACE)
    assert "expert_success" not in run

    from lerobot_pnp.viz.rollouts import rollout_config

    recorded = rollout_config(str(policy_dir), str(custom_dataset["root"]), None)
    assert recorded.place_low == PLACE and recorded.control_mode == "keyframe"
    dense = rollout_config(str(policy_dir), str(custom_dataset["root"]), "dense")
    assert dense.control_mode == "dense" and dense.fps == 20 and dense.object_low == CUSTOM_TASK["object_low"]
    assert rollout_config(str(policy_dir), None, None).place_low == (0.60, -0.05)  # nothing recorded: the paper's
    dropped = rollout_config(
        str(policy_dir), str(custom_dataset["root"]), None, {"drop_prob": 1.0, "keyframe_budget": 20}
    )
    assert dropped.drop_prob == 1.0 and dropped.episode_length == 20 and dropped.place_low == PLACE
    with pytest.raises(ConfigError, match="unknown fields"):
        VizConfig(policy_path=str(policy_dir), env_changes={"drop_probability": 1.0})


def test_run_episode_is_deterministic(policy_dir, capsys):
    """evaluation.episodes.run_episode follows LeRobot's eval pipeline; the same seed gives the same episode.
    Loading prints nothing (LeRobot's per-load "Loading weights" line would flood a study's log)."""
    from lerobot_pnp.evaluation.checkpoints import load_policy
    from lerobot_pnp.evaluation.closed_loop import run_episode

    capsys.readouterr()
    loaded = load_policy(policy_dir)
    assert capsys.readouterr().out == ""
    assert loaded.type == "pnp_lstm"
    a = run_episode(make_env(None, render_mode=None), loaded, seed=5)
    b = run_episode(make_env(None, render_mode=None), loaded, seed=5)
    assert a.actions.shape == (10, 8) and a.states.shape == (11, 8)
    np.testing.assert_array_equal(a.actions, b.actions)


# ---------------------------------------------------------------------------------------------- bad input
def test_bad_inputs(dataset, policy_dir, tmp_path):
    from lerobot_pnp.evaluation.checkpoints import IncompatiblePolicyError, PolicyLoadError
    from lerobot_pnp.viz import DatasetNotFoundError, EpisodeNotFoundError, VizConfig, visualize

    save = str(tmp_path / "x.rrd")
    cases = [
        (DatasetNotFoundError, "no LeRobot dataset", VizConfig(repo_id=REPO_ID, root=str(tmp_path / "nope"))),
        (
            EpisodeNotFoundError,
            "no episode 7 .*2 episodes: 0..1",
            VizConfig(repo_id=REPO_ID, root=str(dataset["root"]), episode_index=[0, 7]),
        ),
        (PolicyLoadError, "does not exist", VizConfig(policy_path=str(tmp_path / "no_ckpt"))),
        (ConfigError, "nothing to show", VizConfig()),
    ]
    (tmp_path / "empty").mkdir()
    cases.append((PolicyLoadError, "config.json", VizConfig(policy_path=str(tmp_path / "empty"))))
    wrong_action = _save_policy(tmp_path / "a7", dataset["stats"], action_dim=7, weights=False)
    cases.append((IncompatiblePolicyError, r"action has shape \(7,\)", VizConfig(policy_path=str(wrong_action))))
    no_env = _save_policy(tmp_path / "noenv", dataset["stats"], with_env=False, weights=False)
    missing = "missing input feature 'observation.environment_state'"
    cases.append((IncompatiblePolicyError, missing, VizConfig(policy_path=str(no_env))))
    for err_type, match, cfg in cases:
        cfg.save = save
        with pytest.raises(err_type, match=match) as info:
            visualize(cfg)
        assert "\n" not in str(info.value)  # one line
    with pytest.raises(ConfigError, match="disagree"):
        VizConfig(policy_path="a", policy={"path": "b"})
    with pytest.raises(ConfigError, match=r"\.rrd"):
        VizConfig(repo_id=REPO_ID, save="out.txt")
    with pytest.raises(ConfigError, match=r"\.png"):
        VizConfig(repo_id=REPO_ID, screenshot="out.jpg")
    with pytest.raises(ConfigError, match="window_size"):
        VizConfig(repo_id=REPO_ID, window_size="big")
    assert not Path(save).exists()  # bad input fails before anything is written
    assert issubclass(DatasetNotFoundError, DatasetError) and issubclass(EpisodeNotFoundError, DatasetError)
    assert issubclass(PolicyLoadError, PolicyError) and issubclass(IncompatiblePolicyError, PolicyError)


# ---------------------------------------------------------------------------------------------- CLI
def test_cli_viz_saves_recording(dataset, policy_dir, tmp_path, capsys):
    from lerobot_pnp.cli import main

    out = tmp_path / "cli.rrd"
    argv = ["viz", "--repo_id", REPO_ID, "--root", str(dataset["root"]), "--episode_index", "1"]
    rc = main([*argv, "--policy.path", str(policy_dir), "--save", str(out)])
    assert rc == 0 and out.is_file()
    printed = capsys.readouterr().out
    assert '"episode_1"' in printed and '"rollout_0"' in printed
    rc = main(
        ["viz", "--repo_id", REPO_ID, "--root", str(dataset["root"]), "--episode_index", "[5]", "--save", str(out)]
    )
    err = capsys.readouterr().err
    assert rc != 0 and "no episode 5" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_save_and_screenshot_replace_only_files_viz_wrote(dataset, tmp_path, capsys):
    """``--save``/``--screenshot`` write through the output folder's owner: viz's own recording is replaced (one
    rename, no temporary file left), a user's file of that name is refused in one line and kept."""
    from lerobot_pnp.cli import main

    argv = ["viz", "--repo_id", REPO_ID, "--root", str(dataset["root"]), "--episode_index", "0"]
    out = tmp_path / "rec.rrd"
    assert main([*argv, "--save", str(out)]) == 0 and main([*argv, "--save", str(out)]) == 0
    assert out.is_file() and not (tmp_path / "rec.rrd.tmp").exists()
    for flag, name in (("--save", "mine.rrd"), ("--screenshot", "mine.png")):
        (tmp_path / name).write_text("my own file")
        capsys.readouterr()
        assert main([*argv, flag, str(tmp_path / name)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and name in err and flag in err, err
        assert (tmp_path / name).read_text() == "my own file"


def test_normalize_cli_args():
    import draccus

    from lerobot_pnp.cli import normalize_args
    from lerobot_pnp.viz import VizConfig

    def normalize(args):
        return normalize_args(VizConfig, args)

    args = normalize(["--repo-id", "a/b", "--episode-index", "0", "2", "--policy.path=/p", "--save", "x.rrd"])
    assert args == ["--repo_id", "a/b", "--episode_index=[0,2]", "--policy.path=/p", "--save", "x.rrd"]
    assert normalize(["--episode-index", "3"]) == ["--episode_index=[3]"]
    for argv in (["--episode-index", "1", "4"], ["--episode_index", "[1, 4]"], ["--episode_index=[1,4]"]):
        assert draccus.parse(VizConfig, args=normalize(argv)).episode_index == [1, 4]
    assert VizConfig(episode_index="0, 2").episode_index == [0, 2]
    assert VizConfig(episode_index=3).episode_index == [3]
    assert VizConfig(policy={"path": "/p"}).policy_path == "/p"


# ---------------------------------------------------------------------------------------------- the real viewer
def test_screenshot_shows_the_scene(dataset, tmp_path):
    """The headless Rerun viewer renders the recording; the 3D view shows the arm (framed, not a speck)."""
    from PIL import Image

    from lerobot_pnp.viz import ViewerUnavailableError, VizConfig, visualize
    from lerobot_pnp.viz.scene import PART_COLORS

    shot = tmp_path / "shot.png"
    cfg = VizConfig(repo_id=REPO_ID, root=str(dataset["root"]), screenshot=str(shot), window_size="960x600")
    try:
        summary = visualize(cfg)
    except ViewerUnavailableError as err:  # no `rerun` binary, or no graphics adapter for wgpu on this machine
        pytest.skip(str(err))
    assert summary["screenshot"] == str(shot.resolve()) and summary["recording"] is None
    img = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    h, w, _ = img.shape
    assert w >= 960 and h >= 600 and img.std() > 20  # not blank
    view3d = img[h // 10 : 9 * h // 10, : w // 2]  # the 3D view fills the left ~60 % of the window
    arm = [PART_COLORS[p] for p in ("lower_shoulder", "upper_elbow", "lower_forearm", "wrist")]
    near = np.zeros(view3d.shape[:2], bool)
    for color in arm:
        near |= np.abs(view3d - np.array(color)).max(axis=-1) < 60
    assert near.mean() > 0.01, f"the arm covers only {near.mean():.2%} of the 3D view"


# ---------------------------------------------------------------------------------------------- stock viewer
@pytest.mark.slow
def test_stock_lerobot_dataset_viz(dataset, tmp_path):
    """LeRobot's own `lerobot-dataset-viz` reads our dataset and writes a recording."""
    exe = shutil.which("lerobot-dataset-viz", path=str(Path(sys.executable).parent)) or shutil.which(
        "lerobot-dataset-viz"
    )
    assert exe, "lerobot-dataset-viz not installed"
    out_dir = tmp_path / "stock"
    env = {**os.environ, "HF_HUB_OFFLINE": "1"}
    args = ["--repo-id", REPO_ID, "--root", str(dataset["root"]), "--episode-index", "0", "--save", "1"]
    args += ["--output-dir", str(out_dir), "--num-workers", "0"]
    proc = subprocess.run([exe, *args], capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    files = list(out_dir.glob("*.rrd"))
    assert len(files) == 1
    paths, chunks = _read(files[0])
    assert any(p.startswith("/observation.state") or p.startswith("/state") for p in paths), sorted(paths)
    rows = _rows(chunks, "/action", "frame_index")
    assert rows["frame_index"] == list(range(dataset["episodes"][0].num_frames))


def test_errors_are_pnp_errors():
    from lerobot_pnp.viz import ScreenshotError, ViewerUnavailableError

    assert issubclass(ViewerUnavailableError, PnPError) and issubclass(ScreenshotError, PnPError)


# ---------------------------------------------------------------------------------------------- image policies, events
def _image_policy(path: Path, stats: dict, size=(32, 32)) -> Path:
    """A tiny untrained stock ACT checkpoint that reads the front camera and the joints (no environment_state)."""
    import torch
    from lerobot.configs import FeatureType, PolicyFeature
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.act.modeling_act import ACTPolicy
    from lerobot.policies.factory import make_pre_post_processors

    torch.manual_seed(0)
    image = "observation.images.front"
    cfg = ACTConfig(
        input_features={
            "observation.state": PolicyFeature(FeatureType.STATE, (8,)),
            image: PolicyFeature(FeatureType.VISUAL, (3, *size)),
        },
        output_features={"action": PolicyFeature(FeatureType.ACTION, (8,))},
        pretrained_backbone_weights=None, chunk_size=2, n_action_steps=1, dim_model=16, n_heads=2,
        dim_feedforward=32, n_encoder_layers=1, use_vae=False, device="cpu", push_to_hub=False,
    )  # fmt: skip
    stats = {**stats, image: {"mean": np.full((3, 1, 1), 0.5), "std": np.full((3, 1, 1), 0.2)}}
    ACTPolicy(cfg).save_pretrained(path)
    pre, post = make_pre_post_processors(cfg, dataset_stats=stats)
    pre.save_pretrained(path)
    post.save_pretrained(path)
    return path


def test_image_policy_rollout_shows_its_camera(dataset, tmp_path):
    """An image checkpoint is accepted (its camera is rendered at its size) and the camera panel is logged."""
    from lerobot_pnp.viz import VizConfig, visualize

    ckpt = _image_policy(tmp_path / "act_img", dataset["stats"])
    out = tmp_path / "img.rrd"
    run = visualize(VizConfig(policy_path=str(ckpt), compare_expert=False, save=str(out)))["runs"][0]
    assert run["steps"] == robot.N_KEYFRAMES
    paths, chunks = _read(out)
    assert "/rollout_0/cameras/front" in paths
    images = _rows(chunks, "/rollout_0/cameras/front", "frame_index")
    assert images["frame_index"] == list(range(robot.N_KEYFRAMES + 1))  # one image per observation
    fmt = images["Image:format"][0][0]
    assert (fmt["height"], fmt["width"]) == (32, 32)

    from lerobot_pnp.evaluation.checkpoints import IncompatiblePolicyError

    wrong = VizConfig(policy_path=str(ckpt), env_changes={"image_height": 48}, save=str(tmp_path / "w.rrd"))
    with pytest.raises(IncompatiblePolicyError, match="is 32x32; the env renders it at"):
        visualize(wrong)


def test_events_and_camera_changes(policy_dir, tmp_path):
    """Perturbations and the failure cause are logged as events; env_changes can add a camera panel."""
    from lerobot_pnp.viz import VizConfig, visualize
    from lerobot_pnp.viz.config import UNSEEN_SEED

    out = tmp_path / "ev.rrd"
    changes = {"nudge_max": 0.03, "cameras": ["overhead"], "image_height": 24, "image_width": 32}
    run = visualize(VizConfig(policy_path=str(policy_dir), env_changes=changes, save=str(out)))["runs"][0]
    assert run["seed"] == UNSEEN_SEED  # rollouts default to an episode no dataset was generated with
    assert "frame 1: perturbation: nudge" in run["events"]  # nudged after step 1 (nudge_at_step)
    assert run["success"] or any(e.startswith(f"frame {run['steps']}: failure: ") for e in run["events"])
    paths, chunks = _read(out)
    events = _rows(chunks, "/rollout_0/events", "frame_index")
    assert events["frame_index"][0] == 1 and "nudge" in str(events["TextLog:text"][0])
    assert "/rollout_0/cameras/overhead" in paths


def test_phase_labels_name_the_phase_or_its_index():
    from lerobot_pnp.viz.sampling import phase_name

    assert phase_name(np.int64(0)) == robot.PHASE_NAMES[0]
    assert phase_name(len(robot.PHASE_NAMES)) == f"phase {len(robot.PHASE_NAMES)}"
    assert phase_name(-1) == "phase -1"
