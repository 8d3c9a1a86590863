"""Stock ``lerobot-train`` on a streaming dataset with ``--num_workers 0``: one line naming the fix (stock_streaming)."""

from __future__ import annotations

import os
import subprocess
import sys
import types
from pathlib import Path

import pytest

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.stock_checkpoints import TRAIN_MODULE
from lerobot_pnp.stock_streaming import install_stream_check

REPO_ID = "local/t_stream"


@pytest.fixture(scope="module")
def tiny_root(tmp_path_factory) -> Path:
    from lerobot_pnp.dataset import GenerateConfig, generate

    root = tmp_path_factory.mktemp("stream") / "data"
    generate(GenerateConfig(repo_id=REPO_ID, root=str(root), num_episodes=2, seed=0, workers=1, progress=False))
    return root


def test_a_stream_lerobot_would_leave_empty_is_refused_in_lerobot_train(tiny_root, monkeypatch):
    """The wrapped ``make_train_eval_datasets`` raises for the stream LeRobot builds with 0 workers (no shard: it
    yields nothing) and returns a stream with a shard unchanged; a map-style dataset is never questioned."""
    from lerobot.datasets.streaming_dataset import StreamingLeRobotDataset

    def lerobot_make(cfg):  # as LeRobot 0.6.1's make_dataset builds the stream: max_num_shards=num_workers
        return StreamingLeRobotDataset(REPO_ID, root=tiny_root, max_num_shards=cfg.num_workers), None

    monkeypatch.setitem(sys.modules, TRAIN_MODULE, types.SimpleNamespace(make_train_eval_datasets=lerobot_make))
    assert install_stream_check() and install_stream_check()  # idempotent: wrapped once
    wrapped = sys.modules[TRAIN_MODULE].make_train_eval_datasets
    assert wrapped.__wrapped__ is lerobot_make
    with pytest.raises(ConfigError, match=r"--num_workers 0 gives an empty stream.*pass --num_workers 1 or more"):
        wrapped(types.SimpleNamespace(num_workers=0))
    stream, _ = wrapped(types.SimpleNamespace(num_workers=1))
    assert len(list(stream)) == stream.num_frames > 0  # every frame of the two episodes once


def test_not_in_lerobot_train_nothing_is_wrapped(monkeypatch):
    monkeypatch.delitem(sys.modules, TRAIN_MODULE, raising=False)
    assert install_stream_check() is False


@pytest.mark.slow
def test_lerobot_train_streaming_with_no_worker_is_one_line(tiny_root, tmp_path):
    exe = Path(sys.executable).parent / "lerobot-train"
    if not exe.exists():
        pytest.skip(f"lerobot-train is not installed next to {sys.executable}")
    cmd = [str(exe), f"--dataset.repo_id={REPO_ID}", f"--dataset.root={tiny_root}", "--dataset.streaming=true"]
    cmd += ["--num_workers=0", "--policy.type=pnp_lstm", "--policy.device=cpu", "--policy.push_to_hub=false"]
    cmd += ["--steps=2", f"--output_dir={tmp_path / 'out'}"]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "HF_HUB_OFFLINE": "1", "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert "Traceback" not in proc.stderr and "StopIteration" not in proc.stderr, proc.stderr[-3000:]
    assert "lerobot-train: error: --dataset.streaming=true with --num_workers 0 gives an empty stream" in proc.stderr
