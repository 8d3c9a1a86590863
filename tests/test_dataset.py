"""Dataset writer: LeRobot v3.0 round trip, exact re-simulation, split, determinism, crash safety, push."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import zygote

from lerobot_pnp import robot
from lerobot_pnp.dataset import (
    GenerateConfig,
    data_hash,
    generate,
    load_split,
    validate_dataset,
    verify_dataset,
)
from lerobot_pnp.errors import ConfigError, DatasetError

REPO = "test/pnp_kf"


def _cfg(root, **kw) -> GenerateConfig:
    base = {"repo_id": REPO, "root": str(root), "num_episodes": 10, "seed": 0, "workers": 1, "progress": False}
    base.update(kw)
    return GenerateConfig(**base)


PNP = str(Path(sys.executable).parent / "lerobot-pnp")  # the installed console script (PYTHONPATH: this tree)


def _snapshot(root: Path) -> dict:
    """Every file's content hash and mtime, to prove a folder was not touched."""
    out = {}
    for p in sorted(Path(root).rglob("*")):
        if p.is_file():
            out[str(p.relative_to(root))] = (hashlib.sha256(p.read_bytes()).hexdigest(), p.stat().st_mtime_ns)
    return out


def _cli_env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("HF_")}
    env.update({"OMP_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}, **extra)
    return env


def _cli(*args, env=None, timeout=120) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "lerobot_pnp.cli", *args],
        capture_output=True,
        text=True,
        env=env or _cli_env(HF_HUB_OFFLINE="1"),
        timeout=timeout,
    )


@pytest.fixture(scope="module")
def kf(tmp_path_factory):
    """10 keyframe episodes in 3 shards (3+3+4) merged with LeRobot's aggregate_datasets."""
    root = tmp_path_factory.mktemp("ds") / "kf"
    summary = generate(_cfg(root, tasks=3))
    return root, summary


# ---------------------------------------------------------------------------------------------- content
def test_keyframe_dataset_loads_with_stock_loader(kf):
    root, summary = kf
    assert summary["episodes"] == 10 and summary["frames"] == 10 * robot.N_KEYFRAMES and summary["shards"] == 3
    code = (
        "import json; from lerobot.datasets.lerobot_dataset import LeRobotDataset\n"
        f"ds = LeRobotDataset({REPO!r}, root={str(root)!r}, video_backend='pyav')\n"
        "item = ds[9]\n"
        "print(json.dumps({'n': len(ds), 'eps': ds.num_episodes, 'fps': ds.fps, 'keys': sorted(item),"
        " 'done': bool(item['next.done']), 'phase': int(item['phase.index']), 'task': item['task'],"
        " 'names': ds.features['observation.state']['names'], 'splits': ds.meta.info.splits}))\n"
    )
    res = zygote.run([sys.executable, "-c", code], timeout=120)  # a process of its own (tests/zygote.py)
    assert res.returncode == 0, res.stderr
    assert "libtorchcodec" not in res.stderr  # video_backend="pyav": no torchcodec traceback
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["n"] == 100 and out["eps"] == 10 and out["fps"] == 1
    assert out["done"] and out["phase"] == 9 and out["task"] == robot.TASK
    assert out["names"] == list(robot.STATE_NAMES)
    for key in (
        "observation.state",
        "observation.environment_state",
        "action",
        "next.done",
        "next.success",
        "phase.index",
        "phase.subtask",
        "episode.seed",
    ):
        assert key in out["keys"]
    assert not any(k.startswith("observation.") and k.split(".")[1] in ("phase", "seed") for k in out["keys"])
    assert out["splits"] == {"train": "0:8", "test": "8:10"}


def test_keyframe_episodes_reproduce_the_expert_exactly(kf):
    import gymnasium as gym
    import pyarrow.parquet as pq

    from lerobot_pnp.sim.expert import run_expert_episode

    root, _ = kf
    table = pq.read_table(sorted((root / "data").rglob("*.parquet"))).sort_by("index").to_pydict()
    ep_index = np.array(table["episode_index"])
    env = gym.make("lerobot_pnp/BaxterPnP-v0")  # a fresh env: nothing carried over from the writer
    try:
        for e in (0, 5, 9):
            rows = np.flatnonzero(ep_index == e)
            assert len(rows) == robot.N_KEYFRAMES
            seeds = {table["episode.seed"][i] for i in rows}
            assert len(seeds) == 1
            ep = run_expert_episode(env, seeds.pop())
            np.testing.assert_array_equal(
                np.array([table["observation.state"][i] for i in rows], np.float32), ep.states
            )
            np.testing.assert_array_equal(np.array([table["action"][i] for i in rows], np.float32), ep.actions)
            np.testing.assert_array_equal(
                np.array([table["observation.environment_state"][i] for i in rows], np.float32), ep.env_states
            )
            np.testing.assert_array_equal([table["phase.index"][i] for i in rows], np.arange(robot.N_KEYFRAMES))
            np.testing.assert_array_equal([table["phase.subtask"][i] for i in rows], np.arange(10) // 5)
            assert [table["next.done"][i] for i in rows] == [False] * 9 + [True]
            # keyframe k's action is the commanded keyframe k+1 (the last one holds)
            np.testing.assert_array_equal(ep.actions[:-1], ep.keyframes[1:])
    finally:
        env.close()


def test_split_is_80_20_disjoint_and_stats_verified(kf):
    root, _ = kf
    split = load_split(root)
    assert split == {"train": list(range(8)), "test": [8, 9]}
    assert not set(split["train"]) & set(split["test"])
    info = verify_dataset(root)  # stats.json recomputed from the data, distinct seeds
    assert info["total_episodes"] == 10
    record = json.loads((root / "meta" / "pnp_generate.json").read_text())
    assert record["generation"]["num_episodes"] == 10 and record["generation"]["seed"] == 0
    assert "env" not in record and "control_mode" not in json.dumps(record)  # the env config lives in one file
    env = json.loads((root / "meta" / "baxter_pnp_env.json").read_text())
    assert env["type"] == "baxter_pnp" and env["control_mode"] == "keyframe" and env["place_low"] == [0.6, -0.05]
    assert not (root / ".pnp_work").exists()


# The `paper` task's content, pinned: 100 episodes from seed 7 (every feature added to the env, the expert, the
# writer or the dataset pipeline since must leave it byte-identical: a feature that is off draws no number).
PAPER_20_SEED_7 = "590b595b139659fb973fdd48b5e80d389ef4f1136b179e9d705d984c53b5b8ae"  # the first 20 of 100, pinned


def test_paper_dataset_content_is_pinned(tmp_path):
    root = tmp_path / "paper"
    generate(
        GenerateConfig(repo_id="local/paper_pin", root=str(root), num_episodes=20, seed=7, workers=1, progress=False)
    )
    assert data_hash(root) == PAPER_20_SEED_7


def test_same_hash_whatever_the_tasks_and_workers(kf, tmp_path):
    root, _ = kf  # 3 tasks, in this process
    one = generate(_cfg(tmp_path / "t1", tasks=1))
    assert one["shards"] == 1 and data_hash(tmp_path / "t1") == data_hash(root)


@pytest.mark.slow
def test_deterministic_across_worker_counts(kf, tmp_path):
    root, _ = kf
    summary = generate(_cfg(tmp_path / "w2", workers=2, tasks=4))  # datatrove's pool: two spawned workers
    assert summary["workers"] == 2 and summary["shards"] == 4
    assert data_hash(tmp_path / "w2") == data_hash(root)


def test_a_small_generation_starts_no_worker_pool():
    """Each shard beyond the first costs a spawned worker, which imports LeRobot and torch before it simulates
    anything: shards of less than half their size run in this process instead, larger ones on every core."""
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    def tasks(n: int, **env) -> int:
        return _cfg("/nowhere", num_episodes=n, env=BaxterPnPEnvConfig(**env)).auto_tasks(workers=2)

    assert [tasks(n) for n in (3, 10, 99, 100, 150, 250)] == [1, 1, 1, 2, 2, 3]
    assert [tasks(n, control_mode="dense", fps=20) for n in (9, 19, 20, 40)] == [1, 1, 2, 2]
    assert [tasks(n, control_mode="dense", cameras=["front"]) for n in (1, 23, 24, 100)] == [1, 1, 2, 4]


def test_a_large_local_generation_has_a_bounded_number_of_shards():
    """The merge rewrites the growing merged video for every shard it appends: locally the auto shard count stops
    at ``MAX_LOCAL_SHARDS`` and the shards grow instead; on SLURM (parallel tasks) it does not."""
    from lerobot_pnp.dataset.generation import MAX_LOCAL_SHARDS
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    cams = BaxterPnPEnvConfig(cameras=["front", "wrist"])
    assert _cfg("/nowhere", num_episodes=3600, env=cams).auto_tasks(workers=2) == MAX_LOCAL_SHARDS
    assert _cfg("/nowhere", num_episodes=1200, env=cams).auto_tasks(workers=2) == 48
    assert _cfg("/nowhere", num_episodes=100_000).auto_tasks(workers=2) == MAX_LOCAL_SHARDS
    assert _cfg("/nowhere", num_episodes=100_000, executor="slurm").auto_tasks(workers=2) == 100


# ---------------------------------------------------------------------------------------------- existing roots
def test_existing_root_is_an_error_and_untouched(kf, capsys):
    from lerobot_pnp import cli

    root, _ = kf
    before = _snapshot(root)
    with pytest.raises(DatasetError, match="already exists.*--resume.*--overwrite"):
        generate(_cfg(root, tasks=3))
    assert cli.main(["generate", f"--repo_id={REPO}", f"--root={root}", "--num_episodes=10", "--progress=false"]) == 2
    assert "already exists" in capsys.readouterr().err
    # --resume on a finished dataset: verified, reported, untouched; different settings are refused
    assert generate(_cfg(root, resume=True))["status"] == "already complete"
    with pytest.raises(ConfigError, match="num_episodes"):
        generate(_cfg(root, num_episodes=11, resume=True))
    assert _snapshot(root) == before


def test_overwrite_replaces_and_refuses_foreign_folders(tmp_path):
    root = tmp_path / "ow"
    generate(_cfg(root, num_episodes=3))
    summary = generate(_cfg(root, num_episodes=4, seed=100, overwrite=True))
    assert summary["episodes"] == 4 and validate_dataset(root)["total_episodes"] == 4
    foreign = tmp_path / "home"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me")
    with pytest.raises(DatasetError, match="refusing to --overwrite"):
        generate(_cfg(foreign, overwrite=True))
    assert (foreign / "notes.txt").read_text() == "keep me"


def test_corrupt_dataset_is_detected(kf, tmp_path):
    root, _ = kf
    broken = tmp_path / "broken"
    shutil.copytree(root, broken)
    data = sorted((broken / "data").rglob("*.parquet"))[0]
    data.write_bytes(data.read_bytes()[: data.stat().st_size // 2])
    with pytest.raises(DatasetError, match="corrupt or truncated"):
        validate_dataset(broken)
    with pytest.raises(DatasetError, match="corrupt or truncated"):
        generate(_cfg(broken, resume=True))
    (broken / "meta" / "info.json").unlink()
    with pytest.raises(DatasetError, match="meta/info.json missing"):
        validate_dataset(broken)
    (broken / "meta" / "info.json").write_text("{not json")
    with pytest.raises(DatasetError, match="meta/info.json is corrupt"):
        load_split(broken)


# ---------------------------------------------------------------------------------------------- crash safety
def _children(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except FileNotFoundError:
        return []


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.slow
def test_kill_9_then_resume(tmp_path, capsys):
    from lerobot_pnp import cli

    root = tmp_path / "crash"
    n = 12  # 4 tasks of 3 episodes: 2 finished, others being written when it is killed
    args = [f"--repo_id={REPO}", f"--root={root}", f"--num_episodes={n}", "--tasks=4", "--progress=false"]
    # a process of its own (forked from a warm interpreter, tests/zygote.py), killed below
    proc = zygote.start([sys.executable, "-m", "lerobot_pnp.cli", "generate", *args, "--workers=2"])
    shards = root / ".pnp_work" / "shards"
    completions = root / ".pnp_work" / "logs" / "completions"
    deadline = time.time() + 90
    workers = []
    # kill once datatrove has marked 2 tasks complete (a finished shard file alone may not be marked yet, and
    # an unmarked task is redone on resume) while others are being written
    while time.time() < deadline:
        workers = workers or [c for c in _children(proc.pid) if _alive(c)]
        done = list(completions.glob("*")) if completions.exists() else []
        if len(done) >= 2 and list(shards.glob("*.tmp")):
            break
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    workers = [c for c in _children(proc.pid) if c not in workers] + workers
    assert workers  # datatrove's pool workers (spawned) and its manager process
    (root / "notes.txt").write_text("keep me")  # an unrelated file in the root survives the resume
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate()
    # The orphaned workers die with their parent (PR_SET_PDEATHSIG) without finishing their shard, so they
    # cannot race the resume below on the same shard paths.
    for w in workers:
        for _ in range(200):
            if not _alive(w):
                break
            time.sleep(0.05)
    assert not [w for w in workers if _alive(w) and "python" in Path(f"/proc/{w}/cmdline").read_text()]

    with pytest.raises(DatasetError, match="interrupted generation"):
        validate_dataset(root)
    before = _snapshot(root)
    assert cli.main(["generate", *args]) == 2  # no --resume: error, nothing touched
    assert "interrupted generation" in capsys.readouterr().err
    assert _snapshot(root) == before

    summary = generate(_cfg(root, num_episodes=n, resume=True))
    assert summary["status"] == "resumed" and 6 <= summary["episodes_reused"] < n
    assert (root / "notes.txt").read_text() == "keep me"
    info = verify_dataset(root)  # exactly n distinct seeds, stats recomputed from the data
    assert info["total_episodes"] == n and info["total_frames"] == n * robot.N_KEYFRAMES
    clean = generate(_cfg(tmp_path / "clean", num_episodes=n, tasks=1))
    assert clean["episodes"] == n
    assert data_hash(root) == data_hash(tmp_path / "clean")  # none lost, none duplicated, same content


# ---------------------------------------------------------------------------------------------- push
def test_push_without_token_or_network_fails_fast_and_touches_nothing(kf, tmp_path, monkeypatch, capsys):
    """The installed CLI refuses a push without a token in one line; without a network (a dead name server
    included) or with HF_HUB_OFFLINE it fails within its connect timeout. None of them touches the folder."""
    import socket

    from huggingface_hub import constants

    from lerobot_pnp import cli

    root, _ = kf
    before = _snapshot(root)
    home = tmp_path / "hf_home"
    res = _cli("push", f"--repo_id={REPO}", f"--root={root}", env=_cli_env(HF_HOME=str(home)))
    assert res.returncode == 2 and "no Hugging Face token" in res.stderr, res.stderr

    push = ["push", f"--repo_id={REPO}", f"--root={root}", "--connect_timeout_s=1"]
    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", False)
    monkeypatch.setenv("HF_TOKEN", "hf_not_a_real_token")
    lookups = []

    def dead_name_server(host, *args, **kwargs):
        lookups.append(host)
        time.sleep(30)  # a resolver retrying an unreachable name server
        raise socket.gaierror(socket.EAI_AGAIN, "Temporary failure in name resolution")

    monkeypatch.setattr(socket, "getaddrinfo", dead_name_server)
    t0 = time.monotonic()
    assert cli.main(push) == 2
    assert lookups and time.monotonic() - t0 < 1 + 5, "the failure waited for the resolver, not the timeout"
    err = capsys.readouterr().err
    assert "cannot push: the Hub at" in err and "unreachable" in err and len(err.strip().splitlines()) == 1, err

    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", True)
    assert cli.main(push) == 2
    assert "HF_HUB_OFFLINE" in capsys.readouterr().err
    assert _snapshot(root) == before


def test_push_uploads_the_dataset_and_not_the_local_bookkeeping(kf, tmp_path, monkeypatch):
    """The files a push sends (the Hub's API recorded here, not called): the dataset's meta/ and data/, not the
    output folder's manifest, which would make a downloaded copy look like this command's own output."""
    import huggingface_hub
    from huggingface_hub import constants
    from huggingface_hub.utils import filter_repo_objects

    from lerobot_pnp import cli
    from lerobot_pnp.dataset import hub

    root, _ = kf
    (root / "stage.json").write_text("{}")  # a study's record beside the dataset
    sent: list[str] = []

    def upload_folder(self, folder_path, allow_patterns=None, ignore_patterns=None, **kwargs):
        files = [str(p.relative_to(folder_path)) for p in Path(folder_path).rglob("*") if p.is_file()]
        sent.extend(filter_repo_objects(files, allow_patterns=allow_patterns, ignore_patterns=ignore_patterns))

    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", False)
    monkeypatch.setenv("HF_TOKEN", "hf_not_a_real_token")
    monkeypatch.setattr(hub, "_connect", lambda *a: None)
    monkeypatch.setattr(huggingface_hub.HfApi, "upload_folder", upload_folder)
    for name in ("create_repo", "create_tag", "delete_tag", "create_branch", "list_repo_refs"):
        monkeypatch.setattr(huggingface_hub.HfApi, name, lambda self, *a, **k: SimpleNamespace(tags=[], branches=[]))
    monkeypatch.setattr(huggingface_hub.RepoCard, "push_to_hub", lambda self, *a, **k: None)
    try:
        assert cli.main(["push", f"--repo_id={REPO}", f"--root={root}"]) == 0
    finally:
        (root / "stage.json").unlink()
    assert "meta/info.json" in sent and any(f.startswith("data/") for f in sent), sent
    assert ".pnp_manifest.json" not in sent and "stage.json" not in sent, sent


# ---------------------------------------------------------------------------------------------- dense
def test_dense_small(tmp_path):
    import gymnasium as gym
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_pnp.sim.expert import run_expert_episode

    root = tmp_path / "dense"
    summary = generate(_cfg(root, repo_id="test/pnp_dense", num_episodes=2, env={"control_mode": "dense", "fps": 20}))
    ds = LeRobotDataset("test/pnp_dense", root=root, video_backend="pyav")
    assert ds.fps == 20 and ds.num_episodes == 2
    env = gym.make("lerobot_pnp/BaxterPnP-v0", control_mode="dense")
    lengths = [run_expert_episode(env, s).num_frames for s in (0, 1)]
    env.close()
    assert [int(x) for x in ds.meta.episodes["length"]] == lengths
    assert summary["frames"] == sum(lengths) and 100 < lengths[0] < 300
    assert load_split(root) == {"train": [0], "test": [1]}


@pytest.mark.slow
def test_dense_with_camera_video(tmp_path):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = tmp_path / "cam"
    generate(
        _cfg(
            root,
            repo_id="test/pnp_cam",
            num_episodes=1,
            env={"control_mode": "dense", "cameras": ["front"], "image_height": 32, "image_width": 32},
        )
    )
    ds = LeRobotDataset("test/pnp_cam", root=root, video_backend="pyav")
    assert ds.meta.video_keys == ["observation.images.front"]
    frame = ds[len(ds) - 1]["observation.images.front"]
    assert tuple(frame.shape) == (3, 32, 32) and float(frame.std()) > 0


def test_expert_failures_are_retried_with_disjoint_seeds_and_reported(tmp_path, monkeypatch):
    import lerobot_pnp.sim.expert as expert
    from lerobot_pnp.errors import ExpertFailure, UnreachableError

    real = expert.run_expert_episode

    def flaky(env, seed, config=None):
        if seed == 1:
            raise ExpertFailure(f"seed {seed}: expert failed: grasp_missed", "grasp_missed")
        if seed == 3:
            raise UnreachableError("no IK solution")
        return real(env, seed, config)

    monkeypatch.setattr(expert, "run_expert_episode", flaky)
    root = tmp_path / "flaky"
    summary = generate(_cfg(root, num_episodes=4))
    assert summary["expert_failures"] == 2
    assert summary["failure_causes"] == {"grasp_missed": 1, "unreachable": 1}
    record = json.loads((root / "meta" / "pnp_generate.json").read_text())
    assert [f["seed"] for f in record["failures"]] == [1, 3]
    verify_dataset(root, expected_seeds=[0, 1 + 4, 2, 3 + 4])  # slot i, retry r -> seed + i + N * r


def test_config_validation():
    with pytest.raises(ConfigError):
        GenerateConfig(env={"control_mode": "video"})
    with pytest.raises(ConfigError):
        GenerateConfig(env={"cameras": ["nope"]})
    with pytest.raises(ConfigError):
        GenerateConfig(resume=True, overwrite=True)
    with pytest.raises(ConfigError, match="executor"):
        GenerateConfig(executor="ray")
    with pytest.raises(ConfigError, match="tasks"):
        GenerateConfig(num_episodes=3, tasks=4)
    assert GenerateConfig().env.fps == 1 and GenerateConfig().num_episodes == 1400
    from lerobot_pnp.cli import normalize_args

    assert normalize_args(
        GenerateConfig, ["--repo-id", "a/b", "--resume", "--num-episodes=3", "--overwrite", "false"]
    ) == ["--repo_id", "a/b", "--resume=true", "--num_episodes=3", "--overwrite", "false"]


def test_full_preset_dataset_has_goal_yaw_and_recoveries(tmp_path):
    """The `full` task: 7-d environment state (object, yaw features, goal), recovery episodes kept, preset recorded."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_pnp.integration.recorded_task import read_recorded
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    root = tmp_path / "full"
    generate(_cfg(root, num_episodes=8, env=BaxterPnPEnvConfig(preset="full")))
    ds = LeRobotDataset(REPO, root=root, video_backend="pyav")
    names = ds.meta.features["observation.environment_state"]["names"]
    assert names == ["object_x", "object_y", "object_z", "object_yaw_sin4", "object_yaw_cos4", "goal_x", "goal_y"]
    lengths = [int(n) for n in ds.meta.episodes["length"]]
    assert max(lengths) > robot.N_KEYFRAMES  # at least one episode recovered from a perturbation
    assert read_recorded(root)["preset"] == "full"
    phases = np.asarray(ds.hf_dataset["phase.index"]).reshape(-1)
    assert phases.min() == 0 and phases.max() == robot.N_KEYFRAMES - 1


def test_saves_without_image_embedding_write_the_same_table(tmp_path):
    """The writer skips LeRobot's per-frame image embedding only where there is no image column, and the
    parquet it writes holds what LeRobot's own save_episode writes: the same table, the same features."""
    import lerobot.datasets.dataset_writer as writer
    import pyarrow.parquet as pq
    from keyframe_synth import features, make_keyframe_dataset

    from lerobot_pnp.dataset.schema import saves_without_image_embedding

    original = writer.embed_images
    make_keyframe_dataset(tmp_path / "stock", n_episodes=3, episode_len=40)
    with saves_without_image_embedding(features()):
        assert writer.embed_images is not original  # no image feature: the map is skipped
        make_keyframe_dataset(tmp_path / "lean", n_episodes=3, episode_len=40)
    assert writer.embed_images is original
    files = sorted(p.relative_to(tmp_path / "stock") for p in (tmp_path / "stock").rglob("*.parquet"))
    assert files and files == sorted(p.relative_to(tmp_path / "lean") for p in (tmp_path / "lean").rglob("*.parquet"))
    for rel in files:
        stock, lean = pq.read_table(tmp_path / "stock" / rel), pq.read_table(tmp_path / "lean" / rel)
        assert stock.num_rows > 0 and stock.equals(lean), rel
        metas = [pq.read_schema(tmp_path / d / rel).metadata or {} for d in ("stock", "lean")]
        hf = [json.loads(m[b"huggingface"])["info"] if b"huggingface" in m else None for m in metas]
        assert hf[0] == hf[1], rel  # the features LeRobot and datasets read back
        assert hf[0] is not None or "data" not in rel.parts, rel
    image = {**features(), "observation.images.front": {"dtype": "image", "shape": (8, 8, 3), "names": None}}
    with saves_without_image_embedding(image):
        assert writer.embed_images is original  # an image column keeps LeRobot's embedding


@pytest.mark.parametrize(("field", "value"), [("partition", "cpu\n#SBATCH --x=1"), ("job_name", "a b"), ("qos", "q'")])
def test_generate_refuses_a_slurm_name_sbatch_would_not_read_as_one(field, value):
    from lerobot_pnp.dataset.executors import SlurmOptions

    with pytest.raises(ConfigError, match=f"slurm.{field} may hold only") as err:
        SlurmOptions(**{field: value})
    assert "\n" not in str(err.value)
