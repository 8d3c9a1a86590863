"""The real CLIs end to end on a tiny scale: ``lerobot-pnp generate`` (a custom task) -> ``lerobot-pnp train`` ->
the stock ``lerobot-eval``, which reads the task back from the checkpoint; and ``lerobot-eval``'s refusals of a
checkpoint that does not fit. A file of its own: the rest of test_cli.py runs on the other worker meanwhile."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from clis import ENV
from clis import exe as _exe
from clis import run as _run
from zygote import run as _forked

from lerobot_pnp import cli


def _write_mismatched_checkpoint(out: Path) -> None:
    """A valid pnp_lstm checkpoint for a robot with 14 state dims (e.g. two arms): not this env's 8."""
    import torch
    from lerobot.configs import FeatureType, PolicyFeature
    from lerobot.policies.factory import make_pre_post_processors

    from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy

    cfg = PnpLstmConfig(hidden_size=8)
    cfg.input_features = {
        "observation.state": PolicyFeature(FeatureType.STATE, (14,)),
        "observation.environment_state": PolicyFeature(FeatureType.ENV, (3,)),
    }
    cfg.output_features = {"action": PolicyFeature(FeatureType.ACTION, (8,))}
    policy = PnpLstmPolicy(cfg)

    def unit(n: int) -> dict:
        return {"mean": torch.zeros(n), "std": torch.ones(n)}

    stats = {"observation.state": unit(14), "observation.environment_state": unit(3), "action": unit(8)}
    pre, post = make_pre_post_processors(cfg, dataset_stats=stats)
    for obj in (policy, pre, post):
        obj.save_pretrained(out)


def _eval_cmd(policy_path: Path, out: Path, n_episodes: int = 2) -> list[str]:
    return [
        _exe("lerobot-eval"),
        f"--policy.path={policy_path}",
        "--env.type=baxter_pnp",
        f"--eval.n_episodes={n_episodes}",
        f"--eval.batch_size={min(n_episodes, 10)}",
        "--eval.use_async_envs=false",
        "--policy.device=cpu",
        f"--output_dir={out}",
    ]


# A task that is not the default one: a 10 x 10 cm object box and a place target 7 cm from the default.
CUSTOM_TASK = [
    "--env.object_low=[0.5,0.2]",
    "--env.object_high=[0.6,0.3]",
    "--env.place_low=[0.65,-0.1]",
    "--env.place_high=[0.65,-0.1]",
]
E2E_SUCCESS_THRESHOLD = 60.0  # % of 20 episodes: far below a trained policy, far above the default target (0 %)


@pytest.mark.slow
def test_end_to_end_real_clis(tmp_path, capsys, monkeypatch):
    """generate (custom task) -> train -> the real lerobot-eval with NO task flags: the recorded task is used and a
    small trained policy succeeds in closed loop. Placing on the default target instead would fail every episode
    (7 cm off, the tolerance is 2 cm), so the threshold also proves the task was read back. generate, train and
    viz run through ``cli.main`` (the README quick start runs their executables); lerobot-eval is the stock
    process, whose only source of the task is the checkpoint (the flag that overrides it runs lerobot-eval's
    entry in this process)."""
    ds = tmp_path / "ds"
    gen = ["generate", "--repo_id=local/cli_e2e", f"--root={ds}", "--num_episodes=100", "--workers=1"]
    assert cli.main([*gen, "--progress=false", *CUSTOM_TASK]) == 0
    info = json.loads((ds / "meta" / "info.json").read_text())
    assert info["total_episodes"] == 100 and info["splits"] == {"train": "0:80", "test": "80:100"}
    recorded = json.loads((ds / "meta" / "baxter_pnp_env.json").read_text())
    assert recorded["place_low"] == [0.65, -0.1] and recorded["object_high"] == [0.6, 0.3]

    train = tmp_path / "train"
    argv = ["train", "--dataset_repo_id=local/cli_e2e", f"--dataset_root={ds}", "--epochs=400"]
    assert cli.main([*argv, f"--output_dir={train}", "--progress=false"]) == 0
    ckpt = train / "checkpoints" / "last" / "pretrained_model"
    for name in ("config.json", "model.safetensors", "train_config.json", "policy_preprocessor.json",
                 "policy_postprocessor.json", "baxter_pnp_env.json"):  # fmt: skip
        assert (ckpt / name).is_file(), name

    out = tmp_path / "eval"
    proc = _run(_eval_cmd(ckpt, out, n_episodes=20), tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    overall = json.loads((out / "eval_info.json").read_text())["overall"]
    assert overall["n_episodes"] == 20
    assert overall["pc_success"] >= E2E_SUCCESS_THRESHOLD, overall

    # An explicit task flag still wins over the recorded task: the default target makes every episode fail.
    # lerobot-eval's own entry (its argument parsing and evaluation) in this process, where the plugin is registered.
    from lerobot.scripts.lerobot_eval import eval_main

    out = tmp_path / "eval_default_target"
    argv = [*_eval_cmd(ckpt, out, n_episodes=2), "--env.place_low=[0.6,-0.05]", "--env.place_high=[0.6,-0.05]"]
    monkeypatch.setattr("sys.argv", ["lerobot-eval", *argv[1:]])
    eval_main()
    assert json.loads((out / "eval_info.json").read_text())["overall"]["pc_success"] == 0.0

    # The viewer replays an episode in the recorded task with no flags either.
    capsys.readouterr()
    rrd = tmp_path / "ep.rrd"
    assert cli.main(["viz", "--repo_id=local/cli_e2e", f"--root={ds}", "--episode_index=0", f"--save={rrd}"]) == 0
    (run,) = json.loads(capsys.readouterr().out)["runs"]
    assert run["place_target"] == [0.65, -0.1] and run["success"] and rrd.is_file()


@pytest.mark.slow
def test_lerobot_eval_refuses_a_contradicting_flag_and_a_checkpoint_of_other_features(tmp_path):
    """lerobot-eval's entry point in processes of their own (forked from a warm interpreter, tests/zygote.py), on
    untrained checkpoints (both refusals come before any rollout)."""
    from lerobot_pnp.integration.recorded_task import write_checkpoint_task
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    # A checkpoint trained for other features must not run, and must not write results.
    bad = tmp_path / "bad_ckpt"
    _write_mismatched_checkpoint(bad)
    bad_out = tmp_path / "eval_bad"
    proc = _forked(_eval_cmd(bad, bad_out), tmp_path)
    assert proc.returncode != 0
    assert not (bad_out / "eval_info.json").exists()
    # One line naming the feature and both shapes (not a bare tensor-size error, no traceback).
    assert "input 'observation.state' has shape (14,), this env gives (8,)" in proc.stderr, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr

    # A keyframe checkpoint in dense control would fail every episode silently: a clear error.
    keyframe = tmp_path / "keyframe_ckpt"
    _write_mismatched_checkpoint(keyframe)
    write_checkpoint_task({"type": "baxter_pnp", **BaxterPnPEnvConfig(preset="paper").to_dict()}, keyframe)
    proc = _forked([*_eval_cmd(keyframe, tmp_path / "eval_dense"), "--env.control_mode=dense"], tmp_path)
    assert proc.returncode != 0 and "contradicts the recorded task ('keyframe'" in proc.stderr, proc.stderr[-2000:]
    assert not (tmp_path / "eval_dense" / "eval_info.json").exists()


def _hub_cache_checkpoint(cache: Path, repo_id: str) -> Path:
    """A checkpoint in the Hub cache's layout (``models--owner--name``, ``refs/main``, a snapshot), as
    ``hf download`` or a first ``lerobot-eval --policy.path=<repo id>`` leaves it, recording the ``paper`` task."""
    from lerobot_pnp.integration.recorded_task import write_checkpoint_task
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    revision = "0123456789abcdef0123456789abcdef01234567"
    repo = cache / f"models--{repo_id.replace('/', '--')}"
    snapshot = repo / "snapshots" / revision
    _write_mismatched_checkpoint(snapshot)
    write_checkpoint_task({"type": "baxter_pnp", **BaxterPnPEnvConfig(preset="paper").to_dict()}, snapshot)
    (repo / "refs").mkdir(parents=True)
    (repo / "refs" / "main").write_text(revision)
    return snapshot


def test_a_hub_repo_id_as_policy_path_reads_the_checkpoints_recorded_task(tmp_path, monkeypatch):
    """``--policy.path=owner/name`` in a run on this env stands for the record of the cached Hub checkpoint; a run
    on another env, and a repo id that cannot be fetched, are left to LeRobot."""
    from huggingface_hub import constants

    from lerobot_pnp.integration import stock_cli

    snapshot = _hub_cache_checkpoint(tmp_path / "hub", "someone/pnp_lstm_paper")
    monkeypatch.setattr(constants, "HF_HUB_CACHE", str(tmp_path / "hub"))
    monkeypatch.setattr(constants, "HF_HUB_OFFLINE", True)
    ours = ["lerobot-eval", "--policy.path=someone/pnp_lstm_paper", "--env.type=baxter_pnp"]
    monkeypatch.setattr("sys.argv", ours)
    assert stock_cli.command_line_sources() == {None: str(snapshot)}
    monkeypatch.setattr("sys.argv", [ours[0], ours[1], "--env.type=pusht"])
    assert stock_cli.command_line_sources() == {None: "someone/pnp_lstm_paper"}
    monkeypatch.setattr("sys.argv", [ours[0], "--policy.path=someone/not_cached", ours[2]])
    assert stock_cli.command_line_sources() == {None: "someone/not_cached"}


def test_lerobot_eval_of_a_hub_checkpoint_applies_its_recorded_task(tmp_path):
    """The real lerobot-eval, offline, on a checkpoint in the Hub cache: its recorded keyframe task is read, so a
    contradicting ``--env.control_mode=dense`` is refused in one line before any rollout."""
    _hub_cache_checkpoint(tmp_path / "hub", "someone/pnp_lstm_paper")
    env = {**ENV, "HF_HUB_CACHE": str(tmp_path / "hub"), "HF_HUB_OFFLINE": "1"}
    cmd = [*_eval_cmd("someone/pnp_lstm_paper", tmp_path / "eval_hub"), "--env.control_mode=dense"]
    proc = _run(cmd, tmp_path, env=env)
    assert proc.returncode != 0 and "contradicts the recorded task ('keyframe'" in proc.stderr, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
