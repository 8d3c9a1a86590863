"""Hooks inside stock ``lerobot-train`` (stock_train): the recovering policy's per-frame phase labels, and a
stream LeRobot would leave empty (``--num_workers 0``) as one line naming the fix."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import pytest
import zygote

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.integration.stock_checkpoints import TRAIN_MODULE
from lerobot_pnp.integration.stock_train import FACTORY_MODULE, install_stock_train_hooks

REPO_ID = "local/t_stream"


@pytest.fixture(scope="module")
def tiny_root(tmp_path_factory) -> Path:
    from lerobot_pnp.dataset import GenerateConfig, generate

    root = tmp_path_factory.mktemp("stream") / "data"
    generate(GenerateConfig(repo_id=REPO_ID, root=str(root), num_episodes=2, seed=0, workers=1, progress=False))
    return root


@pytest.fixture
def in_lerobot_train(monkeypatch):
    """This process as ``lerobot-train``: its module holds LeRobot's real functions, and every function the
    hooks wrap is restored after the test."""
    import importlib

    from lerobot.datasets.factory import make_train_eval_datasets
    from lerobot.policies import make_pre_post_processors

    train = types.SimpleNamespace(
        make_train_eval_datasets=make_train_eval_datasets, make_pre_post_processors=make_pre_post_processors
    )
    monkeypatch.setitem(sys.modules, TRAIN_MODULE, train)
    factory = importlib.import_module(FACTORY_MODULE)
    monkeypatch.setattr(factory, "resolve_delta_timestamps", factory.resolve_delta_timestamps)
    assert install_stock_train_hooks() and install_stock_train_hooks()  # idempotent: wrapped once
    assert train.make_train_eval_datasets.__wrapped__ is make_train_eval_datasets
    return train


def _train_cfg(root: Path, streaming: bool, num_workers: int = 1, mode: str = "recovering"):
    from lerobot.configs.default import DatasetConfig
    from lerobot.configs.train import TrainPipelineConfig

    from lerobot_pnp.policy import PnpLstmConfig

    policy = PnpLstmConfig(mode=mode, max_episode_length=12, hidden_size=8, device="cpu", push_to_hub=False)
    dataset = DatasetConfig(repo_id=REPO_ID, root=str(root), streaming=streaming)
    return TrainPipelineConfig(dataset=dataset, policy=policy, num_workers=num_workers)


@pytest.mark.parametrize("streaming", [True, False])
def test_the_recovering_policy_trains_on_per_frame_phase_labels(tiny_root, in_lerobot_train, streaming):
    """As lerobot-train builds them: the dataset windows phase.index / phase.subtask as the action, the
    pre-processor passes them through, and the policy's loss includes its phase and subtask cross-entropies."""
    import torch
    from lerobot.policies.factory import make_policy

    from lerobot_pnp.policy.modeling_pnp_lstm import PHASE_KEY, SUBTASK_KEY

    cfg = _train_cfg(tiny_root, streaming)
    dataset, _ = in_lerobot_train.make_train_eval_datasets(cfg)
    policy = make_policy(cfg.policy, ds_meta=dataset.meta)
    pre, _ = in_lerobot_train.make_pre_post_processors(policy_cfg=cfg.policy, dataset_stats=dataset.meta.stats)
    batch = next(iter(torch.utils.data.DataLoader(dataset, batch_size=4)))
    window = len(cfg.policy.action_delta_indices)
    assert batch[PHASE_KEY].shape == batch[SUBTASK_KEY].shape == (4, window)
    batch = pre(batch)
    assert batch[PHASE_KEY].shape == (4, window)
    real = ~batch["action_is_pad"]
    first = batch[PHASE_KEY][real.nonzero()[0, 0], real.nonzero()[0, 1]]
    assert int(first) == 0  # a window's first real frame is its episode's frame 0, in the first phase
    policy.train()
    _, info = policy.forward(batch)
    assert {"ce_phase", "ce_subtask", "acc_phase"} <= set(info), info


def test_the_clocked_policy_and_other_datasets_keep_lerobots_windows(tiny_root, in_lerobot_train):
    from lerobot_pnp.policy.modeling_pnp_lstm import PHASE_KEY

    dataset, _ = in_lerobot_train.make_train_eval_datasets(_train_cfg(tiny_root, False, mode="clocked"))
    assert PHASE_KEY not in dataset.delta_timestamps and "action" in dataset.delta_timestamps


def test_a_stream_lerobot_would_leave_empty_is_refused_in_lerobot_train(tiny_root, in_lerobot_train):
    """LeRobot gives the stream num_workers shards: with 0 it has none and yields nothing. The wrapped
    ``make_train_eval_datasets`` refuses it in one line; with a worker the stream is returned and whole."""
    with pytest.raises(ConfigError, match=r"--num_workers 0 gives an empty stream.*pass --num_workers 1 or more"):
        in_lerobot_train.make_train_eval_datasets(_train_cfg(tiny_root, True, num_workers=0))
    stream, _ = in_lerobot_train.make_train_eval_datasets(_train_cfg(tiny_root, True, num_workers=1))
    assert len(list(stream)) == stream.num_frames > 0  # every frame of the two episodes once


def test_not_in_lerobot_train_nothing_is_wrapped(monkeypatch):
    monkeypatch.delitem(sys.modules, TRAIN_MODULE, raising=False)
    assert install_stock_train_hooks() is False


@pytest.mark.slow
def test_lerobot_train_streaming_with_no_worker_is_one_line(tiny_root, tmp_path):
    exe = Path(sys.executable).parent / "lerobot-train"
    if not exe.exists():
        pytest.skip(f"lerobot-train is not installed next to {sys.executable}")
    cmd = [str(exe), f"--dataset.repo_id={REPO_ID}", f"--dataset.root={tiny_root}", "--dataset.streaming=true"]
    cmd += ["--num_workers=0", "--policy.type=pnp_lstm", "--policy.device=cpu", "--policy.push_to_hub=false"]
    cmd += ["--steps=2", f"--output_dir={tmp_path / 'out'}"]
    proc = zygote.run(cmd, tmp_path, timeout=120)  # its entry point, in a process forked from a warm interpreter
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "StopIteration" not in proc.stderr, proc.stderr[-3000:]
    assert "lerobot-train: error: --dataset.streaming=true with --num_workers 0 gives an empty stream" in proc.stderr
