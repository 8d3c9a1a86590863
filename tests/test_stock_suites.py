"""Suites as stock ``lerobot-eval`` tasks (``--env.task``): the same episodes as the study's evaluator, the names,
the bad inputs (one line, nothing written) and one real ``lerobot-eval`` run over two suites."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import zygote

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.integration.recorded_task import write_checkpoint_task
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.stock_suites import suite_names, valid_names

SUITES = ("nominal", "nudge_0.02", "drop")  # a mixed outcome, a recovery budget (20 steps), all failures
SEED = 100


@pytest.fixture(scope="module")
def lookup_table():
    """The study's lookup table over expert demonstrations of seeds 100-103: it replays them, so it succeeds on
    nominal where the demonstration started and fails where a disturbance moves the object."""
    from lerobot_pnp.report.adapters import Episodes
    from lerobot_pnp.report.baselines import LookupTablePolicy
    from lerobot_pnp.sim.env_config import make_env
    from lerobot_pnp.sim.expert import run_expert_episode

    env = make_env(BaxterPnPEnvConfig(preset="paper"))
    demos = [run_expert_episode(env, s) for s in range(SEED, SEED + 4)]
    env.close()
    starts = np.stack([d.env_states[0] for d in demos])
    return LookupTablePolicy(Episodes(np.arange(len(demos)), starts, [d.actions for d in demos]))


def test_stock_eval_of_suites_equals_the_study_evaluator_episode_by_episode(lookup_table):
    """lerobot-eval's own path (the env config's create_envs -> eval_policy_all) against the study's in-process
    evaluator (eval_lerobot_policy on each suite's env config), on the same seeds: the same outcome per episode."""
    import torch
    from lerobot.envs.factory import make_env_pre_post_processors
    from lerobot.scripts.lerobot_eval import eval_policy_all

    from lerobot_pnp.evaluation.closed_loop import eval_lerobot_policy
    from lerobot_pnp.report.baselines import identity_processors
    from lerobot_pnp.sim.suites import SUITES as CATALOGUE

    base = BaxterPnPEnvConfig(preset="paper")
    cfg = base.with_changes(task=",".join(SUITES))
    pre, post = identity_processors()
    envs = cfg.create_envs(n_envs=3)  # two batches of 3 for 4 episodes
    assert list(envs) == list(SUITES)
    steps = {s: envs[s][0].call("_max_episode_steps")[0] for s in SUITES}
    tasks = {s: envs[s][0].call("task")[0] for s in SUITES}
    env_pre, env_post = make_env_pre_post_processors(cfg, lookup_table.config)
    with torch.no_grad():
        info = eval_policy_all(envs, lookup_table, env_pre, env_post, pre, post, n_episodes=4, start_seed=SEED)
    stock = {t["task_group"]: t["metrics"]["successes"] for t in info["per_task"]}
    study = {
        s: [
            r.success
            for r in eval_lerobot_policy(lookup_table, pre, post, CATALOGUE[s].env_configs(base)[0], 4, SEED, 3)
        ]
        for s in SUITES
    }
    assert stock == study
    assert any(study["nudge_0.02"]) and not all(study["nudge_0.02"]) and all(study["nominal"])
    assert {s: g["n_episodes"] for s, g in info["per_group"].items()} == dict.fromkeys(SUITES, 4)
    assert steps == {"nominal": 10, "nudge_0.02": 10, "drop": 20} and tasks == {s: s for s in SUITES}


def test_names_aliases_axes_and_the_default():
    from lerobot_pnp.sim.suites import HELD_OUT_AXES, PROTOCOL_SUITES

    assert suite_names(None) is None and suite_names("BaxterPnP-v0") is None
    heldout = suite_names("heldout")
    assert heldout == ["nominal", *PROTOCOL_SUITES] and len(heldout) == 18
    assert suite_names("paper")[:2] == ["nominal", "slack"] and "nudge_0.05" in suite_names("paper")
    timing = next(a for a in HELD_OUT_AXES if a.name == "timing")
    assert suite_names("heldout_timing") == [*timing.in_distribution, *timing.held_out]
    assert suite_names(" drop , nudge,drop") == ["drop", "nudge_0.01", "nudge_0.02", "nudge_0.03", "nudge_0.05"]
    assert {"heldout", "paper", "heldout_latency", "latency", "nudge"} <= set(valid_names())


@pytest.mark.parametrize("task", ["nominal,bogus", "", " , ", "nominal,", ",drop"])
def test_unknown_or_no_suite_is_one_line_naming_the_valid_ones(task):
    """The list of valid names holds every name --env.task accepts (the aliases too), whatever the mistake."""
    with pytest.raises(ConfigError) as err:
        BaxterPnPEnvConfig(preset="paper", task=task)
    message = str(err.value)
    assert "\n" not in message and message.startswith("env.task")
    assert all(repr(name) in message for name in valid_names())
    assert ("'bogus'" in message) if "bogus" in task else ("empty" in message)
    assert all(suite_names(name) for name in valid_names())  # every name listed is accepted


def test_a_long_unknown_name_is_echoed_cut_short():
    with pytest.raises(ConfigError) as err:
        BaxterPnPEnvConfig(preset="paper", task="x" * 10_000)
    message = str(err.value)
    assert "'xxxxxxxxxx" in message and "…" in message and "10002 characters" in message
    assert len(message) < len(str(valid_names())) + 300


@pytest.mark.parametrize("task", ["nominal,drop", "BaxterPnP-v0"])
def test_tasks_in_threads_are_refused_for_every_task(task):
    """eval_policy_all runs tasks in threads: MuJoCo's EGL context belongs to the thread that made it (closing the
    env from the main thread fails after the rollouts), and a recurrent policy's memory would mix suites."""
    with pytest.raises(ConfigError, match="env.max_parallel_tasks=2: lerobot-eval would run the tasks in threads"):
        BaxterPnPEnvConfig(preset="paper", task=task, max_parallel_tasks=2)
    assert BaxterPnPEnvConfig(preset="paper", task=task, max_parallel_tasks=1).max_parallel_tasks == 1


def test_a_suite_contradicting_the_checkpoints_control_mode(tmp_path):
    """A nudge suite fires at keyframe step 1: in a dense checkpoint's task that is before the arm moves."""
    dense = BaxterPnPEnvConfig(preset="paper", control_mode="dense")
    write_checkpoint_task({"type": "baxter_pnp", **dense.to_dict()}, tmp_path)
    dense_ckpt = BaxterPnPEnvConfig.from_source(str(tmp_path))
    assert dense_ckpt.control_mode == "dense"
    with pytest.raises(ConfigError, match="suite 'nudge_0.03' nudges the object at env step 1"):
        BaxterPnPEnvConfig.from_source(str(tmp_path), task="nominal,nudge_0.03")
    ok = BaxterPnPEnvConfig.from_source(str(tmp_path), task="drop,latency")  # no keyframe-timed change
    assert ok.task == "drop,latency" and ok.control_mode == "dense"
    fixed = BaxterPnPEnvConfig.from_source(str(tmp_path), task="nudge_0.03", nudge_at_step=30)
    assert fixed.nudge_at_step == 30


# ---------------------------------------------------------------------------------------------- the real CLI
def _checkpoint(path: Path) -> Path:
    """A tiny untrained pnp_lstm checkpoint recording the paper's keyframe task."""
    import torch
    from lerobot.configs import FeatureType, PolicyFeature

    from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy, make_pnp_lstm_pre_post_processors

    torch.manual_seed(0)
    cfg = PnpLstmConfig(
        hidden_size=8,
        input_features={
            "observation.state": PolicyFeature(FeatureType.STATE, (8,)),
            "observation.environment_state": PolicyFeature(FeatureType.ENV, (3,)),
        },
        output_features={"action": PolicyFeature(FeatureType.ACTION, (8,))},
    )

    def unit(n: int) -> dict:
        return {"mean": torch.zeros(n), "std": torch.ones(n), "min": -torch.ones(n), "max": torch.ones(n)}

    stats = {"observation.state": unit(8), "observation.environment_state": unit(3), "action": unit(8)}
    PnpLstmPolicy(cfg).save_pretrained(path)
    for proc in make_pnp_lstm_pre_post_processors(cfg, stats):
        proc.save_pretrained(path)
    write_checkpoint_task({"type": "baxter_pnp", **BaxterPnPEnvConfig(preset="paper").to_dict()}, path)
    return path


def _eval(ckpt: Path, out: Path, task: str, tmp_path: Path) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("lerobot-eval")
    if not exe.exists():
        pytest.skip("lerobot-eval is not installed next to the interpreter")
    cmd = [str(exe), f"--policy.path={ckpt}", "--env.type=baxter_pnp", f"--env.task={task}", "--eval.n_episodes=1",
           "--eval.batch_size=1", "--policy.device=cpu", f"--output_dir={out}"]  # fmt: skip
    return zygote.run(cmd, tmp_path, timeout=300)  # its entry point, in a process forked from a warm interpreter


@pytest.mark.slow
def test_lerobot_eval_runs_named_suites_and_refuses_an_unknown_one(tmp_path):
    ckpt = _checkpoint(tmp_path / "ckpt")
    proc = _eval(ckpt, tmp_path / "bad", "nominal,bogus", tmp_path)
    assert proc.returncode == 2 and not (tmp_path / "bad").exists()
    errors = [line for line in proc.stderr.splitlines() if "error" in line.lower()]
    assert len(errors) == 1 and "unknown suite 'bogus'" in errors[0], proc.stderr[-2000:]

    proc = _eval(ckpt, tmp_path / "ok", "nominal,heldout_far_drop", tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    info = json.loads((tmp_path / "ok" / "eval_info.json").read_text())
    assert list(info["per_group"]) == ["nominal", "heldout_far_drop"]
    assert [t["task_group"] for t in info["per_task"]] == ["nominal", "heldout_far_drop"]
    assert (tmp_path / "ok" / "videos" / "heldout_far_drop_0" / "eval_episode_0.mp4").is_file()


def test_video_frames_are_sketches_and_a_frozen_scene_is_drawn_once():
    """Without cameras a suite's video frame is a sketch of the simulator's state; once the episode ended the
    frame of the frozen scene is drawn once, until the next rollout's reset."""
    from lerobot_pnp.sim.stock_suites import SKETCH_SIZE, make_suite_env

    env = make_suite_env(BaxterPnPEnvConfig(preset="paper").to_dict(), "nominal")
    env.reset(seed=3, options={"lerobot_new_rollout": True})
    first = env.render()
    assert (
        first.shape == (*SKETCH_SIZE, 3)
        and first.dtype == np.uint8
        and len(np.unique(first.reshape(-1, 3), axis=0)) > 2
    )
    hold = np.append(env.unwrapped.physics.state_vector()[:7], 1.0)
    while not env.is_frozen:
        env.step(hold)
    still = env.render()
    assert env.render() is still
    env.reset(seed=4, options={"lerobot_new_rollout": True})
    assert not env.is_frozen and env.render() is not still
    env.close()


def test_stock_lerobot_eval_resolves_the_task_a_test_builds_from_the_same_record(tmp_path, monkeypatch):
    """``lerobot-eval --policy.path=<ckpt>``: the plugin's load-time edge, then LeRobot's own parser (``parser.wrap``
    over ``EvalPipelineConfig``, which builds the env config inside draccus): the env config it resolves equals
    ``BaxterPnPEnvConfig(recorded=<the checkpoint's record>, **the same flags)``."""
    from lerobot.configs import parser
    from lerobot.configs.eval import EvalPipelineConfig

    from lerobot_pnp.integration.registration import hand_over_command_line

    ckpt = _checkpoint(tmp_path / "ckpt")
    task = {"type": "baxter_pnp", **BaxterPnPEnvConfig(preset="full", image_width=80).to_dict()}
    write_checkpoint_task(task, ckpt)
    argv = ["lerobot-eval", f"--policy.path={ckpt}", "--env.type=baxter_pnp", "--env.task=nominal,drop",
            "--env.nudge_max=0.01", "--policy.device=cpu", f"--output_dir={tmp_path / 'out'}"]  # fmt: skip
    monkeypatch.setattr(BaxterPnPEnvConfig, "edge_records", {})
    monkeypatch.setattr(sys, "argv", argv)
    hand_over_command_line()  # what the plugin does when lerobot-eval loads it
    seen = {}

    def eval_main(cfg):
        seen["env"] = cfg.env

    eval_main.__annotations__ = {"cfg": EvalPipelineConfig}  # what parser.wrap parses (as lerobot_eval.main)
    parser.wrap()(eval_main)()
    explicit = BaxterPnPEnvConfig(recorded=BaxterPnPEnvConfig.read_source(ckpt), task="nominal,drop", nudge_max=0.01)
    assert seen["env"].to_dict() == explicit.to_dict()
    assert explicit.preset == "full" and explicit.image_width == 80 and explicit.nudge_max == 0.01
