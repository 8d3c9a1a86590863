"""lerobot_pnp.evaluation: the one Wilson interval and paired comparison, the one suite catalogue (DAgger's
suites are its ``quiet*`` entries, with the env changes DAgger used before), episode records, DAgger's table."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.records import EpisodeRecord, summarize
from lerobot_pnp.evaluation.stats import Rate, paired_comparison, sign_test_p, wilson_interval
from lerobot_pnp.sim.suites import SUITES, Suite


# ---------------------------------------------------------------------------------------------- stats
def test_wilson_interval_matches_reference_values():
    lo, hi = wilson_interval(50, 100)
    assert (round(lo, 4), round(hi, 4)) == (0.4038, 0.5962)
    lo, hi = wilson_interval(0, 10)
    assert lo == 0 and math.isclose(hi, 0.2775, abs_tol=1e-4)
    lo, hi = wilson_interval(10, 10)
    assert hi == 1 and math.isclose(lo, 0.7225, abs_tol=1e-4)
    lo, hi = wilson_interval(196, 200)
    assert math.isclose(lo, 0.9497, abs_tol=2e-4) and math.isclose(hi, 0.9923, abs_tol=2e-4)
    with pytest.raises(ValueError, match="n >= 1"):
        wilson_interval(3, 0)
    with pytest.raises(ValueError, match=r"successes must be in \[0, 3\]"):
        wilson_interval(4, 3)


def test_rate_of_outcomes_and_its_text():
    r = Rate.of([True, True, False, True])
    assert (r.successes, r.n, r.rate) == (3, 4, 0.75)
    assert str(Rate(10, 10)) == "100.0% [72.2, 100.0]"


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
# DAgger's catalogue before it joined the one catalogue (dagger/rollouts.py NOMINAL / SUITES), verbatim.
_OFF = ("nudge_max", "grasp_miss_prob", "drop_prob", "displace_prob", "obs_noise_object", "obs_noise_joints")
_OLD_NOMINAL = {**dict.fromkeys((*_OFF, "obs_bias_object"), 0.0), "obs_latency": 0}
_OLD_DAGGER_SUITES = {
    "nominal": _OLD_NOMINAL,
    "grasp_miss": {**_OLD_NOMINAL, "grasp_miss_prob": 1.0},
    "drop": {**_OLD_NOMINAL, "drop_prob": 1.0},
    "nudge": {**_OLD_NOMINAL, "nudge_max": 0.03},
    "displace": {**_OLD_NOMINAL, "displace_prob": 1.0},
    "noise_latency": {
        **_OLD_NOMINAL,
        "obs_noise_object": 0.003,
        "obs_noise_joints": 0.005,
        "obs_bias_object": 0.003,
        "obs_latency": 1,
    },
    "noise": {**_OLD_NOMINAL, "obs_noise_object": 0.003, "obs_noise_joints": 0.005},
    "bias": {**_OLD_NOMINAL, "obs_bias_object": 0.003},
    "latency": {**_OLD_NOMINAL, "obs_latency": 1},
    "full": {},
}


@pytest.mark.parametrize("old", sorted(_OLD_DAGGER_SUITES))
def test_renamed_dagger_suites_keep_their_env_changes(old):
    from lerobot_pnp.dagger.config import _RENAMED

    (changes,) = SUITES[_RENAMED[old]].parts
    assert changes == _OLD_DAGGER_SUITES[old]
    assert {k: type(v) for k, v in changes.items()} == {k: type(v) for k, v in _OLD_DAGGER_SUITES[old].items()}


def test_dagger_suite_env_is_the_catalogue_change_on_the_base_task():
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    base = BaxterPnPEnvConfig(preset="full")
    (drop,) = SUITES["quiet_drop"].env_configs(base)
    assert drop == base.with_changes(**{**_OLD_NOMINAL, "drop_prob": 1.0})
    assert drop.drop_prob == 1.0 and drop.grasp_miss_prob == 0.0 and drop.keyframe_budget == base.keyframe_budget
    assert SUITES["nominal"].env_configs(base) == [base.with_changes()]


def test_dagger_config_refuses_old_names_with_their_renames():
    from lerobot_pnp.dagger import DaggerConfig

    with pytest.raises(
        ConfigError, match=r"rollout_suites .* old suite names; rename them: 'full' -> 'nominal', 'drop'"
    ):
        DaggerConfig(rollout_suites=["full", "drop"])
    with pytest.raises(
        ConfigError, match=r"eval_suites \['nominal', 'nudge'\] .*: 'nominal' -> 'quiet', 'nudge' -> 'quiet_n"
    ):
        DaggerConfig(eval_suites=["nominal", "nudge"])  # the default rollout_suites (with the new 'nominal') are fine
    cfg = DaggerConfig()  # the defaults are catalogue names
    assert all(s in SUITES for s in (*cfg.rollout_suites, *cfg.eval_suites))


def test_dagger_config_refuses_a_multi_part_suite(monkeypatch):
    from lerobot_pnp.dagger import DaggerConfig, config

    two = Suite("two_parts", "a suite of two parts", ({}, {"nudge_max": 0.03}))
    monkeypatch.setattr(config, "SUITES", {**SUITES, two.name: two})
    with pytest.raises(ConfigError, match=r"suites \['two_parts'\] have several parts"):
        DaggerConfig(eval_suites=["quiet", "two_parts"])


# ---------------------------------------------------------------------------------------------- records
def test_record_from_final_info():
    fail = EpisodeRecord.from_info(5, {"failure_cause": "dropped", "furthest_phase": 6, "perturbations": "drop"}, 9,
                                   (0.6, 0.1))  # fmt: skip
    assert fail == EpisodeRecord(5, False, "dropped", 6, "drop", 9, 0.6, 0.1)
    assert EpisodeRecord.from_info(1, {}, 3, (0.0, 0.0)).failure_cause == "truncated"
    ok = EpisodeRecord.from_info(2, {"is_success": True, "failure_cause": "x"}, 4, (0.5, 0.0))
    assert ok.success and ok.failure_cause == "" and ok.furthest_phase == -1
    assert robot.phase_name(-1) == "unknown" and robot.phase_name(len(robot.PHASE_NAMES)) == "unknown"
    assert robot.phase_name(0) == robot.PHASE_NAMES[0]
    assert robot.phase_name(np.int64(3)) == robot.PHASE_NAMES[3]
    counts = summarize([fail, ok, EpisodeRecord.from_info(3, {}, 3, (0.0, 0.0))])
    assert counts == {"n": 3, "successes": 1, "by_cause": {"dropped": 1, "truncated": 1},
                      "by_phase": {robot.PHASE_NAMES[6]: 1, "unknown": 1}}  # fmt: skip


# ---------------------------------------------------------------------------------------------- DAgger's table
def test_dagger_table_uses_the_one_rate(tmp_path):
    """The table's cells are ``Rate``'s text (no space before %), its JSON the one Wilson interval."""
    from lerobot_pnp.dagger import write_table

    rows = [("round 0", {"quiet": {"suite": "quiet", "n": 10, "successes": 10, "failures": {}}})]
    table = write_table(rows, ["quiet", "quiet_drop"], tmp_path)
    assert "| round 0 | 100.0% [72.2, 100.0] | - |" in table
    (row,) = json.loads((tmp_path / "table.json").read_text())
    assert row["quiet"]["rate"] == 1.0 and row["quiet"]["wilson95"] == list(wilson_interval(10, 10))
    assert row["quiet"]["wilson95"][1] == 1.0 and "quiet_drop" not in row


# ---------------------------------------------------------------------------------------------- evaluators
def test_dagger_evaluate_equals_its_former_loop():
    """DAgger's evaluation now runs ``evaluate_serial`` (``run_episode`` per seed); its dict is the one the former
    hand-written loop (verbatim below) gave on the same env and seeds."""
    import numpy as np

    from lerobot_pnp.dagger import evaluate
    from lerobot_pnp.dagger.rollouts import suite_env
    from lerobot_pnp.evaluation.checkpoints import LoadedPolicy
    from lerobot_pnp.report.adapters import Episodes
    from lerobot_pnp.report.baselines import LookupTablePolicy, identity_processors
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.sim.expert import run_expert_episode

    base, seeds = BaxterPnPEnvConfig(preset="paper"), [3, 4, 5]
    env = suite_env(base, "quiet")
    demo = run_expert_episode(env, 3)  # replayed by the lookup table: a success on seed 3, failures elsewhere
    env.close()
    pre, post = identity_processors()
    table = LookupTablePolicy(Episodes(np.arange(1), demo.env_states[:1], [demo.actions]))
    loaded = LoadedPolicy(table, pre, post, path=None, type="pnp_lookup_table")

    def former(suite):
        env = suite_env(base, suite)
        successes, causes = 0, {}
        for seed in seeds:
            loaded.reset()
            obs, info = env.reset(seed=seed)
            while True:
                obs, _, terminated, truncated, info = env.step(loaded.act(obs))
                if terminated or truncated:
                    break
            if info.get("is_success"):
                successes += 1
            else:
                cause = str(info.get("failure_cause") or "unknown")
                causes[cause] = causes.get(cause, 0) + 1
        env.close()
        return {"suite": suite, "n": len(seeds), "successes": successes, "failures": causes}

    for suite in ("quiet", "quiet_drop"):
        got = evaluate(loaded, base, suite, seeds)
        assert got == former(suite) and got["n"] == 3
    assert evaluate(loaded, base, "quiet", [3])["successes"] == 1
    assert evaluate(loaded, base, "quiet_drop", [3])["failures"] == {"dropped": 1}


# ---------------------------------------------------------------------------------------------- checkpoints
def test_both_loaders_name_the_same_non_finite_weights():
    """``weights.non_finite_weights`` is the one check of pnp_lstm's from_pretrained and the strict loader."""
    import torch

    from lerobot_pnp.evaluation.checkpoints import PolicyLoadError, check_checkpoint_values
    from lerobot_pnp.policy.weights import non_finite_weights

    state = {
        "a": torch.zeros(2),
        "b": torch.tensor([1.0, float("inf")]),
        "steps": torch.tensor([3]),
        "c": torch.ones(1),
    }
    state["c"][0] = float("nan")
    assert non_finite_weights(state) == ["b", "c"]  # in order; integer buffers are not weights
    assert non_finite_weights({"a": torch.zeros(2)}) == []

    class Policy:
        def state_dict(self):
            return state

    with pytest.raises(PolicyLoadError, match=r"the checkpoint ckpt is corrupt: its weights 'b' contain NaN/inf"):
        check_checkpoint_values("ckpt", Policy(), ())


def test_t975_gives_students_quantiles():
    from lerobot_pnp.evaluation.stats import t975

    published = {1: 12.706, 2: 4.303, 4: 2.776, 10: 2.228, 11: 2.201, 20: 2.086, 30: 2.042, 60: 2.000, 1000: 1.962}
    assert all(abs(t975(d) - t) < 1e-3 for d, t in published.items())
    with pytest.raises(ValueError, match="dof >= 1"):
        t975(0)


def test_a_pooled_interval_counts_the_seeds_where_they_spread():
    from lerobot_pnp.evaluation.results import Pooled
    from lerobot_pnp.evaluation.stats import Rate, seed_interval

    agree = Pooled(Rate(135, 150), (Rate(45, 50),) * 3)  # seeds with one rate: the episodes' Wilson interval
    assert agree.interval == agree.rate.interval
    close = Pooled(Rate(135, 150), (Rate(45, 50), Rate(46, 50), Rate(44, 50)))  # never narrower than Wilson's
    assert close.interval[0] <= close.rate.interval[0] and close.interval[1] >= close.rate.interval[1]
    spread = Pooled(Rate(75, 150), (Rate(10, 50), Rate(25, 50), Rate(40, 50)))  # 20, 50 and 80 %
    lo, hi = spread.interval
    wlo, whi = spread.rate.interval
    assert lo < wlo and hi > whi  # wider than the episodes allow: a rerun's seeds can land anywhere in there
    assert lo == pytest.approx(max(0.0, 0.5 - 4.302652730 * 0.3 / 3**0.5))
    assert seed_interval(Rate(7, 10), [0.7]) == Rate(7, 10).interval  # one seed: Wilson's
    assert str(spread) == f"50.0% [{100 * lo:.1f}, {100 * hi:.1f}]"
    cell = spread.to_json()
    assert (
        cell["interval"] == (lo, hi) and cell["episode_interval"] == (wlo, whi) and cell["per_seed"] == [0.2, 0.5, 0.8]
    )
