"""Tests of ``lerobot-pnp dagger``: expert labels on policy rollouts, datasets, aggregation, rounds, resume."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lerobot_pnp.dagger import DaggerConfig, labelled_rollout, run_dagger
from lerobot_pnp.dagger.dart import DartNoise
from lerobot_pnp.dagger.rollouts import suite_env
from lerobot_pnp.dagger.writer import aggregate, features_for, write_episodes
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env


class _Follower:
    """A 'policy' that executes the teacher's label (the ideal DAgger learner), or holds still."""

    def __init__(self, env, hold: bool = False):
        from lerobot_pnp.dagger.rollouts import Teacher

        self.env, self.hold, self.teacher = env, hold, Teacher(env)

    def reset(self):
        self.teacher.prev = None

    def act(self, obs):
        if self.hold:
            return np.append(self.env.unwrapped.physics.arm_command(), 1.0).astype(np.float32)
        return self.teacher.label()[0]


@pytest.fixture(scope="module")
def full_cfg():
    return BaxterPnPEnvConfig(preset="full")


def test_labels_of_a_policy_that_follows_them_recover_from_a_drop(full_cfg):
    env = suite_env(full_cfg, "quiet_drop")
    ep = labelled_rollout(env, _Follower(env), seed=3, suite="quiet_drop")
    again = labelled_rollout(env, _Follower(env), seed=3, suite="quiet_drop")
    env.close()
    assert ep.success and len(ep.actions) > 11  # the drop forced a re-grasp: more than the paper's 10 states
    phases = ep.phases.tolist()
    first_return = next(i for i in range(1, len(phases)) if phases[i] < phases[i - 1])
    assert phases[0] == 0 and phases[first_return] == 0 and phases[-1] == 9  # labelled: approach again
    assert ep.env_states.shape == (len(ep.actions), 7)  # yaw features and goal observed
    np.testing.assert_array_equal(ep.actions, again.actions)  # deterministic per seed
    np.testing.assert_array_equal(ep.env_states, again.env_states)


def test_a_rollout_under_latency_records_the_current_state_not_the_late_view(full_cfg):
    """The policy acts on observations two steps old; the frames hold the state each label is for."""
    late_views = []

    class _Recorder(_Follower):
        def act(self, obs):
            late_views.append(np.asarray(obs["agent_pos"], np.float32))
            return super().act(obs)

    env = make_env(full_cfg.with_changes(obs_latency=2, obs_noise_joints=0.0, obs_noise_object=0.0))
    ep = labelled_rollout(env, _Recorder(env), seed=4, suite="nominal")
    env.close()
    assert ep.success and len(ep.states) > 4
    np.testing.assert_allclose(ep.states[-1][:7], env.unwrapped.physics.state_vector()[:7], atol=1e-5)
    for t in range(2, len(late_views)):  # the policy saw frame t - 2 at step t
        np.testing.assert_array_equal(late_views[t], ep.states[t - 2])
    assert not np.array_equal(late_views[3], ep.states[3])


def test_a_stuck_policy_is_labelled_with_the_way_forward(full_cfg):
    env = suite_env(full_cfg, "quiet")
    ep = labelled_rollout(env, _Follower(env, hold=True), seed=5)
    env.close()
    assert not ep.success and len(ep.actions) == full_cfg.keyframe_budget + 1
    assert set(ep.phases.tolist()) == {0}  # never started: every label is "approach the object"
    assert not np.allclose(ep.actions[:, :7], ep.states[:, :7], atol=1e-2)


def test_written_datasets_load_and_aggregate(full_cfg, tmp_path, capfd):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_pnp.integration.recorded_task import read_recorded

    env = suite_env(full_cfg, "quiet_grasp_miss")
    eps = [labelled_rollout(env, _Follower(env), seed=s) for s in (1, 2)]
    env.close()
    a = write_episodes(tmp_path / "a", "local/a", full_cfg, eps[:1], {"test": "0:1"})
    b = write_episodes(tmp_path / "b", "local/b", full_cfg, eps[1:])
    capfd.readouterr()
    agg = aggregate([a, b], ["local/a", "local/b"], tmp_path / "ab", "local/ab", full_cfg, {"test": "0:1"})
    assert "Copy data and videos" in capfd.readouterr().err  # LeRobot's bars, as a command shows them
    quiet = aggregate([a, b], ["local/a", "local/b"], tmp_path / "q", "local/q", full_cfg, {"test": "0:1"}, False)
    assert "Copy data and videos" not in capfd.readouterr().err  # off where the caller shows no progress
    assert LeRobotDataset("local/q", root=quiet).meta.total_frames == sum(len(e.actions) for e in eps)
    ds = LeRobotDataset("local/ab", root=agg)
    assert ds.meta.total_episodes == 2 and ds.meta.total_frames == sum(len(e.actions) for e in eps)
    assert (
        ds.meta.features["observation.environment_state"]["shape"]
        == features_for(full_cfg)["observation.environment_state"]["shape"]
        == (7,)
    )
    assert ds.meta.info.splits == {"test": "0:1"}
    assert read_recorded(agg)["preset"] == "full"
    frames = ds.hf_dataset.with_format("numpy")[:]
    np.testing.assert_allclose(frames["action"][: len(eps[0].actions)], eps[0].actions)
    np.testing.assert_array_equal(frames["phase.subtask"].reshape(-1), frames["phase.index"].reshape(-1) // 5)
    assert not (tmp_path / "ab.tmp").exists()


def test_config_rejects_unknown_suites():
    with pytest.raises(ConfigError, match="unknown suites"):
        DaggerConfig(eval_suites=["quiet", "earthquake"])
    with pytest.raises(ConfigError, match="unknown task fields"):
        DaggerConfig(env_changes={"observe_phaze": True})


def test_rounds_run_and_resume(tmp_path):
    cfg = dict(
        output_dir=str(tmp_path / "dg"),
        num_episodes=6,
        rounds=1,
        rollouts_per_round=2,
        rollout_suites=["quiet_drop", "quiet_grasp_miss"],
        eval_suites=["quiet"],
        n_episodes=2,
        epochs=2,
        progress=False,
    )
    first = run_dagger(DaggerConfig(**cfg))
    out = Path(first["output_dir"])
    assert first["rollouts"][1]["episodes"] == 2
    table = (out / "table.md").read_text()
    assert "| round 0 |" in table and "| round 1 |" in table
    ckpt = Path(first["final_checkpoint"])
    stamp = (ckpt / "model.safetensors").stat().st_mtime_ns
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    merged = LeRobotDataset("x", root=out / "round_01" / "data")
    assert merged.meta.total_episodes == 8  # 6 demos + 2 labelled rollouts
    # the round-0 demonstrations come from the dataset pipeline: slot i is seed i, the generator's split
    from lerobot_pnp.dataset import episode_seeds, load_split
    from lerobot_pnp.dataset.merge import GENERATION_FILE

    demos = out / "demos"
    seeds = episode_seeds(demos)
    assert (demos / GENERATION_FILE).is_file() and [s % 6 for s in seeds] == list(range(6))  # seed + i + 6 * retry
    assert load_split(demos) == {"train": list(range(5)), "test": [5]}
    assert merged.meta.info.splits == {"test": "5:6"}
    second = run_dagger(DaggerConfig(**cfg))  # everything finished is reused
    assert (ckpt / "model.safetensors").stat().st_mtime_ns == stamp
    assert second["table"] == first["table"]
    assert json.loads((out / "round_00" / "eval.json").read_text())["quiet"]["n"] == 2


def test_a_state_the_expert_cannot_reach_ends_the_labelled_episode(full_cfg, monkeypatch):
    from lerobot_pnp.dagger.rollouts import Teacher
    from lerobot_pnp.errors import UnreachableError

    env = suite_env(full_cfg, "quiet")
    label = Teacher.label
    calls = {"n": 0}

    follower = _Follower(env)

    def flaky(self):
        if self is follower.teacher:  # the follower's own copy acts normally
            return label(self)
        calls["n"] += 1
        if calls["n"] > 6:  # the 7th state: the policy pushed the object out of reach
            raise UnreachableError("IK did not converge")
        return label(self)

    monkeypatch.setattr(Teacher, "label", flaky)
    ep = labelled_rollout(env, follower, seed=2)
    env.close()
    assert len(ep.actions) == 6 and not ep.success and ep.info["stopped"] == "unreachable"


@pytest.mark.parametrize("suite", ["quiet", "quiet_grasp_miss", "quiet_drop"])
def test_teacher_labels_equal_the_demonstrations_along_an_expert_trajectory(full_cfg, suite):
    """DAgger labels and demonstrations must not contradict each other on the states both visit."""
    from lerobot_pnp.dagger.rollouts import Teacher
    from lerobot_pnp.sim.expert import run_expert_episode

    env = suite_env(full_cfg, suite)
    ep = run_expert_episode(env, 4)
    env.reset(seed=4)
    teacher = Teacher(env)
    for k, action in enumerate(ep.actions[:-1]):
        keyframe, phase = teacher.label()
        assert phase == ep.phases[k], (k, ep.phases.tolist())
        np.testing.assert_allclose(keyframe, action, atol=1e-2)
        env.step(action)
    env.close()
    assert suite == "quiet" or len(ep.actions) > 11  # the perturbation made the expert recover


class _OneStepLate:
    """A 'policy' that holds every other step (arm and gripper commands as they are) and otherwise executes the
    next keyframe of a demonstration: what a planner that waits to see its last move arrive does."""

    def __init__(self, env, keyframes):
        self.env, self.keyframes, self.t = env, keyframes, 0

    def reset(self):
        self.t = 0

    def act(self, obs):
        physics, t = self.env.unwrapped.physics, self.t
        self.t += 1
        if t % 2 == 0:
            return np.append(physics.arm_command(), physics.gripper_command()).astype(np.float32)
        return self.keyframes[min(t // 2, len(self.keyframes) - 1)]


def test_a_hold_leaves_the_teachers_label_pending(full_cfg):
    """A policy that holds where the expert moves on is labelled with the same keyframe again: the close and the
    open keep the arm where it is, so judged by the arm alone a close not yet commanded passed for a missed grasp
    and the next label lifted with the gripper open."""
    from lerobot_pnp.sim.expert import run_expert_episode

    env = suite_env(full_cfg, "quiet")
    demo = run_expert_episode(env, 4)
    ep = labelled_rollout(env, _OneStepLate(env, demo.actions), seed=4, suite="quiet")
    env.close()
    assert ep.success and demo.phases.tolist() == list(range(10))  # an undisturbed demonstration: 10 states
    phases = ep.phases.tolist()
    assert phases == sorted(phases) and set(phases) == set(range(10))  # never back to an earlier state
    assert len(phases) > len(demo.phases) + 5  # most labels were made twice (the policy held in between)
    for action, phase in zip(ep.actions, phases, strict=True):  # each the demonstration's keyframe of its state
        np.testing.assert_allclose(action, demo.actions[phase], atol=1e-2)


class _Wrong:
    """A 'policy' that always commands the arm's current setpoints with the gripper open (never a label)."""

    def __init__(self, env):
        self.env = env

    def reset(self):
        pass

    def act(self, obs):
        return np.append(self.env.unwrapped.physics.arm_command(), 1.0).astype(np.float32)


class _Recorder:
    """Wraps an env and keeps the actions executed on it."""

    def __init__(self, env):
        self.env, self.actions = env, []
        self.unwrapped = env.unwrapped

    def reset(self, **kw):
        return self.env.reset(**kw)

    def step(self, action):
        self.actions.append(np.asarray(action))
        return self.env.step(action)


@pytest.mark.parametrize("beta", [0.0, 1.0])
def test_beta_decides_who_acts(full_cfg, beta):
    """beta = 1 executes the teacher's label at every step (and recovers); beta = 0 the policy's action."""
    env = suite_env(full_cfg, "quiet_drop")
    rec = _Recorder(env)
    ep = labelled_rollout(rec, _Wrong(env), seed=3, suite="quiet_drop", beta=beta)
    env.close()
    executed = np.stack(rec.actions)
    if beta == 1.0:
        np.testing.assert_array_equal(executed, ep.actions[: len(executed)])
        assert ep.success and ep.info["executed"] == len(executed) and ep.info["disagree"] == 0
        # what the policy alone would have done: holding matches only the FSM's hold after the pick retract
        assert len(executed) - 1 <= ep.info["policy_disagree"] <= len(executed)
    else:
        assert not ep.success and ep.info["executed"] == 0 and ep.info["disagree"] == len(executed)
        assert ep.info["policy_disagree"] == len(executed)
        assert np.all(executed[:, -1] == 1.0)  # the policy's own (gripper always open)


def test_a_changed_beta_or_dart_noise_reruns_the_rollouts(tmp_path):
    cfg = dict(output_dir=str(tmp_path / "dg"), num_episodes=4, rounds=1, rollouts_per_round=1,
               rollout_suites=["quiet_drop"], eval_suites=["quiet"], n_episodes=0, epochs=1, progress=False)  # fmt: skip
    first = run_dagger(DaggerConfig(**cfg))
    record = tmp_path / "dg" / "round_01" / "rollouts.json"
    stamp = record.stat().st_mtime_ns
    assert first["rollouts"][1]["beta"] == 0.0 and first["rollouts"][1]["executed_labels"] == 0
    assert run_dagger(DaggerConfig(**cfg))["rollouts"][1] == first["rollouts"][1]
    assert record.stat().st_mtime_ns == stamp  # same beta: reused
    mixed = run_dagger(DaggerConfig(**cfg, beta=1.0))["rollouts"][1]
    assert record.stat().st_mtime_ns != stamp and mixed["beta"] == 1.0
    assert mixed["executed_labels"] == mixed["frames"] - 1 and mixed["disagree"] == 0  # every step the label's
    stamp = record.stat().st_mtime_ns
    noisy = run_dagger(DaggerConfig(**cfg, beta=1.0, dart=DartNoise(sigma=0.1)))["rollouts"][1]
    assert record.stat().st_mtime_ns != stamp and noisy["dart"] == {"sigma": 0.1, "gripper_flip": 0.0}
    assert noisy["disagree"] > 0  # the executed actions carried the noise
    stamp = record.stat().st_mtime_ns
    assert run_dagger(DaggerConfig(**cfg, beta=1.0, dart=DartNoise(sigma=0.1)))["rollouts"][1] == noisy
    assert record.stat().st_mtime_ns == stamp  # same noise: reused
    run_dagger(DaggerConfig(**cfg, beta=1.0, dart=DartNoise(sigma=0.2)))
    assert record.stat().st_mtime_ns != stamp  # another sigma: re-run
    with pytest.raises(ConfigError, match="beta must be in"):
        DaggerConfig(beta=1.5)


@pytest.mark.parametrize(
    ("settings", "match"),
    [
        ({"sigma": -0.01}, r"dart.sigma must be a finite number >= 0 \(rad\), got -0.01"),
        ({"sigma": float("nan")}, "dart.sigma must be a finite number"),
        ({"gripper_flip": 1.5}, r"dart.gripper_flip must be a probability in \[0, 1\], got 1.5"),
        ({"gripper_flip": -0.1}, "dart.gripper_flip must be a probability"),
    ],
)
def test_bad_dart_settings_are_refused(settings, match):
    with pytest.raises(ConfigError, match=match):
        DartNoise(**settings)


def test_dart_noise_needs_the_expert_to_act():
    with pytest.raises(ConfigError, match="with beta 0 the expert never acts"):
        DaggerConfig(beta=0.0, dart=DartNoise(sigma=0.01))
    assert DaggerConfig(beta=1.0, dart=DartNoise(sigma=0.01)).dart.key() == {
        "dart": {"sigma": 0.01, "gripper_flip": 0.0}
    }
    assert DaggerConfig().dart.key() == {}  # off: the keys of earlier runs are unchanged


def _noisy_rollout(env, seed, dart):
    rec = _Recorder(env)
    ep = labelled_rollout(rec, _Wrong(env), seed=seed, suite="quiet", beta=1.0, dart=dart)
    return ep, np.stack(rec.actions)


def test_a_dart_rollout_executes_noise_and_keeps_the_clean_expert_labels(full_cfg):
    """DART: the executed action is the label plus noise; the label is what the noiseless teacher commands at
    the visited state (replayed: a fresh teacher along the same executed actions gives the same labels)."""
    from lerobot_pnp.dagger.rollouts import Teacher

    sigma = 0.02
    env = suite_env(full_cfg, "quiet")
    ep, executed = _noisy_rollout(env, 7, DartNoise(sigma=sigma, gripper_flip=1.0))
    again, executed_again = _noisy_rollout(env, 7, DartNoise(sigma=sigma, gripper_flip=1.0))
    other, _ = _noisy_rollout(env, 8, DartNoise(sigma=sigma))
    labels = ep.actions[: len(executed)]
    noise = executed[:, :7] - labels[:, :7]
    assert np.all(np.abs(noise).max(axis=1) > 0)  # every executed expert step was perturbed
    assert 0.5 * sigma < noise.std() < 1.5 * sigma and abs(noise.mean()) < 0.5 * sigma
    assert np.all((executed[:, 7] > 0.5) != (labels[:, 7] > 0.5))  # gripper_flip 1: always the other side
    np.testing.assert_array_equal(executed, executed_again)  # the noise is seeded by the rollout's seed
    np.testing.assert_array_equal(ep.actions, again.actions)
    assert not np.array_equal(ep.actions[:3], other.actions[:3])
    env.reset(seed=7)
    teacher = Teacher(env)
    for k, action in enumerate(executed):
        keyframe, phase = teacher.label()
        np.testing.assert_array_equal(keyframe, ep.actions[k])
        assert phase == ep.phases[k]
        teacher.executed(action)
        env.step(action)
    env.close()


def test_dart_with_sigma_0_reproduces_the_expert_episode(full_cfg):
    from lerobot_pnp.sim.expert import run_expert_episode

    env = suite_env(full_cfg, "quiet_drop")
    expert = run_expert_episode(env, 4)
    ep, executed = _noisy_rollout(env, 4, DartNoise(sigma=0.0))
    env.close()
    assert ep.success and len(ep.actions) == len(expert.actions) > 11  # the drop made both recover
    np.testing.assert_array_equal(executed, ep.actions[: len(executed)])  # the clean labels were executed
    np.testing.assert_allclose(executed, expert.actions[:-1], atol=1e-2)  # the teacher's labels (IK-seeded)
    np.testing.assert_allclose(ep.states, expert.states, atol=1e-3)
    np.testing.assert_array_equal(ep.phases[:-1], expert.phases[:-1])


# ---- the output folder: only what DAgger recorded as its own is replaced or deleted ------------------------------
def _tree(folder: Path) -> dict[str, bytes | None]:
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None) for p in sorted(folder.rglob("*"))}


def _dagger_cli(out: Path, *extra: str) -> list[str]:
    return ["dagger", "--output_dir", str(out), "--num_episodes", "4", "--rounds", "0", "--epochs", "1",
            "--n_episodes", "0", "--progress", "false", *extra]  # fmt: skip


def test_a_users_dataset_named_demos_is_refused_and_kept(tmp_path, capsys):
    from keyframe_synth import make_keyframe_dataset

    from lerobot_pnp import cli

    out = tmp_path / "dg"
    make_keyframe_dataset(out / "demos", n_episodes=6)
    before = _tree(out)
    capsys.readouterr()
    assert cli.main(_dagger_cli(out)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "demos" in err and "move it or choose another --output_dir" in err, err
    assert _tree(out) == before  # the dataset untouched, nothing recorded


@pytest.fixture(scope="module")
def dagger_cli_run(tmp_path_factory):
    """``lerobot-pnp dagger --preset paper ... --policy.hidden_size 8`` into a folder that holds a user's
    ``round_05`` folder."""
    from lerobot_pnp import cli

    out = tmp_path_factory.mktemp("dagger_cli") / "dg"
    (out / "round_05").mkdir(parents=True)
    (out / "round_05" / "f").write_text("mine")
    assert cli.main(_dagger_cli(out, "--preset", "paper", "--policy.hidden_size", "8")) == 0
    return out


def test_a_round_folder_dagger_did_not_write_is_kept(dagger_cli_run):
    assert (dagger_cli_run / "round_05" / "f").read_text() == "mine"


def test_one_policy_flag_keeps_the_recovering_recipe_in_the_saved_config(dagger_cli_run):
    from lerobot_pnp.policy.recipes import RECOVERING_RECIPE

    saved = json.loads((dagger_cli_run / "round_00" / "train" / "train_fast_config.json").read_text())["policy"]
    assert {k: saved[k] for k in RECOVERING_RECIPE} == {**RECOVERING_RECIPE, "hidden_size": 8}


def test_a_folder_from_before_the_manifest_is_resumed_and_only_daggers_rounds_go(dagger_cli_run, tmp_path, capsys):
    """A DAgger folder without a manifest (written before it existed) is recognised by DAgger's stage records and
    resumed; a later round DAgger recorded is deleted, a round folder of the user's stays."""
    import shutil

    from lerobot_pnp import cli
    from lerobot_pnp.dagger.folder import COMMAND
    from lerobot_pnp.outputs import MANIFEST_FILE, OutputFolder

    out = shutil.copytree(dagger_cli_run, tmp_path / "dg", symlinks=True)
    (out / MANIFEST_FILE).unlink()
    weights = next((out / "round_00" / "train").rglob("model.safetensors"))
    stamp = weights.stat().st_mtime_ns
    assert cli.main(_dagger_cli(out, "--preset", "paper", "--policy.hidden_size", "8")) == 0
    assert weights.stat().st_mtime_ns == stamp  # reused, not trained again
    owners = json.loads((out / MANIFEST_FILE).read_text())["owners"]
    assert set(owners[COMMAND]) == {"demos", "round_00", "summary.json"}
    with OutputFolder(out, COMMAND) as folder:  # a round 3 of an earlier run with more rounds
        folder.claim("round_03")
    (out / "round_03").mkdir()
    (out / "round_03" / "eval.json").write_text("{}")
    assert cli.main(_dagger_cli(out, "--preset", "paper", "--policy.hidden_size", "8")) == 0
    assert not (out / "round_03").exists() and (out / "round_05" / "f").read_text() == "mine"
    capsys.readouterr()
