"""The reproduction study: suites, the lookup-table baseline, the episode recorder, and (slow)
the ``--quick`` study end to end: a report is written and the clocked LSTM beats the lookup table under a
nudge on the same seeds."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from lerobot_pnp.errors import ConfigError, PolicyError
from lerobot_pnp.presets import PAPER_TASK
from lerobot_pnp.report.adapters import Episodes
from lerobot_pnp.report.baselines import LookupTablePolicy
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.suites import SUITES, get_suites


# ---------------------------------------------------------------------------------------------- suites
def _object_starts(env_cfg, n: int) -> np.ndarray:
    from lerobot_pnp.sim.task import PickPlaceTask

    task, rng = PickPlaceTask(env_cfg), np.random.default_rng(0)
    return np.stack([task._sample_object_xy(rng) for _ in range(n)])


def test_edge_strip_and_outside_ring_sample_exactly_the_band():
    low, high = np.array(PAPER_TASK["object_low"]), np.array(PAPER_TASK["object_high"])
    base = BaxterPnPEnvConfig(preset="paper")
    (strip,) = SUITES["edge_strip"].env_configs(base)
    (ring,) = SUITES["outside_ring"].env_configs(base)
    inside = _object_starts(strip, 2000)
    outside = _object_starts(ring, 2000)
    # distance to the training box's edge: >= 0 inside the box (from its nearest side), < 0 beyond it
    margin_in = np.minimum(inside - low, high - inside).min(axis=1)
    assert margin_in.min() >= 0 and margin_in.max() <= 0.03 + 1e-9
    beyond = np.maximum(low - outside, outside - high).max(axis=1)
    assert beyond.min() > 0 and beyond.max() <= 0.03 + 1e-9
    # uniform on the band: each side's share is its share of the band's area (long sides 0.4 m, short 0.3 m)
    near_y_high = np.mean(high[1] - inside[:, 1] <= 0.03)
    assert abs(near_y_high - 0.3 * 0.03 / (0.3 * 0.4 - 0.24 * 0.34)) < 0.04
    # the nominal task draws exactly as before: no exclusion, first draw taken
    assert np.array_equal(_object_starts(base, 5), np.random.default_rng(0).uniform(low, high, (5, 2)))


def test_an_exclusion_that_covers_the_object_box_is_a_clear_error():
    with pytest.raises(ConfigError, match="covers the whole object box"):
        BaxterPnPEnvConfig(preset="paper", object_exclude_low=(0.4, 0.0), object_exclude_high=(0.8, 0.6))
    with pytest.raises(ConfigError, match="object_exclude_low must be <= object_exclude_high"):
        BaxterPnPEnvConfig(preset="paper", object_exclude_low=(0.6, 0.3), object_exclude_high=(0.5, 0.4))


def test_suites_apply_to_the_training_task_and_reject_unknown_names():
    base = BaxterPnPEnvConfig(preset="paper")
    (grasp,) = SUITES["grasp_miss"].env_configs(base)
    assert grasp.grasp_miss_prob == 1.0 and grasp.keyframe_budget == 20 and grasp.episode_length == 20
    assert grasp.object_low == base.object_low  # everything else is the training task
    assert [s.name for s in get_suites(["nudge"])] == ["nudge_0.01", "nudge_0.02", "nudge_0.03", "nudge_0.05"]
    assert SUITES["edge_strip"].part_episodes(10) == [10]
    with pytest.raises(ConfigError, match="unknown evaluation suite"):
        get_suites(["nudge_big"])


# ---------------------------------------------------------------------------------------------- baseline
def _table():
    first = np.array([[0.5, 0.2, 0.0], [0.7, 0.4, 0.0]], dtype=np.float32)
    actions = [np.full((3, 8), 1.0, dtype=np.float32), np.stack([np.full(8, k, dtype=np.float32) for k in (5, 6)])]
    return LookupTablePolicy(Episodes(np.arange(2), first, actions))


def test_lookup_table_replays_the_nearest_episode_open_loop():
    policy = _table()
    obs = {"observation.environment_state": torch.tensor([[0.69, 0.41, 0.0], [0.51, 0.2, 0.0]])}
    first = policy.select_action(obs)
    assert first[:, 0].tolist() == [5.0, 1.0]
    # later observations are ignored (open loop): the object "moves" but the replay goes on
    moved = {"observation.environment_state": torch.tensor([[0.5, 0.2, 0.0], [0.7, 0.4, 0.0]])}
    assert policy.select_action(moved)[:, 0].tolist() == [6.0, 1.0]
    assert policy.select_action(moved)[:, 0].tolist() == [6.0, 1.0]  # past its end: holds the last action
    policy.reset()
    assert policy.select_action(moved)[:, 0].tolist() == [1.0, 5.0]  # a new episode looks up again


def test_lookup_table_rejects_a_task_with_other_observations():
    policy = _table()
    with pytest.raises(PolicyError, match="environment_state has 5"):
        policy.select_action({"observation.environment_state": torch.zeros(1, 5)})


# ---------------------------------------------------------------------------------------------- evaluation
def test_recorder_agrees_with_eval_policy_and_explains_failures():
    """A policy that never moves fails every episode; the records carry seeds, causes and start positions."""
    from lerobot_pnp.evaluation.closed_loop import eval_lerobot_policy
    from lerobot_pnp.report.baselines import identity_processors

    class Still(LookupTablePolicy):
        def select_action(self, batch, **kwargs):
            return torch.as_tensor(batch["observation.state"]).float()  # hold the current joints, gripper as is

    policy = Still(Episodes(np.arange(1), np.zeros((1, 3), np.float32), [np.zeros((1, 8), np.float32)]))
    pre, post = identity_processors()
    env_cfg = BaxterPnPEnvConfig(preset="paper")
    records = eval_lerobot_policy(policy, pre, post, env_cfg, n_episodes=3, start_seed=7, batch_size=2)
    assert [r.seed for r in records] == [7, 8, 9]
    assert not any(r.success for r in records)
    assert {r.failure_cause for r in records} == {"not_grasped"} and all(r.steps == 10 for r in records)
    low, high = env_cfg.object_low, env_cfg.object_high
    assert all(low[0] <= r.object_x <= high[0] and low[1] <= r.object_y <= high[1] for r in records)


# ---------------------------------------------------------------------------------------------- end to end
@pytest.mark.slow
def test_quick_study_writes_a_report_where_the_planner_beats_the_lookup_table(tmp_path):
    from lerobot_pnp.report.run import StudyConfig, SuiteSpec, run_study

    out = tmp_path / "study"
    # the quick preset cut to a third of its demonstrations and 40 % of its episodes (the nudge gap stays far
    # beyond p = 0.05)
    small = dict(num_episodes=100, epochs=250, suites=[SuiteSpec("nominal", 40), SuiteSpec("nudge_0.03", 40)])
    run_study(StudyConfig(output_dir=str(out), quick=True, workers=1, **small))
    report = (out / "report.md").read_text()
    assert "Success by suite" in report and "figures/heatmap_nominal.png" in report
    for name in json.loads((out / "summary.json").read_text())["figures"]:
        assert (out / "figures" / name).stat().st_size > 10_000
    summary = json.loads((out / "summary.json").read_text())
    nudge = summary["vs_lookup_table"]["clocked_lstm"]["nudge_0.03"]
    assert nudge["difference"] > 0 and nudge["max_p"] < 0.05, nudge
    # the summary records where and from what it was made: CPU model, cores, the commit and the date
    assert {"cpu", "cores_available", "commit", "uncommitted_changes", "date"} <= summary["machine"].keys()
    assert summary["machine"]["cpu"] and summary["machine"]["cores_available"] >= 1

    # A report written again removes a figure the previous report drew and this one does not (its summary says
    # which), and nothing else in figures/.
    summary["figures"].append("gone.png")
    (out / "summary.json").write_text(json.dumps(summary))
    (out / "figures" / "gone.png").write_bytes(b"old")
    (out / "figures" / "mine.png").write_bytes(b"a user's")
    run_study(StudyConfig(output_dir=str(out), quick=True, workers=1, report_only=True, **small))
    assert not (out / "figures" / "gone.png").exists() and (out / "figures" / "mine.png").read_bytes() == b"a user's"
    assert all((out / "figures" / n).is_file() for n in summary["figures"][:-1])


# ---------------------------------------------------------------------------------------------- command line
@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["demo", "--quick", "--full"], "either --quick or --full"),
        (["report", "--methods", "[clocked_lstm,bogus]"], "unknown method(s) ['bogus']"),
        (["report", "--preset", "huge"], "preset must be one of"),
    ],
)
def test_study_commands_reject_bad_configs_in_one_line(argv, message, capsys, tmp_path):
    from lerobot_pnp import cli

    assert cli.main([*argv, f"--output_dir={tmp_path / 'never'}"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "never").exists()  # nothing was started
