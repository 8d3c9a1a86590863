"""A dense (ACT) checkpoint under stock ``lerobot-eval --env.task heldout``: the same suites as the study runs it.

The study evaluates ACT on each suite's config of the keyframe task moved to dense control
(``act_baseline.dense_env``: the nudge at the dense step of the first keyframe); ``lerobot-eval`` builds each suite
on the checkpoint's recorded dense task, with ``--env.nudge_at_step`` given. Both go through stock ``eval_policy``,
so the suites' env configs are what could make them differ.
"""

from __future__ import annotations

import pytest

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.integration.recorded_task import write_checkpoint_task
from lerobot_pnp.report import act_baseline
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.stock_suites import suite_configs, suite_names
from lerobot_pnp.sim.suites import SUITES

NUDGE_STEP = 19  # a dense step of the first keyframe (the study reads it from the dense demonstrations)


@pytest.fixture()
def dense_checkpoint(tmp_path):
    """A folder holding what an ACT checkpoint records: the `full` task in dense control."""
    dense = BaxterPnPEnvConfig(preset="full", control_mode="dense")
    write_checkpoint_task({"type": "baxter_pnp", **dense.to_dict()}, tmp_path)
    return tmp_path


def test_heldout_suites_of_a_dense_checkpoint_are_the_studys_act_suites(dense_checkpoint, monkeypatch):
    """Every suite of ``--env.task heldout`` on the dense checkpoint, nudge step given, has the env config the
    study's ``act_env`` gives the same suite of the keyframe task: control mode, rate, episode length (a recovery
    budget's too), the nudge's step and size, every perturbation."""
    monkeypatch.setattr(act_baseline, "dense_nudge_step", lambda root: NUDGE_STEP)
    stock = suite_configs(
        BaxterPnPEnvConfig.from_source(str(dense_checkpoint), task="heldout", nudge_at_step=NUDGE_STEP)
    )
    keyframe = BaxterPnPEnvConfig(preset="full")
    assert list(stock) == suite_names("heldout") and len(stock) == 18
    lengths = set()
    for name, cfg in stock.items():
        (part,) = SUITES[name].env_configs(keyframe)
        study = act_baseline.dense_env(part, "dense_root")
        assert cfg.to_dict() == study.to_dict(), name
        assert (cfg.control_mode, cfg.nudge_at_step) == ("dense", NUDGE_STEP) and cfg.nudge_max > 0
        lengths.add(cfg.episode_length)
    assert len(lengths) > 1  # the suites that change the keyframe budget got their own dense length


@pytest.mark.parametrize("task", ["nominal", "train_drop", "heldout"])
def test_a_suite_nudged_by_the_dense_task_itself_needs_the_nudge_step(dense_checkpoint, task):
    """On `full` every suite nudges (the task does, not only the nudge suites): without ``--env.nudge_at_step``
    the push would come at dense step 1, before the arm moves, not the study's suite; one line, not a silent run."""
    with pytest.raises(ConfigError, match=r"nudges the object at env step 1.*--env.nudge_at_step"):
        BaxterPnPEnvConfig.from_source(str(dense_checkpoint), task=task)
