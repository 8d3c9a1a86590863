"""The reproduction study: statistics, suites, the lookup-table baseline, the episode recorder, and (slow)
the ``--quick`` study end to end: a report is written and the clocked LSTM beats the lookup table under a
nudge on the same seeds."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from lerobot_pnp.env_config import PAPER_TASK, BaxterPnPEnvConfig
from lerobot_pnp.errors import ConfigError, PolicyError
from lerobot_pnp.report.adapters import Episodes
from lerobot_pnp.report.baselines import LookupTablePolicy
from lerobot_pnp.report.stats import paired_comparison, sign_test_p, wilson_interval
from lerobot_pnp.report.suites import SUITES, get_suites, strip_parts


# ---------------------------------------------------------------------------------------------- stats
def test_wilson_interval_matches_reference_values():
    lo, hi = wilson_interval(50, 100)
    assert (round(lo, 4), round(hi, 4)) == (0.4038, 0.5962)
    lo, hi = wilson_interval(0, 10)
    assert lo == 0 and math.isclose(hi, 0.2775, abs_tol=1e-4)
    lo, hi = wilson_interval(10, 10)
    assert hi == 1 and math.isclose(lo, 0.7225, abs_tol=1e-4)
    with pytest.raises(ValueError):
        wilson_interval(3, 0)


def test_sign_test_and_paired_comparison():
    assert math.isclose(sign_test_p(10, 0), 2 / 1024)
    assert sign_test_p(5, 5) == 1.0
    assert sign_test_p(0, 0) == 1.0
    a = {s: True for s in range(100)}
    b = {s: s >= 20 for s in range(100)}  # b fails the first 20 seeds, a fails none
    c = paired_comparison(a, b)
    assert (c.n, c.a_only, c.b_only) == (100, 20, 0)
    assert math.isclose(c.difference, 0.2) and c.significant()
    assert not paired_comparison(a, a).significant()
    with pytest.raises(ValueError, match="share no"):
        paired_comparison({1: True}, {2: True})


# ---------------------------------------------------------------------------------------------- suites
def test_strip_inside_and_ring_outside_the_training_box():
    low, high = PAPER_TASK["object_low"], PAPER_TASK["object_high"]
    inside = strip_parts(low, high, 0.03, outside=False)
    outside = strip_parts(low, high, 0.03, outside=True)
    for part in inside:
        assert all(low[i] - 1e-9 <= part["object_low"][i] and part["object_high"][i] <= high[i] + 1e-9 for i in (0, 1))
    for part in outside:  # every box reaches beyond the training box on one side
        assert (
            part["object_low"][0] < low[0]
            or part["object_low"][1] < low[1]
            or part["object_high"][0] > high[0]
            or part["object_high"][1] > high[1]
        )
    # the four boxes cover the band: a point in the middle of the box is in none of them
    centre = [(low[i] + high[i]) / 2 for i in (0, 1)]
    assert not any(all(p["object_low"][i] <= centre[i] <= p["object_high"][i] for i in (0, 1)) for p in inside)


def test_suites_apply_to_the_training_task_and_reject_unknown_names():
    base = BaxterPnPEnvConfig(preset="paper")
    (grasp,) = SUITES["grasp_miss"].env_configs(base)
    assert grasp.grasp_miss_prob == 1.0 and grasp.keyframe_budget == 20 and grasp.episode_length == 20
    assert grasp.object_low == base.object_low  # everything else is the training task
    assert [s.name for s in get_suites(["nudge"])] == ["nudge_0.01", "nudge_0.02", "nudge_0.03", "nudge_0.05"]
    assert SUITES["edge_strip"].part_episodes(10) == [3, 3, 2, 2]
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
    from lerobot_pnp.report.baselines import identity_processors
    from lerobot_pnp.report.evaluation import eval_lerobot_policy

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
    from lerobot_pnp.report.run import StudyConfig, run_study

    out = tmp_path / "study"
    run_study(StudyConfig(output_dir=str(out), quick=True, workers=1))
    report = (out / "report.md").read_text()
    assert "Success by suite" in report and "figures/heatmap_nominal.png" in report
    for name in json.loads((out / "summary.json").read_text())["figures"]:
        assert (out / "figures" / name).stat().st_size > 10_000
    summary = json.loads((out / "summary.json").read_text())
    nudge = summary["vs_lookup_table"]["clocked_lstm"]["nudge_0.03"]
    assert nudge["difference"] > 0 and nudge["max_p"] < 0.05, nudge


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
