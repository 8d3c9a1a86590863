"""The lookup table as a checkpoint: ``lerobot-pnp lookup-table`` writes it, LeRobot's loader reads it back (the
same table, the same actions), and stock ``lerobot-eval``'s path on suites gives the study's outcomes episode by
episode. Bad input is one line, exit 2."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest
import torch

from lerobot_pnp import cli
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

SEED = 100  # the demonstrations are seeds 100.. and so are the evaluated episodes: nominal replays them exactly
SUITES = ("nominal", "drop")
N = 3


@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    from lerobot_pnp.dataset import GenerateConfig, generate

    root = tmp_path_factory.mktemp("lookup") / "demos"
    env = BaxterPnPEnvConfig(preset="paper")
    generate(GenerateConfig(repo_id="local/demos", root=str(root), num_episodes=5, seed=SEED, workers=1,
                            progress=False, env=env))  # fmt: skip
    return root


@pytest.fixture(scope="module")
def checkpoint(demos):
    out = demos.parent / "table"
    assert cli.main(["lookup-table", "--dataset_root", str(demos), "--output_dir", str(out)]) == 0
    return out


def test_save_then_load_round_trips_the_table_and_its_actions(demos, checkpoint):
    from lerobot_pnp.integration.recorded_task import read_recorded
    from lerobot_pnp.policy.modeling_pnp_lookup_table import PnpLookupTablePolicy
    from lerobot_pnp.report.adapters import load_train_episodes
    from lerobot_pnp.report.baselines import LookupTablePolicy

    episodes = load_train_episodes(demos)  # the training split: 4 of the 5
    loaded = PnpLookupTablePolicy.from_pretrained(checkpoint)
    starts, actions = loaded.episodes()
    assert len(actions) == 4 and np.array_equal(starts, episodes.first_env_state)
    assert all(np.array_equal(a, b) for a, b in zip(actions, episodes.actions, strict=True))
    assert read_recorded(checkpoint) == read_recorded(demos)  # the dataset's task, for lerobot-eval
    built = LookupTablePolicy(episodes)
    obs = {"observation.environment_state": torch.as_tensor(episodes.first_env_state[[2, 0, 3]] + 0.001)}
    for _ in range(12):  # past the longest episode: both hold the last action
        assert torch.equal(loaded.select_action(obs), built.select_action(obs))


def test_stock_eval_of_the_checkpoint_equals_the_study_episode_by_episode(demos, checkpoint):
    """lerobot-eval's loading (make_policy and make_pre_post_processors from the folder, with lerobot-eval's
    processor overrides) and its multi-suite rollout (eval_policy_all on the config's create_envs) against the
    study's ``lookup_eval`` on each suite's config, the same seeds."""
    from lerobot.configs import PreTrainedConfig
    from lerobot.envs.factory import make_env_pre_post_processors
    from lerobot.policies.factory import make_policy, make_pre_post_processors
    from lerobot.scripts.lerobot_eval import eval_policy_all

    from lerobot_pnp.report.builders import lookup_eval
    from lerobot_pnp.sim.suites import SUITES as CATALOGUE

    env_cfg = BaxterPnPEnvConfig.from_source(str(checkpoint), task=",".join(SUITES))
    policy_cfg = PreTrainedConfig.from_pretrained(checkpoint)
    policy_cfg.pretrained_path = checkpoint
    policy = make_policy(policy_cfg, env_cfg=env_cfg)
    overrides = {"device_processor": {"device": "cpu"}, "rename_observations_processor": {"rename_map": {}}}
    pre, post = make_pre_post_processors(policy_cfg, pretrained_path=str(checkpoint), preprocessor_overrides=overrides)
    env_pre, env_post = make_env_pre_post_processors(env_cfg, policy_cfg)
    with torch.no_grad():
        info = eval_policy_all(env_cfg.create_envs(n_envs=2), policy, env_pre, env_post, pre, post, N, start_seed=SEED)
    stock = {t["task_group"]: t["metrics"]["successes"] for t in info["per_task"]}

    ctx = types.SimpleNamespace(dataset_root=demos, data_keys={}, n_demos=None)
    base = BaxterPnPEnvConfig.from_source(str(demos))
    study = {
        s: [r.success for r in lookup_eval(None, ctx, CATALOGUE[s].env_configs(base)[0], N, SEED, 2)] for s in SUITES
    }
    assert stock == study, (stock, study)
    assert stock["nominal"] == [True] * N and not any(stock["drop"])  # replays succeed until the object moves


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, demos, checkpoint):
    from keyframe_synth import make_keyframe_dataset

    make_keyframe_dataset(tmp_path / "other", n_episodes=2)  # a LeRobot dataset that records no baxter_pnp task
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy/config.json").write_text('{"mine": true}')  # a user's file under a checkpoint file's name
    cases = {
        "is not a dataset folder": ["--dataset_root", str(tmp_path / "none")],
        "records no baxter_pnp task": ["--dataset_root", str(tmp_path / "other")],
        "config.json exists and `lerobot-pnp lookup-table` did not write it": [
            "--dataset_root", str(demos), "--output_dir", str(tmp_path / "busy"), "--overwrite", "true"],
        "pass --overwrite true": ["--dataset_root", str(demos), "--output_dir", str(checkpoint)],
    }  # fmt: skip
    for message, args in cases.items():
        capsys.readouterr()
        assert cli.main(["lookup-table", "--output_dir", str(tmp_path / "out"), *args]) == 2, message
        err = capsys.readouterr().err.strip()
        assert message in err and "\n" not in err, err
    assert not (tmp_path / "out").exists() and (tmp_path / "busy/config.json").read_text() == '{"mine": true}'
    assert json.loads((checkpoint / "config.json").read_text())["type"] == "pnp_lookup_table"


def test_a_damaged_table_is_refused_when_loaded(checkpoint, tmp_path):
    """lerobot-eval's feature check passes on the task the table was recorded for; a table holding NaN, or a file
    without the table, is a PolicyError when loaded, never a replay of zeros or NaN."""
    import shutil

    from lerobot.configs import PreTrainedConfig
    from safetensors.torch import load_file, save_file

    from lerobot_pnp.errors import PolicyError
    from lerobot_pnp.evaluation.checkpoints import check_policy_features
    from lerobot_pnp.policy.modeling_pnp_lookup_table import PnpLookupTablePolicy

    check_policy_features(
        PreTrainedConfig.from_pretrained(checkpoint), len(BaxterPnPEnvConfig(preset="paper").environment_state_names)
    )
    bad = tmp_path / "bad"
    shutil.copytree(checkpoint, bad)
    tensors = load_file(bad / "model.safetensors")
    save_file({**tensors, "actions": tensors["actions"] * float("nan")}, bad / "model.safetensors")
    with pytest.raises(PolicyError, match="non-finite values in \\['actions'\\]"):
        PnpLookupTablePolicy.from_pretrained(bad)
    save_file({k: v for k, v in tensors.items() if k != "actions"}, bad / "model.safetensors")
    with pytest.raises(RuntimeError, match="actions"):
        PnpLookupTablePolicy.from_pretrained(bad)


def test_overwrite_replaces_only_the_tables_files(demos, tmp_path, capsys):
    """``--overwrite`` replaces the files this command wrote (recorded in the folder's manifest, or a table from
    before the manifest); a file of the user's in the folder stays."""
    from lerobot_pnp.outputs import MANIFEST_FILE

    out = tmp_path / "table"
    args = ["lookup-table", "--dataset_root", str(demos), "--output_dir", str(out)]
    assert cli.main(args) == 0
    written = sorted(p.name for p in out.iterdir() if p.name != MANIFEST_FILE)
    (out / "NOTES.txt").write_text("my notes")
    assert cli.main([*args, "--overwrite", "true", "--num_episodes", "2"]) == 0
    assert (out / "NOTES.txt").read_text() == "my notes"
    assert json.loads((out / "config.json").read_text())["table_episodes"] == 2
    (out / MANIFEST_FILE).unlink()  # a table written before the manifest: its files are still the command's
    assert cli.main([*args, "--overwrite", "true"]) == 0
    assert (out / "NOTES.txt").read_text() == "my notes"
    assert sorted(p.name for p in out.iterdir() if p.name not in (MANIFEST_FILE, "NOTES.txt")) == written
    assert json.loads((out / "config.json").read_text())["table_episodes"] == 4
    capsys.readouterr()
