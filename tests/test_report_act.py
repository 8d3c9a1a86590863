"""LeRobot's ACT as a study method: dense recording of the same demonstrations, training, checkpoint, dense eval."""

import json

import numpy as np
import pytest
import torch

from lerobot_pnp.errors import DatasetError
from lerobot_pnp.report import act_baseline, adapters
from lerobot_pnp.report.run import StudyConfig, SuiteSpec, run_study
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

N = 10  # demonstrations: 8 train / 2 test


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """A tiny study with ACT only: 10 demonstrations, 2 training seeds of 30 steps, 3 nominal + 2 nudged episodes."""
    out = tmp_path_factory.mktemp("act") / "study"
    cfg = dict(
        output_dir=str(out),
        preset="quick",
        num_episodes=N,
        workers=1,
        methods=["act"],
        train_seeds=[1000, 1001],
        suites=[SuiteSpec("nominal", 3), SuiteSpec("nudge_0.03", 2)],
        act_steps=30,
    )
    summary = run_study(StudyConfig(**cfg))
    return out, cfg, summary


def test_act_trains_saves_loads_and_runs_dense_episodes(study):
    from lerobot.policies.act.modeling_act import ACTPolicy

    from lerobot_pnp.evaluation.checkpoints import load_policy

    out, _, _ = study
    for seed in (1000, 1001):
        ckpt = adapters.checkpoint_of(out / "train" / "act" / f"seed{seed}")
        assert json.loads((ckpt / "config.json").read_text())["type"] == "act"
        assert json.loads((ckpt / "baxter_pnp_env.json").read_text())["control_mode"] == "dense"
        train = json.loads((out / "train" / "act" / f"seed{seed}" / "act_train.json").read_text())
        assert train["steps"] == 30 and train["train_episodes"] == N * 8 // 10
        assert np.isfinite(train["train_l1_last10pc"]) and np.isfinite(train["held_out_l1"])

        nominal = json.loads((out / "evals" / "act" / f"seed{seed}" / "nominal.json").read_text())
        assert [e["seed"] for e in nominal["episodes"]] == [100_000, 100_001, 100_002]
        assert [p["control_mode"] for p in nominal["env_parts"]] == ["dense"]
        assert nominal["env_parts"][0]["fps"] == 20 and nominal["env_parts"][0]["episode_length"] == 200
        # an episode ends on success or at the 200-step truncation, never in between without success
        assert all(e["success"] or e["steps"] == 200 for e in nominal["episodes"])
        nudge = json.loads((out / "evals" / "act" / f"seed{seed}" / "nudge_0.03.json").read_text())
        assert nudge["env_parts"][0]["nudge_at_step"] == act_baseline.dense_nudge_step(out / "dataset_dense") > 1

    # the two training seeds give different weights
    weights = [
        load_policy(adapters.checkpoint_of(out / "train" / "act" / f"seed{s}"), env_cfg=BaxterPnPEnvConfig()).policy
        for s in (1000, 1001)
    ]
    assert isinstance(weights[0], ACTPolicy)
    p0, p1 = (next(w.parameters()).detach() for w in weights)
    assert not torch.equal(p0, p1)
    assert "ACT (dense)" in (out / "report.md").read_text()


def test_dense_dataset_and_training_are_reused_on_the_second_call(study):
    out, cfg, first = study
    dense = out / "dataset_dense"
    stamps = {p: p.stat().st_mtime_ns for p in [*dense.rglob("*.parquet"), out / "train" / "act" / "seed1000"]}
    weights = adapters.checkpoint_of(out / "train" / "act" / "seed1000") / "model.safetensors"
    stamps[weights] = weights.stat().st_mtime_ns
    run_study(StudyConfig(**cfg))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["generation"]["dense"]["status"] == "reused"
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps


def test_dense_recording_must_hold_the_same_demonstrations(study, tmp_path):
    out, _, _ = study
    assert adapters.check_same_demonstrations(out / "dataset", out / "dataset_dense") == N
    other = tmp_path / "other"
    adapters.generate_dataset(other, N, seed=5, workers=1)  # other seeds: other object positions
    with pytest.raises(DatasetError, match="does not hold the demonstrations"):
        adapters.check_same_demonstrations(other, out / "dataset_dense")


def test_dense_env_keeps_the_suite_and_times_the_nudge(study):
    out, _, _ = study
    base = BaxterPnPEnvConfig(preset="paper", keyframe_budget=20, nudge_max=0.02, obs_latency=1)
    dense = act_baseline.dense_env(base, out / "dataset_dense")
    assert (dense.control_mode, dense.fps, dense.episode_length) == ("dense", 20, 400)
    assert dense.nudge_max == 0.02 and dense.obs_latency == 1 and dense.object_low == base.object_low
    assert dense.nudge_at_step == act_baseline.dense_nudge_step(out / "dataset_dense")
    with pytest.raises(DatasetError, match="needs the dense dataset"):
        act_baseline.dense_env(base, None)
