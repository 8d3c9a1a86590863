"""The waiting-expert benchmark's rules: which keyframes it waits at changes the episode's length as documented."""

import pytest
from clis import load_script

from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.sim.suites import get_suites


@pytest.fixture(scope="module")
def bench():
    return load_script("benchmarks/latency_step_cost.py")


@pytest.fixture(scope="module")
def env():
    (cfg,) = get_suites(["heldout_latency_2"])[0].env_configs(BaxterPnPEnvConfig.from_dict({"preset": "full"}))
    env = make_env(cfg, render_mode=None)
    yield env
    env.close()


def test_each_wait_rule_costs_what_it_waits_for(bench, env):
    seed = 100_001  # draws no disturbance: the paper's 9 keyframes
    plain = bench.waiting_expert(env, seed, hold=0)
    runs = {wait: bench.waiting_expert(env, seed, hold=1, wait=wait) for wait in bench.WAITS}
    assert plain.success and all(r.success for r in runs.values())
    # The env counts held steps against the budget. Of the 9 keyframes, 8 move (not the place/start repeat); the
    # episode ends on success during the last one's wait, so 7 waits; 2 gripper commands, each after a descent.
    assert plain.steps == 9
    assert runs["every_move"].steps == 9 + 7
    assert runs["every_move_no_hold"].steps == 9 + 7 - 1
    assert runs["gripper"].steps == 9 + 4
    assert runs["after_gripper"].steps == 9 + 2
    # The gate's schedule: no third move in a row. Moves 1-2, wait, 3-4, the place/start hold, 6-7, wait, 8-9.
    assert runs["gate"].steps == 9 + 2
