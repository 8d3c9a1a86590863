"""Tests of the Rerun viewer (lerobot_pnp/viz.py) and the policy rollout helper (lerobot_pnp/rollout.py).

Recordings are written headless (``save=...rrd``) and read back with Rerun's own reader
(``rerun.experimental.RrdReader``): entity paths, row counts per timeline and logged values are checked
against the dataset they came from. The dataset (2 expert episodes) and a tiny untrained ``pnp_lstm``
checkpoint are made here, so the module does not depend on the dataset generator.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, PnPError

REPO_ID = "test/viz_keyframe"
SEEDS = (0, 1)
FEATURES = {
    "observation.state": {"dtype": "float32", "shape": (8,), "names": list(robot.STATE_NAMES)},
    "observation.environment_state": {"dtype": "float32", "shape": (3,), "names": list(robot.OBJECT_NAMES)},
    "action": {"dtype": "float32", "shape": (8,), "names": list(robot.ACTION_NAMES)},
    "next.done": {"dtype": "bool", "shape": (1,), "names": None},
    "next.success": {"dtype": "bool", "shape": (1,), "names": None},
    "phase.index": {"dtype": "int64", "shape": (1,), "names": None},
    "phase.subtask": {"dtype": "int64", "shape": (1,), "names": None},
    "episode.seed": {"dtype": "int64", "shape": (1,), "names": None},
}
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
@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Two keyframe expert episodes as a LeRobotDataset v3 (the dataset module's feature layout)."""
    import gymnasium as gym
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_pnp.expert import run_expert_episode

    root = tmp_path_factory.mktemp("viz") / "dataset"
    ds = LeRobotDataset.create(REPO_ID, fps=1, features=FEATURES, root=root, robot_type="baxter", use_videos=False)
    env = gym.make("lerobot_pnp/BaxterPnP-v0")
    episodes = []
    for seed in SEEDS:
        ep = run_expert_episode(env, seed)
        n = ep.num_frames
        for k in range(n):
            last = k == n - 1
            ds.add_frame(
                {
                    "observation.state": ep.states[k],
                    "observation.environment_state": ep.object_positions[k],
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
    return {"root": root, "episodes": episodes, "stats": ds.meta.stats}


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
    """A tiny untrained pnp_lstm checkpoint (LeRobot pretrained_model layout)."""
    import torch

    torch.manual_seed(0)
    return _save_policy(tmp_path_factory.mktemp("viz") / "pretrained_model", dataset["stats"])


def _read(path: Path):
    from rerun.experimental import RrdReader

    reader = RrdReader(path)
    assert len(reader.recordings()) == 1
    store = reader.store()
    chunks = store.stream().to_chunks()
    return set(store.schema().entity_paths()), chunks


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


# ---------------------------------------------------------------------------------------------- dataset episodes
def test_dataset_episodes_recording(dataset, tmp_path):
    from lerobot_pnp.viz import VizConfig, visualize

    out = tmp_path / "episodes.rrd"
    summary = visualize(VizConfig(repo_id=REPO_ID, root=str(dataset["root"]), episode_index=[0, 1], save=str(out)))
    assert out.is_file()
    assert [r["run"] for r in summary["runs"]] == ["episode_0", "episode_1"]
    for run in summary["runs"]:
        assert run["mode"] == "replay" and run["frames"] == 10 and run["success"]
        assert run["replay_max_state_error"] < 1e-5  # the seed + actions re-simulate the episode exactly

    paths, chunks = _read(out)
    for ep_i, ep in enumerate(dataset["episodes"]):
        run = f"/episode_{ep_i}"
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
            assert rows["frame_index"] == list(range(10))
            np.testing.assert_allclose(np.ravel(rows["Scalars:scalars"]), ep.states[:, j], atol=1e-6)
        grip = _rows(chunks, f"{run}/plots/gripper", "frame_index")
        np.testing.assert_allclose(np.ravel(grip["Scalars:scalars"]), ep.states[:, 7], atol=1e-6)
        act = _rows(chunks, f"{run}/plots/action/left_s0", "frame_index")
        np.testing.assert_allclose(np.ravel(act["Scalars:scalars"]), ep.actions[:, 0], atol=1e-6)
        obj = _rows(chunks, f"{run}/plots/object/x", "frame_index")
        np.testing.assert_allclose(np.ravel(obj["Scalars:scalars"]), ep.object_positions[:, 0], atol=1e-6)
        phase = _rows(chunks, f"{run}/plots/phase", "frame_index")
        assert [t[0] for t in phase["TextLog:text"]] == list(robot.PHASE_NAMES)

        # Continuous motion: many samples on `time` between the 10 frames, no jumps between samples.
        all_rows = _rows(chunks, f"{run}/plots/joints/left_s1", "time")
        t = _seconds(all_rows["time"])
        assert len(t) > 80 and np.all(np.diff(t) >= 0)
        q = np.ravel(all_rows["Scalars:scalars"])
        assert np.max(np.abs(np.diff(q))) < 0.15  # rad between two 40 ms samples: continuous, not 10 jumps
        tf = _rows(chunks, f"{run}/world/robot/left_wrist", "time")
        assert len(tf["time"]) == len(t) and "Transform3D:translation" in tf

        # Keyframe markers: the 10 FSM states, labelled, at the EE positions of the frames.
        kf = _rows(chunks, f"{run}/world/keyframes", static=True)
        assert kf["Points3D:labels"][0] == list(robot.PHASE_NAMES)
        assert len(kf["Points3D:positions"][0]) == 10


# ---------------------------------------------------------------------------------------------- policy rollouts
def test_policy_rollout_recording(policy_dir, tmp_path):
    from lerobot_pnp.viz import VizConfig, visualize

    out = tmp_path / "rollout.rrd"
    summary = visualize(VizConfig(policy_path=str(policy_dir), n_rollouts=2, seed=3, save=str(out)))
    runs = summary["runs"]
    assert [r["run"] for r in runs] == ["rollout_0", "rollout_1"]
    assert [r["seed"] for r in runs] == [3, 4]
    assert all(r["steps"] == 10 and r["expert_success"] for r in runs)
    assert all(np.isfinite(r["mean_ee_error_m"]) and r["mean_ee_error_m"] >= 0 for r in runs)

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
    np.testing.assert_allclose(
        np.ravel(err["Scalars:scalars"]),
        np.abs(np.ravel(pred["Scalars:scalars"]) - np.ravel(ref["Scalars:scalars"])),
        atol=1e-6,
    )
    ee = np.ravel(_rows(chunks, f"{run}/policy/error/ee_pos", "frame_index")["Scalars:scalars"])
    assert ee.shape == (10,) and np.isclose(ee.mean(), runs[0]["mean_ee_error_m"])
    # The expert's keyframes are what the FSM expert commands from the same seed.
    from lerobot_pnp.expert import run_expert_episode
    from lerobot_pnp.viz import make_env

    expert = run_expert_episode(make_env({"control_mode": "keyframe", "fps": 1}), 3)
    np.testing.assert_allclose(np.ravel(ref["Scalars:scalars"]), expert.actions[:, 0], atol=1e-6)
    kf = _rows(chunks, f"{run}/world/expert_keyframes", static=True)
    assert kf["Points3D:labels"][0][1] == "expert pick/grasp"


def test_run_policy_episode_matches_manual_loop(policy_dir):
    """rollout.run_policy_episode follows LeRobot's eval pipeline; the same seed gives the same episode."""
    from lerobot_pnp.rollout import load_policy, run_policy_episode
    from lerobot_pnp.viz import make_env

    loaded = load_policy(policy_dir)
    assert loaded.type == "pnp_lstm"
    a = run_policy_episode(make_env({"control_mode": "keyframe", "fps": 1}), loaded, seed=5)
    b = run_policy_episode(make_env({"control_mode": "keyframe", "fps": 1}), loaded, seed=5)
    assert a.actions.shape == (10, 8) and a.states.shape == (11, 8)
    np.testing.assert_array_equal(a.actions, b.actions)


# ---------------------------------------------------------------------------------------------- bad input
def test_bad_inputs(dataset, policy_dir, tmp_path):
    from lerobot_pnp.rollout import IncompatiblePolicyError, PolicyLoadError
    from lerobot_pnp.viz import DatasetNotFoundError, EpisodeNotFoundError, VizConfig, visualize

    save = str(tmp_path / "x.rrd")
    with pytest.raises(DatasetNotFoundError, match="no LeRobot dataset"):
        visualize(VizConfig(repo_id=REPO_ID, root=str(tmp_path / "nope"), save=save))
    with pytest.raises(EpisodeNotFoundError, match="no episode 7 .*2 episodes: 0..1"):
        visualize(VizConfig(repo_id=REPO_ID, root=str(dataset["root"]), episode_index=[0, 7], save=save))
    with pytest.raises(PolicyLoadError, match="does not exist"):
        visualize(VizConfig(policy_path=str(tmp_path / "no_ckpt"), save=save))
    (tmp_path / "empty").mkdir()
    with pytest.raises(PolicyLoadError, match="config.json"):
        visualize(VizConfig(policy_path=str(tmp_path / "empty"), save=save))
    wrong_action = _save_policy(tmp_path / "a7", dataset["stats"], action_dim=7, weights=False)
    with pytest.raises(IncompatiblePolicyError, match=r"action has shape \(7,\)"):
        visualize(VizConfig(policy_path=str(wrong_action), save=save))
    no_env = _save_policy(tmp_path / "noenv", dataset["stats"], with_env=False, weights=False)
    with pytest.raises(IncompatiblePolicyError, match="missing input feature 'observation.environment_state'"):
        visualize(VizConfig(policy_path=str(no_env), save=save))
    with pytest.raises(ConfigError, match="nothing to show"):
        visualize(VizConfig(save=save))
    with pytest.raises(ConfigError, match="disagree"):
        VizConfig(policy_path="a", policy={"path": "b"})
    with pytest.raises(ConfigError, match=r"\.rrd"):
        VizConfig(repo_id=REPO_ID, save="out.txt")
    assert not Path(save).exists()  # bad input fails before anything is written
    for err in (DatasetNotFoundError, EpisodeNotFoundError, PolicyLoadError, IncompatiblePolicyError):
        assert issubclass(err, PnPError) and issubclass(err, ValueError)


# ---------------------------------------------------------------------------------------------- CLI
def test_cli_viz_saves_recording(dataset, policy_dir, tmp_path, capsys):
    from lerobot_pnp.cli import main

    out = tmp_path / "cli.rrd"
    rc = main(
        [
            "viz",
            "--repo_id",
            REPO_ID,
            "--root",
            str(dataset["root"]),
            "--episode_index",
            "1",
            "--policy.path",
            str(policy_dir),
            "--save",
            str(out),
        ]
    )
    assert rc == 0 and out.is_file()
    printed = capsys.readouterr().out
    assert '"episode_1"' in printed and '"rollout_0"' in printed
    rc = main(
        ["viz", "--repo_id", REPO_ID, "--root", str(dataset["root"]), "--episode_index", "[5]", "--save", str(out)]
    )
    assert rc == 1
    assert "no episode 5" in capsys.readouterr().err


def test_normalize_cli_args():
    from lerobot_pnp.cli import normalize_args
    from lerobot_pnp.viz import VizConfig

    def normalize_cli_args(args):
        return normalize_args(VizConfig, args)

    args = normalize_cli_args(["--repo-id", "a/b", "--episode-index", "0", "2", "--policy.path=/p", "--save", "x.rrd"])
    assert args == ["--repo_id", "a/b", "--episode_index=[0,2]", "--policy.path=/p", "--save", "x.rrd"]
    assert normalize_cli_args(["--episode-index", "3"]) == ["--episode_index=[3]"]
    assert normalize_cli_args(["--episode_index", "[1, 4]"]) == ["--episode_index", "[1, 4]"]
    import draccus

    for argv in (["--episode-index", "1", "4"], ["--episode_index", "[1, 4]"], ["--episode_index=[1,4]"]):
        assert draccus.parse(VizConfig, args=normalize_cli_args(argv)).episode_index == [1, 4]
    assert VizConfig(episode_index="0, 2").episode_index == [0, 2]
    assert VizConfig(episode_index=3).episode_index == [3]
    assert VizConfig(policy={"path": "/p"}).policy_path == "/p"


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
    proc = subprocess.run(
        [
            exe,
            "--repo-id",
            REPO_ID,
            "--root",
            str(dataset["root"]),
            "--episode-index",
            "0",
            "--save",
            "1",
            "--output-dir",
            str(out_dir),
            "--num-workers",
            "0",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    files = list(out_dir.glob("*.rrd"))
    assert len(files) == 1
    paths, chunks = _read(files[0])
    assert any(p.startswith("/observation.state") or p.startswith("/state") for p in paths), sorted(paths)
    rows = _rows(chunks, "/action", "frame_index")
    assert rows["frame_index"] == list(range(10))


def test_render_picture(tmp_path):
    """The README picture: an offscreen MuJoCo render of the viewer's scene with the keyframe markers."""
    from lerobot_pnp.viz import render_picture

    try:
        info = render_picture(tmp_path / "viewer.png", size=(120, 160))
    except Exception as err:  # no OpenGL backend on this machine
        if "gl" in str(err).lower() or "egl" in str(err).lower():
            pytest.skip(f"no offscreen OpenGL: {err}")
        raise
    from PIL import Image

    img = np.asarray(Image.open(info["path"]))
    assert img.shape[:2] == (120, 160) and img.std() > 5 and info["bytes"] < 300_000
